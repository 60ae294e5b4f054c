//! `meso_maps::pyramid_cache`: an extraction is stored and read back by key (the map file's
//! pyramid, bit for bit); a changed parameter is another key; `MESO_CACHE_DIR=off` stores
//! nothing. This binary sets `MESO_CACHE_DIR` itself (one test: the variable is global).

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
