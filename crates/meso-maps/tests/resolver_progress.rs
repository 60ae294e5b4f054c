//! `MapsResolver::with_progress`: a pyramid extraction through the resolver reports its
//! progress, up to every texel, once per extraction (the cache answers the second call). The
//! disk cache (`meso_maps::pyramid_cache`) is off in this binary, so that every run extracts.

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
