//! The fixtures of the version-2 and version-3 reader tests (crates/meso-maps/tests/data/README.md),
//! written with the version-2 and version-3 writers this build still has: a 16² Gaussian height
//! map (horizon statistics; K ≤ 4) and the 32² corner of `facade_normal_256.png` (no horizon
//! statistics; K ≤ 4), each as `*.v2.map` and `*.v3.map` of the same pyramid.
//!
//! ```text
//! cargo run --release -p meso-maps --example map_fixtures -- crates/meso-maps/tests/data
//! ```
use meso_maps::*;
use std::path::PathBuf;

fn main() {
    let dir = PathBuf::from(std::env::args().nth(1).expect("usage: map_fixtures DIR"));
    let mut params = ExtractParams::default();
    params.fit.max_lobes = 4;
    let heights = fixtures::gaussian(16, 2.0, 0.1, 3, 0.1).unwrap();
    let h = extract(Source::Heights(&heights), &params, &mut |_| {}).unwrap();
    let full = NormalMap::load(&dir.join("facade_normal_256.png"), NormalConvention::Gl).unwrap();
    let (w, n) = (256, 32);
    assert_eq!(full.normals().len(), w * w);
    let corner: Vec<_> = (0..n)
        .flat_map(|r| (0..n).map(move |c| (r, c)))
        .map(|(r, c)| full.normals()[r * w + c])
        .collect();
    let normals = NormalMap::from_normals(n, n, corner).unwrap();
    let nm = extract(Source::Normals(&normals), &params, &mut |_| {}).unwrap();
    for (name, p) in [("heights16", &h), ("normals32", &nm)] {
        let mut v2 = Vec::new();
        p.write_v2_to(&mut v2).unwrap();
        std::fs::write(dir.join(format!("{name}.v2.map")), &v2).unwrap();
        p.write(&dir.join(format!("{name}.v3.map"))).unwrap();
        let v3 = std::fs::read(dir.join(format!("{name}.v3.map"))).unwrap();
        let lobes: usize = p.levels.iter().map(|l| l.lobes.len()).sum();
        println!(
            "{name}: {} levels, {lobes} lobes, horizon {}: v2 {} B, v3 {} B",
            p.levels.len(),
            p.levels[0].horizon.is_some(),
            v2.len(),
            v3.len()
        );
    }
}
