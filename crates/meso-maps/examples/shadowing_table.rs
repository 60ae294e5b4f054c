//! Which masking–shadowing model should be the default? The effective BRDF of the top-level
//! lobes (K ≤ 4) with Smith, horizon and no shadowing against the ray-traced
//! gonioreflectometer (single bounce), Lambert facets, on the fixture maps: the worst relative
//! error over direction pairs with θ ≤ 60° and over grazing pairs (θ ≥ 70°).
//!
//! ```text
//! CARGO_TARGET_DIR=/work/targets/maps cargo run --release -p meso-maps --example shadowing_table
//! ```
use meso_core::convolution::{effective_brdf_with, Accuracy, Form, Visibility};
use meso_core::frame::spherical_direction_deg as dir;
use meso_core::ndf::{Ndf, PhongPeaks};
use meso_core::transfer::Transfer;
use meso_core::visibility::VisibilityModel;
use meso_maps::*;

fn main() {
    let maps = [
        (
            "gaussian",
            fixtures::gaussian(64, 4.0, 0.12, 21, 0.1).unwrap(),
        ),
        ("v-grooves", fixtures::v_grooves(64, 16, 0.2, 0.05).unwrap()),
        ("woven", fixtures::woven(64, 16, 0.1, 0.05).unwrap()),
    ];
    let low: [(f64, f64, f64, f64); 7] = [
        (0.0, 0.0, 0.0, 0.0),
        (30.0, 0.0, 30.0, 180.0),
        (45.0, 0.0, 45.0, 180.0),
        (60.0, 0.0, 60.0, 180.0),
        (60.0, 0.0, 30.0, 180.0),
        (45.0, 0.0, 60.0, 90.0),
        (30.0, 0.0, 60.0, 0.0),
    ];
    let grazing: [(f64, f64, f64, f64); 5] = [
        (75.0, 0.0, 75.0, 180.0),
        (80.0, 0.0, 60.0, 180.0),
        (70.0, 0.0, 70.0, 0.0),
        (85.0, 0.0, 45.0, 180.0),
        (75.0, 90.0, 75.0, 270.0),
    ];
    let facet = Transfer::Lambert { albedo: [1.0; 3] };
    let gp = GonioParams {
        rays_per_side: 128,
        ..Default::default()
    };
    println!("| map | θ ≤ 60°: Smith | horizon | none | θ ≥ 70°: Smith | horizon | none |");
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for (name, map) in &maps {
        let pyr = extract(Source::Heights(map), &ExtractParams::default(), &mut |_| {}).unwrap();
        let top = pyr.top();
        let ndf = Ndf::PhongPeaks(PhongPeaks::new(top.lobes.iter().collect()).unwrap());
        let hz = top.texel_horizon(0, 0).unwrap().unwrap();
        // The horizon model of a texel, as `meso brdf` gets it from a map (`[shadowing] kind =
        // "horizon"`).
        let hv = HorizonVisibility(hz);
        let horizon = |i: glam::DVec3, o: glam::DVec3| hv.g(i, o);
        let models = [
            Visibility::Smith,
            Visibility::Custom(&horizon),
            Visibility::None,
        ];
        let gonio = Gonio::new(map).unwrap();
        let mut row = format!("| {name} |");
        for set in [&low[..], &grazing[..]] {
            let mut worst = [0.0f64; 3];
            for &(ti, pi, to, po) in set {
                let (i, o) = (dir(ti, pi), dir(to, po));
                let g = gonio.measure(&facet, i, o, &gp)[0];
                for (w, m) in worst.iter_mut().zip(&models) {
                    let v = effective_brdf_with(
                        &ndf,
                        &facet,
                        Form::Microfacet,
                        *m,
                        i,
                        o,
                        Accuracy::default(),
                    )[0];
                    *w = w.max((v - g).abs() / g.max(1e-12));
                }
            }
            for w in worst {
                row += &format!(" {:.1} % |", 100.0 * w);
            }
        }
        println!("{row}");
    }
}
