//! The memory check of a bump-mapped `[texture]` (what `meso render` builds from a height map):
//! its facet normals and shadow rays' tracer against the budget, refused one byte under it with
//! a message naming the file, built at it. Its own test binary: it sets the process's budget.

use meso_maps::MapsResolver;
use meso_render::{load_textured, BumpMapped};
use std::path::Path;

#[test]
fn a_bump_mapped_height_map_is_budgeted() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bump_budget");
    std::fs::create_dir_all(&dir).unwrap();
    let n = 32usize;
    let values: Vec<f32> = (0..n * n)
        .map(|k| ((k % n) as f32 * 0.4).sin() * ((k / n) as f32 * 0.3).cos())
        .collect();
    let exr = meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap();
    std::fs::write(dir.join("bumps.exr"), exr).unwrap();
    let mat = dir.join("bump.toml");
    std::fs::write(
        &mat,
        "[texture]\nkind = \"bump-mapped\"\nfile = \"bumps.exr\"\ntexel_size = 0.03125\n\
         height_scale = 0.035\n[transfer]\nkind = \"phong\"\nexponent = 20.0\n",
    )
    .unwrap();
    // A wrapped map of n² samples has n² cells; with shadowing (the default) the tracer too.
    let need = BumpMapped::bytes(n, n, true);
    assert!(need > BumpMapped::bytes(n, n, false));
    meso_core::budget::set_budget(need - 1);
    let e = match load_textured(&mat, &MapsResolver::new()) {
        Err(e) => e,
        Ok(_) => panic!("built over the budget"),
    };
    assert!(
        e.contains("bumps.exr")
            && e.contains("bump-mapping the height map")
            && e.contains("memory budget"),
        "{e}"
    );
    meso_core::budget::set_budget(need);
    let shader = load_textured(&mat, &MapsResolver::new()).unwrap().unwrap();
    assert!(
        shader.describe().unwrap().contains("ray-traced shadowing"),
        "{:?}",
        shader.describe()
    );
    meso_core::budget::set_budget(0);
}
