//! `MapsResolver::with_progress`: a pyramid extraction through the resolver reports its
//! progress, up to every texel, once per extraction (the cache answers the second call).

use meso_maps::MapsResolver;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

#[test]
fn extraction_progress_reaches_every_texel_once() {
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

/// `facet_alpha` sets the kernel of the shading error (a sharper facet asks for more lobes),
/// is part of the cache key, and is refused outside 0.02–1 with a message naming it.
#[test]
fn facet_alpha_sets_the_kernel_and_is_checked() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("resolver_alpha");
    std::fs::create_dir_all(&dir).unwrap();
    let map = meso_maps::fixtures::gaussian(32, 2.0, 0.3, 4, 1.0).unwrap();
    let values: Vec<f32> = (0..32 * 32).map(|k| map.heights()[k] as f32).collect();
    let file = dir.join("g.exr");
    std::fs::write(
        &file,
        meso_maps::fixtures::exr_bytes(32, 32, &values).unwrap(),
    )
    .unwrap();
    let maps = MapsResolver::new();
    let table = |extra: &str| -> toml::Table {
        format!("kind = \"heightmap\"\nfile = \"g.exr\"\ntexel_size = 1.0\nheight_scale = 1.0\nmax_lobes = 8\n{extra}")
            .parse()
            .unwrap()
    };
    let lobes = |extra: &str| -> usize {
        let p = maps.heightmap_pyramid(&table(extra), &file).unwrap();
        p.levels.iter().map(|l| l.lobes.len()).sum()
    };
    let (wide, default, sharp) = (
        lobes("facet_alpha = 0.5"),
        lobes(""),
        lobes("facet_alpha = 0.05"),
    );
    assert!(
        wide < default && default < sharp,
        "lobes: α 0.5 {wide}, default {default}, α 0.05 {sharp}"
    );
    for bad in ["facet_alpha = 0.01", "facet_alpha = 2", "facet_alpha = -1"] {
        let e = maps.heightmap_pyramid(&table(bad), &file).unwrap_err();
        assert!(e.to_string().contains("facet_alpha"), "{e}");
    }
}
