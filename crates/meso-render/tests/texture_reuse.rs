//! Reuse of extracted pyramids by `[texture]` materials (issue #15, "Reuse"): a map file written
//! by `meso_maps` extraction (`map = "…"`) renders exactly as the height map it came from; a
//! height map's pyramid is cached on disk (`meso_maps::pyramid_cache`) and read back by the next
//! load; a damaged cache entry is rebuilt; a map file cannot be bump-mapped. The cache folder is
//! this test binary's own (`MESO_CACHE_DIR`, set before any load).

use meso_maps::pyramid_cache;
use meso_maps::{extract, Border, ExtractParams, HeightMap, MapsResolver, Pyramid, Source};
use meso_render::*;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

const S: f64 = 0.03125;
const H: f64 = 0.035;

/// This binary's cache folder, set as `MESO_CACHE_DIR` once for every test.
fn cache() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("texture_reuse_cache");
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        std::env::set_var("MESO_CACHE_DIR", &d);
        d
    })
}

/// A 32 × 32 egg crate with `bumps` × `bumps` bumps (a different map per test, hence a
/// different cache key) as a float EXR, and the facet material's tables.
fn write_map(dir: &Path, bumps: f64) -> PathBuf {
    cache();
    std::fs::create_dir_all(dir).unwrap();
    let n = 32usize;
    let tau = std::f64::consts::TAU;
    let values: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64 / n as f64, (k / n) as f64 / n as f64);
            ((tau * bumps * x).sin() * (tau * bumps * y).sin()) as f32
        })
        .collect();
    let file = dir.join("bumps.exr");
    std::fs::write(
        &file,
        meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap(),
    )
    .unwrap();
    file
}

const SURFACE: &str = "[transfer]\nkind = \"phong\"\nexponent = 20.0\nspecular = [0.6, 0.6, 0.6]\n\
                       [diffuse]\nalbedo = [0.5, 0.4, 0.3]\n";

fn material(dir: &Path, name: &str, texture: &str) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, format!("[texture]\n{texture}\n{SURFACE}")).unwrap();
    p
}

const FROM_HEIGHTS: &str = "kind = \"ndf-mapped\"\nfile = \"bumps.exr\"\ntexel_size = 0.03125\n\
                            height_scale = 0.035";

/// The pyramid `MapsResolver` extracts for [`FROM_HEIGHTS`], as `meso extract` writes it.
fn extracted(file: &Path) -> Pyramid {
    let map = HeightMap::load(file, S, H, Border::Wrap).unwrap();
    extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap()
}

/// The cache entry of [`FROM_HEIGHTS`] over `file`.
fn entry(file: &Path) -> PathBuf {
    let key = pyramid_cache::key(
        &std::fs::read(file).unwrap(),
        S,
        H,
        Border::Wrap,
        &ExtractParams::default(),
    );
    pyramid_cache::entry_path(cache(), &key)
}

fn render_with(dir: &Path, material: &Path, maps: &MapsResolver) -> Image {
    render_with_width(dir, material, maps, 3.0)
}

/// [`render_with`] with the camera seeing `width` world units across.
fn render_with_width(dir: &Path, material: &Path, maps: &MapsResolver, width: f64) -> Image {
    let scene_file = dir.join(format!(
        "{}.scene.toml",
        material.file_stem().unwrap().to_string_lossy()
    ));
    std::fs::write(
        &scene_file,
        format!(
            "[camera]\nkind = \"orthographic\"\nposition = [0.0, -20.0, 45.0]\n\
             look_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nwidth = {width}\n\
             [image]\nwidth = 48\nheight = 48\nspp = 1\n\
             [[object]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\
             tangent = [1.0, 0.0, 0.0]\nmaterial = \"{}\"\n\
             [[light]]\nkind = \"directional\"\ndirection = [-0.5, 0.3, 0.8]\n\
             irradiance = [2.0, 2.0, 2.0]\n",
            material.file_name().unwrap().to_string_lossy(),
        ),
    )
    .unwrap();
    let resolve = |p: &Path| -> Result<Arc<dyn Shader>, ResolveError> {
        Ok(load_textured(p, maps)?.expect("a [texture] material"))
    };
    let scene = Scene::from_toml_file(&scene_file, &resolve).unwrap();
    render(&scene, &RenderOptions::default(), None)
}

fn load_err(material: &Path) -> String {
    match load_textured(material, &MapsResolver::new()) {
        Err(e) => e,
        Ok(_) => panic!("{} loaded", material.display()),
    }
}

#[test]
fn a_map_file_renders_as_its_height_map() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("texture_reuse_map");
    let file = write_map(&dir, 4.0);
    extracted(&file).write(&dir.join("bumps.map")).unwrap();
    let heights = material(&dir, "heights", FROM_HEIGHTS);
    let from_map = material(
        &dir,
        "from-map",
        "kind = \"ndf-mapped\"\nmap = \"bumps.map\"",
    );
    // The extraction's keys may be repeated when they agree with the file.
    let agreeing = material(
        &dir,
        "agreeing",
        "kind = \"ndf-mapped\"\nmap = \"bumps.map\"\ntexel_size = 0.03125\nmax_lobes = 4\n\
         border = \"wrap\"\nnormals = \"triangles\"\nshadowing = true",
    );
    let a = render_with(&dir, &heights, &MapsResolver::new());
    let b = render_with(&dir, &from_map, &MapsResolver::new());
    let c = render_with(&dir, &agreeing, &MapsResolver::new());
    assert!(a.pixels().iter().any(|p| p.iter().any(|&v| v > 0.0)));
    assert_eq!(
        a.pixels(),
        b.pixels(),
        "map file and height map: the same image"
    );
    assert_eq!(b.pixels(), c.pixels());
    // Glossy facets (GGX α = 0.1: the box filter three levels finer) seen close, where the
    // detail reads level 0: the map file's tables, built on demand under a cap that holds
    // them all, read it too (before 2026-12-08 the cap kept the detail on level 1 and 3328 of
    // 4096 pixels of a new user's such view differed, by up to 11.7 %).
    let glossy = "[transfer]\nkind = \"microfacet\"\ndistribution = \"ggx\"\nalpha = 0.1\n";
    let write = |name: &str, texture: &str| {
        let p = dir.join(format!("{name}.toml"));
        std::fs::write(&p, format!("[texture]\n{texture}\n{glossy}")).unwrap();
        p
    };
    let heights = write("glossy-heights", FROM_HEIGHTS);
    let from_map = write("glossy-map", "kind = \"ndf-mapped\"\nmap = \"bumps.map\"");
    let maps = MapsResolver::new();
    let shader = load_textured(&from_map, &maps).unwrap().unwrap();
    let said = shader.describe().unwrap();
    assert!(!said.contains("table cap"), "{said}");
    let a = render_with_width(&dir, &heights, &MapsResolver::new(), 0.5);
    let b = render_with_width(&dir, &from_map, &MapsResolver::new(), 0.5);
    assert!(a.pixels().iter().any(|p| p.iter().any(|&v| v > 0.0)));
    assert_eq!(a.pixels(), b.pixels(), "glossy, close: the same image");
}

#[test]
fn the_second_load_reads_the_disk_cache() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("texture_reuse_hit");
    let file = write_map(&dir, 3.0);
    let m = material(&dir, "heights", FROM_HEIGHTS);
    let entry = entry(&file);
    let _ = std::fs::remove_file(&entry);
    let first = MapsResolver::new();
    let a = render_with(&dir, &m, &first);
    assert_eq!(first.disk_cache_hits(), 0, "nothing cached yet");
    assert!(entry.is_file(), "{} written", entry.display());
    let second = MapsResolver::new();
    let b = render_with(&dir, &m, &second);
    assert_eq!(second.disk_cache_hits(), 1, "read back, not extracted");
    assert_eq!(a.pixels(), b.pixels());
    // The cached pyramid is the extracted one, as the map file stores it.
    let table: toml::Table = format!(
        "kind = \"heightmap\"\n{}",
        FROM_HEIGHTS.replace("kind = \"ndf-mapped\"\n", "")
    )
    .parse()
    .unwrap();
    let third = MapsResolver::new();
    let cached = third.heightmap_pyramid(&table, &file).unwrap();
    assert_eq!(third.disk_cache_hits(), 1);
    let bytes = extracted(&file).to_bytes();
    assert_eq!(cached.to_bytes(), bytes);
    assert_eq!(*cached, Pyramid::from_bytes(&file, &bytes).unwrap());
    // The entry holds those very bytes (map format 4, what `meso extract` writes), after its
    // 44-byte header and the load's warnings (none for this map), before its 32-byte seal.
    assert_eq!(bytes[8..12], meso_maps::format::VERSION.to_le_bytes());
    let stored = std::fs::read(&entry).unwrap();
    let mut payload = &stored[44..stored.len() - 32];
    let warnings = meso_maps::disk_cache::take_warnings(&mut payload).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!(payload == &bytes[..]);
}

#[test]
fn a_damaged_cache_entry_is_rebuilt() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("texture_reuse_damaged");
    let file = write_map(&dir, 2.0);
    let m = material(&dir, "heights", FROM_HEIGHTS);
    let entry = entry(&file);
    let good = render_with(&dir, &m, &MapsResolver::new());
    let intact = std::fs::read(&entry).unwrap();
    let mut flipped = intact.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 0x40;
    for damaged in [
        flipped,
        intact[..intact.len() / 3].to_vec(),
        intact[..20].to_vec(),
        Vec::new(),
    ] {
        std::fs::write(&entry, &damaged).unwrap();
        let maps = MapsResolver::new();
        let img = render_with(&dir, &m, &maps);
        assert_eq!(maps.disk_cache_hits(), 0, "a damaged entry is a miss");
        assert_eq!(img.pixels(), good.pixels());
        assert_eq!(std::fs::read(&entry).unwrap(), intact, "rebuilt");
    }
    let maps = MapsResolver::new();
    render_with(&dir, &m, &maps);
    assert_eq!(maps.disk_cache_hits(), 1);
}

#[test]
fn map_files_are_refused_where_they_cannot_serve() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("texture_reuse_refused");
    let file = write_map(&dir, 5.0);
    extracted(&file).write(&dir.join("bumps.map")).unwrap();
    let bump = material(&dir, "bump", "kind = \"bump-mapped\"\nmap = \"bumps.map\"");
    let e = load_err(&bump);
    assert!(
        e.contains("bumps.map") && e.contains("bump-mapped") && e.contains("heights"),
        "{e}"
    );
    let twice = material(
        &dir,
        "twice",
        "kind = \"ndf-mapped\"\nmap = \"bumps.map\"\ntexel_size = 0.05",
    );
    let e = load_err(&twice);
    assert!(
        e.contains("texel_size = 0.05 conflicts")
            && e.contains("0.03125")
            && e.contains("bumps.map"),
        "{e}"
    );
    for (name, extra, what) in [
        ("lobes", "max_lobes = 2", "max_lobes = 2 conflicts"),
        (
            "border",
            "border = \"clamp\"",
            "border = \"clamp\" conflicts",
        ),
        (
            "scale",
            "height_scale = 0.035",
            "height_scale: does not apply",
        ),
        ("both", "file = \"bumps.exr\"", "exclude each other"),
    ] {
        let m = material(
            &dir,
            name,
            &format!("kind = \"ndf-mapped\"\nmap = \"bumps.map\"\n{extra}"),
        );
        let e = load_err(&m);
        assert!(e.contains(what), "{name}: {e}");
    }
    // A map file given as a height map: told to use `map`, not "Invalid PNG signature".
    let as_heights = material(
        &dir,
        "as-heights",
        "kind = \"ndf-mapped\"\nfile = \"bumps.map\"\ntexel_size = 0.03125\nheight_scale = 0.035",
    );
    let e = load_err(&as_heights);
    assert!(e.contains("bumps.map") && e.contains("map = "), "{e}");
    // A damaged map file: the reader's error, naming it.
    std::fs::write(dir.join("broken.map"), b"MESOMAP\0\x02\0\0\0").unwrap();
    let broken = material(
        &dir,
        "broken",
        "kind = \"ndf-mapped\"\nmap = \"broken.map\"",
    );
    let e = load_err(&broken);
    assert!(e.contains("broken.map"), "{e}");
}
