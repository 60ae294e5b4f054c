//! The on-disk cache of height-map facets (`meso_maps::facet_cache`): a second load reads the
//! same NDF and visibility back (identical BRDF values), a damaged, truncated or foreign entry
//! is rebuilt rather than trusted (a checksum covers every byte), and another parameter is another entry. One test function:
//! it sets `MESO_CACHE_DIR` for this test binary.

use meso_core::frame::spherical_direction_deg as d;
use meso_core::material::Material;
use meso_maps::facet_cache::{cache_dir, facets_cached};
use meso_maps::{facets_with_visibility, fixtures, Border, HeightMap, MapsResolver, NormalMode};
use std::path::Path;

fn entries(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .map(|r| r.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn facet_cache_round_trip_damage_and_keys() {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("facet_cache");
    let _ = std::fs::remove_dir_all(&root);
    let cache = root.join("cache");
    std::fs::create_dir_all(&root).unwrap();
    std::env::set_var("MESO_CACHE_DIR", &cache);
    assert_eq!(cache_dir().as_deref(), Some(cache.as_path()));

    let map = fixtures::gaussian(48, 2.0, 0.01, 3, 1.0 / 48.0).unwrap();
    let (png, scale) = map.encode_png16().unwrap();
    let file = root.join("g.png");
    std::fs::write(&file, png).unwrap();
    let toml = format!(
        "[ndf]\nkind = \"heightmap\"\nfile = \"g.png\"\ntexel_size = {}\nheight_scale = {scale}\n\
         [transfer]\nkind = \"microfacet\"\ndistribution = \"beckmann\"\nalpha = 0.1\nfresnel = \"none\"\n",
        1.0 / 48.0
    );
    let mat = root.join("m.toml");
    std::fs::write(&mat, toml).unwrap();
    let pairs = [
        (d(30.0, 0.0), d(30.0, 180.0)),
        (d(60.0, 40.0), d(20.0, 250.0)),
    ];
    let values = || -> Vec<[f64; 3]> {
        let m = Material::from_file(&mat, &MapsResolver::new()).unwrap();
        pairs.iter().map(|&(i, o)| m.brdf(i, o)).collect()
    };

    // First load builds and stores one entry; the second reads it and agrees exactly.
    let first = values();
    let stored = entries(&cache);
    assert_eq!(stored.len(), 1, "{stored:?}");
    let second = values();
    // The same up to the last digits (the stored weights are normalised again on reading).
    let same = |a: &[[f64; 3]], b: &[[f64; 3]]| {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() <= 1e-12 * x.abs())
    };
    assert!(same(&first, &second), "{first:?} vs {second:?}");

    let load =
        || HeightMap::load(&file, 1.0 / 48.0, scale, Border::Wrap).map_err(|e| e.to_string());
    let cached = |load: &dyn Fn() -> Result<HeightMap, String>| {
        facets_cached(
            &file,
            1.0 / 48.0,
            scale,
            Border::Wrap,
            NormalMode::Triangles,
            load,
            |m| facets_with_visibility(m, NormalMode::Triangles),
        )
        .unwrap()
        .hit
    };
    assert!(cached(&load), "the second load is answered by the cache");
    // On a hit the image is not decoded at all.
    assert!(cached(&|| Err("must not be called".to_string())));

    // Damaged entries are rebuilt, never trusted: a flipped byte in the data, a truncation,
    // another entry's content under this name.
    let entry = &stored[0];
    let good = std::fs::read(entry).unwrap();
    for bad in [
        {
            let mut b = good.clone();
            let k = b.len() - 9;
            b[k] ^= 0x40;
            b
        },
        good[..good.len() / 2].to_vec(),
        b"MESOFCT\0not a cache".to_vec(),
    ] {
        std::fs::write(entry, &bad).unwrap();
        assert!(
            !cached(&load),
            "a damaged entry ({} bytes) was used",
            bad.len()
        );
        // Rebuilt and stored again: the same bytes as before (the build is deterministic).
        assert_eq!(std::fs::read(entry).unwrap(), good);
        assert!(same(&values(), &first));
    }

    // Another parameter is another key.
    let _ = facets_cached(
        &file,
        1.0 / 48.0,
        scale * 2.0,
        Border::Wrap,
        NormalMode::Triangles,
        || HeightMap::load(&file, 1.0 / 48.0, scale * 2.0, Border::Wrap).map_err(|e| e.to_string()),
        |m| facets_with_visibility(m, NormalMode::Triangles),
    )
    .unwrap();
    assert_eq!(entries(&cache).len(), 2);

    // Off: nothing read or written.
    std::env::set_var("MESO_CACHE_DIR", "off");
    assert_eq!(cache_dir(), None);
    let _ = std::fs::remove_dir_all(&cache);
    assert!(same(&values(), &first));
    assert!(!cache.exists());

    a_hit_says_the_loads_warnings();
}

/// A hit says the warnings of the load that built the entry: a colour image given as a height
/// map is warned about on the second load too, although the image is then not decoded. (Called
/// from the one test function: `MESO_CACHE_DIR` is global.)
fn a_hit_says_the_loads_warnings() {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("facet_cache_warnings");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let file = root.join("colour.png");
    image::RgbImage::from_fn(16, 16, |x, y| {
        image::Rgb([(x * 16) as u8, (y * 16) as u8, ((x + y) * 8) as u8])
    })
    .save(&file)
    .unwrap();
    let dir = root.join("cache");
    let run = |load_allowed: bool| facets_cached_in(&dir, &file, load_allowed);
    let first = run(true);
    assert!(!first.hit);
    assert!(
        first.warnings.iter().any(|w| w.contains("colour")),
        "{:?}",
        first.warnings
    );
    let second = run(false);
    assert!(second.hit, "the second load is answered by the cache");
    assert_eq!(second.warnings, first.warnings);
}

fn facets_cached_in(
    dir: &Path,
    file: &Path,
    load_allowed: bool,
) -> meso_maps::disk_cache::Cached<(meso_core::ndf::Ndf, meso_maps::FacetVisibility)> {
    std::env::set_var("MESO_CACHE_DIR", dir);
    facets_cached(
        file,
        0.1,
        0.1,
        Border::Wrap,
        NormalMode::Triangles,
        || {
            if load_allowed {
                HeightMap::load(file, 0.1, 0.1, Border::Wrap).map_err(|e| e.to_string())
            } else {
                Err("must not be decoded".to_string())
            }
        },
        |m| facets_with_visibility(m, NormalMode::Triangles),
    )
    .unwrap()
}
