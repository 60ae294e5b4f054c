//! `meso_maps::pyramid_cache`: an extraction is stored and read back by key (the map file's
//! pyramid, bit for bit, in map format 4); a changed parameter is another key; an entry of map
//! format 3 (written by earlier builds) still answers; `MESO_CACHE_DIR=off` stores nothing.
//! This binary sets `MESO_CACHE_DIR` itself (one test: the variable is global).

use meso_maps::pyramid_cache::{entry_path, key, pyramid_cached};
use meso_maps::{extract, Border, ExtractParams, HeightMap, Pyramid, Source};
use std::path::Path;

#[test]
fn stored_read_back_keyed_and_off() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("pyramid_cache");
    let cache = dir.join("cache");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let n = 16usize;
    let values: Vec<f32> = (0..n * n)
        .map(|k| ((k % n) as f32 * 0.9).sin() * ((k / n) as f32 * 0.5).cos())
        .collect();
    let file = dir.join("h.exr");
    std::fs::write(
        &file,
        meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap(),
    )
    .unwrap();
    let (s, h) = (0.1, 0.05);
    let params = ExtractParams::default();
    let build = || -> Result<Pyramid, String> {
        let map = HeightMap::load(&file, s, h, Border::Wrap).map_err(|e| e.to_string())?;
        extract(Source::Heights(&map), &params, &mut |_| {}).map_err(|e| e.to_string())
    };
    let as_stored = Pyramid::from_bytes(&file, &build().unwrap().to_bytes()).unwrap();

    std::env::set_var("MESO_CACHE_DIR", "off");
    let (p, hit) = pyramid_cached(&file, s, h, Border::Wrap, &params, build).unwrap();
    assert!(!hit);
    assert_eq!(p, as_stored, "the map file's pyramid even without a cache");
    assert!(!cache.exists(), "off: nothing written");

    std::env::set_var("MESO_CACHE_DIR", &cache);
    let k = key(&std::fs::read(&file).unwrap(), s, h, Border::Wrap, &params);
    let (p, hit) = pyramid_cached(&file, s, h, Border::Wrap, &params, build).unwrap();
    assert!(!hit && p == as_stored);
    assert!(entry_path(&cache, &k).is_file());
    let (p, hit) = pyramid_cached(&file, s, h, Border::Wrap, &params, || {
        Err::<Pyramid, String>("must not build".into())
    })
    .unwrap();
    assert!(hit && p == as_stored);
    // The entry: its 44-byte header (magic, format, key), the map file (version 4), its seal.
    let entry = std::fs::read(entry_path(&cache, &k)).unwrap();
    let map = &entry[44..entry.len() - 32];
    assert_eq!(&map[..8], b"MESOMAP\0");
    assert_eq!(map[8..12], meso_maps::format::VERSION.to_le_bytes());
    assert!(map == build().unwrap().to_bytes());
    // An entry written by an earlier build (map format 3, the same key) still answers.
    let v3 = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/heights16.v3.map");
    let v3 = std::fs::read(v3).unwrap();
    assert_eq!(v3[8..12], meso_maps::format::VERSION_3.to_le_bytes());
    let mut old = entry[..44].to_vec();
    old.extend_from_slice(&v3);
    meso_maps::disk_cache::seal(&mut old);
    std::fs::write(entry_path(&cache, &k), &old).unwrap();
    let (p, hit) = pyramid_cached(&file, s, h, Border::Wrap, &params, || {
        Err::<Pyramid, String>("must not build".into())
    })
    .unwrap();
    assert!(hit && p == Pyramid::from_bytes(&file, &v3).unwrap());
    // Another parameter, another key: built again.
    let mut two = params.clone();
    two.fit.max_lobes = 2;
    assert_ne!(
        key(&std::fs::read(&file).unwrap(), s, h, Border::Wrap, &two),
        k
    );
    assert_ne!(
        key(
            &std::fs::read(&file).unwrap(),
            s,
            h * 2.0,
            Border::Wrap,
            &params
        ),
        k
    );
    let e = pyramid_cached(&file, s, h, Border::Wrap, &two, || {
        Err::<Pyramid, String>("built".into())
    });
    assert_eq!(e.unwrap_err(), "built");
}
