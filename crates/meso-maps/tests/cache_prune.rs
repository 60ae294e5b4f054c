//! The disk cache (`meso_maps::disk_cache`) is bounded: `MESO_CACHE_MAX_BYTES` (default 2 GiB)
//! caps its entries, pruned least recently used first after every write (an entry read counts
//! as used); normal-map pyramids are cached like height-map ones
//! (`pyramid_cache::normal_pyramid_cached`, keyed by content, convention and parameters). This
//! binary sets `MESO_CACHE_DIR` and `MESO_CACHE_MAX_BYTES` itself (one test: the variables are
//! global).

use meso_maps::disk_cache::{self, max_bytes, prune, DEFAULT_MAX_BYTES, MAX_BYTES_VAR};
use meso_maps::pyramid_cache::{entry_path, key, normal_key, normal_pyramid_cached};
use meso_maps::{extract, Border, ExtractParams, NormalConvention, NormalMap, Pyramid, Source};
use std::cell::Cell;
use std::path::Path;
use std::time::{Duration, SystemTime};

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    v.sort();
    v
}

fn set_age(path: &Path, secs_ago: u64) {
    let f = std::fs::OpenOptions::new().append(true).open(path).unwrap();
    f.set_modified(SystemTime::now() - Duration::from_secs(secs_ago))
        .unwrap();
}

#[test]
fn normal_maps_cached_and_the_folder_pruned_least_recently_used_first() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cache_prune");
    let cache = dir.join("cache");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&cache).unwrap();

    // The cap: default, a size, an invalid value (ignored).
    std::env::remove_var(MAX_BYTES_VAR);
    assert_eq!(max_bytes(), DEFAULT_MAX_BYTES);
    assert_eq!(DEFAULT_MAX_BYTES, 2 << 30);
    std::env::set_var(MAX_BYTES_VAR, "500K");
    assert_eq!(max_bytes(), 500 << 10);
    std::env::set_var(MAX_BYTES_VAR, "lots");
    assert_eq!(max_bytes(), DEFAULT_MAX_BYTES);
    std::env::remove_var(MAX_BYTES_VAR);

    // A 16² OpenGL normal map of a bump, as an 8-bit PNG.
    let n = 16u32;
    let img = image::RgbImage::from_fn(n, n, |x, y| {
        let (u, v) = (
            (f64::from(x) / f64::from(n) * std::f64::consts::TAU).sin() * 0.4,
            (f64::from(y) / f64::from(n) * std::f64::consts::TAU).cos() * 0.3,
        );
        let len = (u * u + v * v + 1.0).sqrt();
        let c = |a: f64| ((a / len * 0.5 + 0.5) * 255.0).round() as u8;
        image::Rgb([c(-u), c(v), c(1.0)])
    });
    let file = dir.join("n.png");
    img.save(&file).unwrap();
    let bytes = std::fs::read(&file).unwrap();
    let params = ExtractParams::default();
    let builds = Cell::new(0);
    let build = |conv| {
        builds.set(builds.get() + 1);
        let map = NormalMap::load(&file, conv).map_err(|e| e.to_string())?;
        let p = extract(Source::Normals(&map), &params, &mut |_| {}).map_err(|e| e.to_string())?;
        Ok::<_, String>((p, Vec::new()))
    };

    std::env::set_var("MESO_CACHE_DIR", &cache);
    let gl = NormalConvention::Gl;
    let got = normal_pyramid_cached(&file, gl, &params, || build(gl)).unwrap();
    let (p1, hit) = (got.value, got.hit);
    assert!(!hit);
    let e_gl = entry_path(&cache, &normal_key(&bytes, gl, &params));
    assert!(e_gl.is_file(), "{:?}", entries(&cache));
    let got = normal_pyramid_cached(&file, gl, &params, || build(gl)).unwrap();
    let (p2, hit) = (got.value, got.hit);
    assert!(hit);
    assert_eq!(builds.get(), 1, "the second run does not extract");
    assert_eq!(p1, p2);
    assert_eq!(p1, Pyramid::from_bytes(&file, &p1.to_bytes()).unwrap());
    // The other convention, other parameters: other keys; a height map's key never collides.
    let dx = NormalConvention::Dx;
    let got = normal_pyramid_cached(&file, dx, &params, || build(dx)).unwrap();
    assert!(!got.hit && got.value != p1 && builds.get() == 2);
    let mut two = params.clone();
    two = two.with_max_lobes(2);
    assert_ne!(
        normal_key(&bytes, gl, &two),
        normal_key(&bytes, gl, &params)
    );
    assert_ne!(
        normal_key(&bytes, gl, &params),
        key(&bytes, 1.0, 1.0, Border::Wrap, &params)
    );

    // Pruning by hand: five 1000-byte entries of known ages and a foreign file.
    let junk = tempdir(&dir, "junk");
    let foreign = junk.join("notes.txt");
    std::fs::write(&foreign, vec![0u8; 10_000]).unwrap();
    let mut paths = Vec::new();
    for i in 0..5u8 {
        let k = [i; 32];
        disk_cache::write(&junk, "pyramid", &k, &[i; 1000]).unwrap();
        let p = disk_cache::entry_path(&junk, "pyramid", &k);
        set_age(&p, 100 - u64::from(i) * 10); // entry 0 is the oldest
        paths.push(p);
    }
    assert_eq!(prune(&junk, 3000, None), 2);
    assert!(!paths[0].exists() && !paths[1].exists());
    assert!(paths[2..].iter().all(|p| p.exists()));
    assert!(foreign.exists(), "only entries are pruned");
    // A read entry is the most recently used: entry 2 (the oldest left) survives, 3 goes.
    assert!(disk_cache::read(&junk, "pyramid", &[2; 32]).is_some());
    assert_eq!(prune(&junk, 2000, None), 1);
    assert!(paths[2].exists() && !paths[3].exists() && paths[4].exists());
    // `keep` is never removed, even alone above the cap.
    assert_eq!(prune(&junk, 0, Some(&paths[4])), 1);
    assert!(paths[4].exists() && !paths[2].exists() && foreign.exists());

    // After a write in the real cache: a 1-byte cap leaves only the entry just written.
    std::env::set_var(MAX_BYTES_VAR, "1");
    assert!(
        !normal_pyramid_cached(&file, gl, &two, || build(gl))
            .unwrap()
            .hit
    );
    let left = entries(&cache);
    assert_eq!(left.len(), 1, "{left:?}");
    assert!(entry_path(&cache, &normal_key(&bytes, gl, &two)).is_file());
    assert!(!e_gl.exists());
    std::env::remove_var(MAX_BYTES_VAR);
    std::env::set_var("MESO_CACHE_DIR", "off");
}

fn tempdir(dir: &Path, name: &str) -> std::path::PathBuf {
    let d = dir.join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}
