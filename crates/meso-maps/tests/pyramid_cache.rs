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
    // The build's load warnings are kept in the entry and returned by a hit.
    let warned = vec!["first warning".to_string(), "second, ü".to_string()];
    let build = || -> Result<(Pyramid, Vec<String>), String> {
        let map = HeightMap::load(&file, s, h, Border::Wrap).map_err(|e| e.to_string())?;
        let p = extract(Source::Heights(&map), &params, &mut |_| {}).map_err(|e| e.to_string())?;
        Ok((p, warned.clone()))
    };
    let as_stored = Pyramid::from_bytes(&file, &build().unwrap().0.to_bytes()).unwrap();

    std::env::set_var("MESO_CACHE_DIR", "off");
    let got = pyramid_cached(&file, s, h, Border::Wrap, &params, build).unwrap();
    assert!(!got.hit);
    assert_eq!(got.warnings, warned);
    assert_eq!(
        got.value, as_stored,
        "the map file's pyramid even without a cache"
    );
    assert!(!cache.exists(), "off: nothing written");

    std::env::set_var("MESO_CACHE_DIR", &cache);
    let k = key(&std::fs::read(&file).unwrap(), s, h, Border::Wrap, &params);
    let got = pyramid_cached(&file, s, h, Border::Wrap, &params, build).unwrap();
    assert!(!got.hit && got.value == as_stored && got.warnings == warned);
    assert!(entry_path(&cache, &k).is_file());
    let got = pyramid_cached(&file, s, h, Border::Wrap, &params, || {
        Err::<(Pyramid, Vec<String>), String>("must not build".into())
    })
    .unwrap();
    assert!(got.hit && got.value == as_stored);
    assert_eq!(got.warnings, warned, "a hit says the build's warnings");
    // The entry: its 44-byte header (magic, format, key), the warnings (a count, then each
    // one's length and text), the map file (version 4), its seal.
    let entry = std::fs::read(entry_path(&cache, &k)).unwrap();
    let mut notes = Vec::new();
    meso_maps::disk_cache::put_warnings(&mut notes, &warned);
    assert_eq!(notes.len(), 4 + 4 + 13 + 4 + 10);
    assert_eq!(&entry[44..44 + notes.len()], &notes[..]);
    let map = &entry[44 + notes.len()..entry.len() - 32];
    assert_eq!(&map[..8], b"MESOMAP\0");
    assert_eq!(map[8..12], meso_maps::format::VERSION.to_le_bytes());
    assert!(map == build().unwrap().0.to_bytes());
    // An entry written by an earlier build (map format 3, the same key) still answers.
    let v3 = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/heights16.v3.map");
    let v3 = std::fs::read(v3).unwrap();
    assert_eq!(v3[8..12], meso_maps::format::VERSION_3.to_le_bytes());
    let mut old = entry[..44].to_vec();
    meso_maps::disk_cache::put_warnings(&mut old, &[]);
    old.extend_from_slice(&v3);
    meso_maps::disk_cache::seal(&mut old);
    std::fs::write(entry_path(&cache, &k), &old).unwrap();
    let got = pyramid_cached(&file, s, h, Border::Wrap, &params, || {
        Err::<(Pyramid, Vec<String>), String>("must not build".into())
    })
    .unwrap();
    assert!(got.hit && got.value == Pyramid::from_bytes(&file, &v3).unwrap());
    assert!(got.warnings.is_empty());
    // Warnings that are not well formed (a count over the limit) make the entry a miss.
    let mut bad = entry[..44].to_vec();
    bad.extend_from_slice(&u32::MAX.to_le_bytes());
    bad.extend_from_slice(&v3);
    meso_maps::disk_cache::seal(&mut bad);
    std::fs::write(entry_path(&cache, &k), &bad).unwrap();
    let e = pyramid_cached(&file, s, h, Border::Wrap, &params, || {
        Err::<(Pyramid, Vec<String>), String>("rebuilt".into())
    });
    assert_eq!(e.unwrap_err(), "rebuilt");
    // Another parameter, another key: built again.
    let mut two = params.clone();
    two = two.with_max_lobes(2);
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
        Err::<(Pyramid, Vec<String>), String>("built".into())
    });
    assert_eq!(e.unwrap_err(), "built");
}
