//! Probe of the lobe fit's shading error on four 64²/32² maps (the zoom egg crate, the materials
//! test's egg crate, half-cylinders, a Gaussian surface): per pyramid level, the texel average of
//! the Phong-facet shading `(m·h)^η (m·i)⁺ / i_z` over the footprint's triangles (truth) against
//! the texel's lobes integrated by quadrature (projected-area weights on both sides).
//!
//! Columns: level; at the diag's pair (`ndf_diag`'s view and light) `Σ|lobes − truth| / Σ truth`
//! (and signed); over ten more pairs `Σ_pairs Σ_texels |lobes − truth| / Σ_pairs Σ_texels truth`
//! and the worst pair's relative error (pairs with tiny truth, e.g. half vectors beyond the
//! steepest slope, dominate it); lobes per texel; the level's binned NDF residual. At most 64
//! texels per level (strided).
//!
//! ```text
//! CARGO_TARGET_DIR=/work/targets/maps cargo run --release -p meso-maps --example fit_probe [K]
//! ```
//! Environment: `SMOOTH=λ` sets `FitParams::smooth_exponent` (0: EM only), `FETA=η` the facet
//! exponent of every map (default 40 for the zoom map, 20 for the others), `SHOW=1` prints the
//! coarse texels' lobes, `VIEWS=1` the top level's per-pair errors.
use glam::DVec3;
use meso_maps::*;
use meso_testkit::lobes::phong_peaks_average;

fn spec(eta: f64, m: DVec3, wi: DVec3, h: DVec3) -> f64 {
    let mi = m.dot(wi);
    if mi <= 0.0 {
        return 0.0;
    }
    m.dot(h).max(0.0).powf(eta) * mi / wi.z
}

fn d(t: f64, p: f64) -> DVec3 {
    let (t, p) = (t.to_radians(), p.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn main() {
    let k: usize = std::env::args().nth(1).map_or(4, |a| a.parse().unwrap());
    let tau = std::f64::consts::TAU;
    let zoom = HeightMap::from_fn(64, 64, 1.0 / 64.0, Border::Wrap, |x, y| {
        0.03 * (tau * x / 0.25).sin() * (tau * y / 0.25).sin()
    })
    .unwrap();
    let test = HeightMap::from_fn(32, 32, 1.0 / 32.0, Border::Wrap, |x, y| {
        0.035 * (tau * x / 0.25).sin() * (tau * y / 0.25).sin()
    })
    .unwrap();
    let cyl = fixtures::half_cylinders(64, 16, 0.05, 1.0).unwrap();
    let gauss = fixtures::gaussian(64, 3.0, 0.15, 11, 0.1).unwrap();
    let diag_zoom = (
        DVec3::new(-0.75, 0.35, 0.57).normalize(),
        DVec3::new(0.0, -0.5, 0.866_025_403_784_438_6),
    );
    let diag_test = (
        DVec3::new(-0.5, 0.3, 0.8).normalize(),
        DVec3::new(0.0, -0.4, 0.9).normalize(),
    );
    let mut views = vec![];
    for (ti, pi, to, po) in [
        (0.0, 0.0, 0.0, 0.0),
        (30.0, 0.0, 30.0, 180.0),
        (30.0, 0.0, 0.0, 0.0),
        (45.0, 20.0, 10.0, 200.0),
        (60.0, 0.0, 20.0, 90.0),
        (40.0, 45.0, 40.0, 45.0),
        (50.0, 120.0, 30.0, 250.0),
        (20.0, 300.0, 60.0, 60.0),
        (70.0, 10.0, 50.0, 10.0),
        (35.0, 210.0, 15.0, 170.0),
    ] {
        views.push((d(ti, pi), d(to, po)));
    }
    let feta: f64 = std::env::var("FETA").map_or(0.0, |v| v.parse().unwrap());
    for (name, map, em_points, eta, diag) in [
        ("zoom", &zoom, 1usize << 14, 40.0, diag_zoom),
        ("test", &test, 512, 20.0, diag_test),
        ("cyl", &cyl, 512, 20.0, diag_test),
        ("gauss", &gauss, 512, 20.0, diag_test),
    ] {
        let eta = if feta > 0.0 { feta } else { eta };
        let mut p = ExtractParams::default().with_max_lobes(k);
        p.fit.max_em_points = em_points;
        if let Ok(v) = std::env::var("SMOOTH") {
            p.fit.smooth_exponent = v.parse().unwrap();
        }
        let t0 = std::time::Instant::now();
        let mut lt = vec![];
        let pyr = extract(Source::Heights(map), &p, &mut |_| {
            lt.push(t0.elapsed().as_secs_f64())
        })
        .unwrap();
        println!(
            "level end times {:?}",
            lt.iter().map(|v| format!("{v:.3}")).collect::<Vec<_>>()
        );
        let dt = t0.elapsed().as_secs_f64();
        let fac = FacetNormals::from_heightmap(map, NormalMode::Triangles);
        println!("== {name} (K={k}, extract {dt:.3} s): level, diag |err| (signed), views mean |err|, worst view |err|, lobes/texel, residual");
        for (lk, lev) in pyr.levels.iter().enumerate().skip(1) {
            let span = lev.span;
            let n = lev.texels();
            let stride = n.div_ceil(64);
            let mut per_view = vec![];
            for (vi, &(wi, wo)) in std::iter::once(&diag).chain(views.iter()).enumerate() {
                let h = (wi + wo).normalize();
                let (mut e, mut b, mut s) = (0.0, 0.0, 0.0);
                for t in (0..n).step_by(stride) {
                    let (r, c) = (t / lev.cols, t % lev.cols);
                    let (r0, r1) = (r * span, ((r + 1) * span).min(fac.rows));
                    let (c0, c1) = (c * span, ((c + 1) * span).min(fac.cols));
                    let (mut num, mut cnt) = (0.0, 0.0);
                    for (m, _) in fac.footprint(r0, r1, c0, c1) {
                        num += spec(eta, m, wi, h);
                        cnt += 1.0;
                    }
                    let truth = num / cnt;
                    let lq = phong_peaks_average(
                        &lev.texel_lobes(r, c).unwrap(),
                        &|m| spec(eta, m, wi, h),
                        (200, 64),
                    );
                    e += (lq - truth).abs();
                    b += lq - truth;
                    s += truth;
                }
                if std::env::var("VIEWS").is_ok() && lk + 1 == pyr.levels.len() {
                    println!("   view {vi}: truth {:.4e} rel {:+.3}", s, b / s);
                }
                per_view.push((e / s, b / s, e, s));
            }
            let vm = per_view[1..].iter().map(|v| v.2).sum::<f64>()
                / per_view[1..].iter().map(|v| v.3).sum::<f64>();
            let vw = per_view[1..].iter().map(|v| v.0).fold(0.0, f64::max);
            println!(
                "{lk:>3}  {:.4} ({:+.4})  {:.4}  {:.4}  {:.2}  {:.3}",
                per_view[0].0,
                per_view[0].1,
                vm,
                vw,
                lev.lobes.len() as f64 / n as f64,
                lev.residual.mean
            );
        }
        if std::env::var("SHOW").is_ok() {
            for lev in pyr.levels.iter().skip(3) {
                println!(
                    "span {}: {:?}",
                    lev.span,
                    lev.texel_lobes(0, 0)
                        .unwrap()
                        .iter()
                        .map(|l| {
                            let (t, ph) = (
                                l.axis.z.acos().to_degrees(),
                                l.axis.y.atan2(l.axis.x).to_degrees(),
                            );
                            format!("t{t:.1} p{ph:.0} w{:.3} e{:.0}", l.weight, l.exponent)
                        })
                        .collect::<Vec<_>>()
                );
            }
        }
    }
}
