//! The top level's errors against `max_lobes` (issue #11 item 4, "monotone K") on the real 256²
//! facade maps of `tests/data` (the normal map and the height map, 1/256 texel, height scale
//! 0.05) and a steep 128² Gaussian surface (RMS slope ≈ 1.5): for Toksvig and K = 1, 2, 4, 8,
//! the top level's shading error (% of the peak, `fit::shading_error`), its binned NDF residual,
//! the total number of lobes of the pyramid and the extraction time.
//!
//! ```text
//! cargo run --release -p meso-maps --example k_curve [OLD_PREFIX]
//! ```
//! With `OLD_PREFIX`, map files `OLD_PREFIX_{normal,height,steep}_{t,1,2,4,8}.map` written by
//! another build (e.g. an older fitter, format version 2) are evaluated the same way.
use meso_maps::fit::{merge_entries, shading_error, Entry, FitParams};
use meso_maps::*;
use std::path::Path;

/// The top-level shading error (fraction of the peak) of `lobes` against all of `facets`.
fn top_error(facets: &FacetNormals, lobes: &[meso_core::ndf::PhongLobe]) -> f64 {
    let singles: Vec<Entry> = facets
        .footprint(0, facets.rows, 0, facets.cols)
        .map(|(n, w)| Entry::new(n, w))
        .collect();
    let mut entries = Vec::new();
    merge_entries(&[&singles], &mut entries);
    shading_error(&entries, lobes, FitParams::default().smooth_exponent).rms_of_peak
}

fn main() {
    let old = std::env::args().nth(1);
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let nm = NormalMap::load(&d.join("facade_normal_256.png"), NormalConvention::Gl).unwrap();
    let hm = HeightMap::load(
        &d.join("facade_disp_256.png"),
        1.0 / 256.0,
        0.05,
        Border::Wrap,
    )
    .unwrap();
    let steep = fixtures::gaussian(128, 2.0, 1.5, 3, 1.0 / 128.0).unwrap();
    for (name, src) in [
        ("normal", Source::Normals(&nm)),
        ("height", Source::Heights(&hm)),
        ("steep", Source::Heights(&steep)),
    ] {
        let facets = match src {
            Source::Normals(n) => FacetNormals::from_normal_map(n),
            Source::Heights(h) => FacetNormals::from_heightmap(h, NormalMode::Triangles),
        };
        for (tag, k, m) in [
            ("t", 1, Method::Baseline(Baseline::Toksvig)),
            ("1", 1, Method::Lobes),
            ("2", 2, Method::Lobes),
            ("4", 4, Method::Lobes),
            ("8", 8, Method::Lobes),
        ] {
            let mut p = ExtractParams::default();
            p.fit.max_lobes = k;
            p.method = m;
            let t = std::time::Instant::now();
            let pyr = extract(src, &p, &mut |_| {}).unwrap();
            let dt = t.elapsed().as_secs_f64();
            let lobes: usize = pyr.levels.iter().map(|l| l.lobes.len()).sum();
            let top = pyr.top();
            let e = top_error(&facets, top.texel_lobes(0, 0).unwrap());
            print!(
                "{name:<7} {tag}: top shading error {:6.2} % (stored {:6.2} %), NDF residual {:.4}, {lobes:>7} lobes, {dt:5.1} s",
                100.0 * e,
                100.0 * top.residual.shading_mean.unwrap_or(f64::NAN),
                top.residual.mean
            );
            if let Some(o) = &old {
                let q = Pyramid::read(Path::new(&format!("{o}_{name}_{tag}.map"))).unwrap();
                let lobes: usize = q.levels.iter().map(|l| l.lobes.len()).sum();
                let e = top_error(&facets, q.top().texel_lobes(0, 0).unwrap());
                print!(
                    " | old: {:6.2} %, NDF residual {:.4}, {lobes:>7} lobes",
                    100.0 * e,
                    q.top().residual.mean
                );
            }
            println!();
        }
    }
}
