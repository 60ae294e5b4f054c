//! `MapsResolver::with_progress`: a pyramid extraction through the resolver reports its
//! progress, up to every texel, once per extraction (the cache answers the second call). The
//! disk cache (`meso_maps::pyramid_cache`) is off in this binary, so that every run extracts.
//! A map file read through the resolver (`MapsResolver::read_map_file`, what `meso render`'s
//! `[texture] map` does) reports its reading through the same hook, as task `Read`.

use meso_maps::MapsResolver;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

#[test]
fn extraction_progress_reaches_every_texel_once() {
    std::env::set_var("MESO_CACHE_DIR", "off");
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("resolver_progress");
    std::fs::create_dir_all(&dir).unwrap();
    let n = 16usize;
    let values: Vec<f32> = (0..n * n)
        .map(|k| ((k % n) as f32 * 0.7).sin() * ((k / n) as f32 * 0.4).cos())
        .collect();
    let file = dir.join("h.exr");
    std::fs::write(
        &file,
        meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap(),
    )
    .unwrap();
    let (done, total, calls) = (
        Arc::new(AtomicU64::new(0)),
        Arc::new(AtomicU64::new(0)),
        Arc::new(AtomicU64::new(0)),
    );
    let (d, t, c) = (done.clone(), total.clone(), calls.clone());
    let maps = MapsResolver::new().with_progress(Arc::new(move |path, p| {
        assert!(path.ends_with("h.exr"));
        d.fetch_max(p.texels_done, Ordering::Relaxed);
        t.store(p.texels_total, Ordering::Relaxed);
        c.fetch_add(1, Ordering::Relaxed);
    }));
    let table: toml::Table =
        "kind = \"heightmap\"\nfile = \"h.exr\"\ntexel_size = 0.1\nheight_scale = 0.05"
            .parse()
            .unwrap();
    let pyr = maps.heightmap_pyramid(&table, &file).unwrap();
    let texels: u64 = pyr.levels.iter().map(|l| l.texels() as u64).sum();
    assert!(total.load(Ordering::Relaxed) > 0);
    assert_eq!(done.load(Ordering::Relaxed), total.load(Ordering::Relaxed));
    assert!(total.load(Ordering::Relaxed) <= texels);
    let first = calls.load(Ordering::Relaxed);
    assert!(first > 0);
    maps.heightmap_pyramid(&table, &file).unwrap();
    assert_eq!(
        calls.load(Ordering::Relaxed),
        first,
        "cached: no second extraction"
    );
}

#[test]
fn reading_a_map_file_reports_through_the_resolver() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("resolver_progress");
    std::fs::create_dir_all(&dir).unwrap();
    let map = meso_maps::fixtures::gaussian(64, 4.0, 0.1, 3, 0.01).unwrap();
    let pyr = meso_maps::extract(
        meso_maps::Source::Heights(&map),
        &meso_maps::ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let file = dir.join("g64.map");
    pyr.write(&file).unwrap();
    let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
    let s = seen.clone();
    let maps = MapsResolver::new().with_progress(Arc::new(move |path, p| {
        assert!(path.ends_with("g64.map"));
        s.lock().unwrap().push(p);
    }));
    let read = maps.read_map_file(&file).unwrap();
    assert!(read.to_bytes() == pyr.to_bytes());
    let seen = seen.lock().unwrap();
    assert!(seen.len() > pyr.levels.len(), "{} reports", seen.len());
    assert!(seen.iter().all(|p| p.task == meso_maps::ProgressTask::Read));
    let last = seen.last().unwrap();
    assert_eq!(last.work_done, last.work_total);
    // Without a hook: the same pyramid, nothing reported.
    assert!(MapsResolver::new().read_map_file(&file).unwrap().to_bytes() == pyr.to_bytes());
}
