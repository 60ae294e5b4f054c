//! Time to compile the plan ([`FastBrdf`], `Policy::Accurate`) of a mirror-facet material whose
//! NDF is a 2-D table (`[ndf] kind = "tabulated"`, 512 × 64 equal-area grid, what `meso fit
//! SAMPLES.csv --nonparametric` writes and rebuilds ≈ 16 times per fit): almost all of it is
//! the Smith Λ table of the projected area. Prints, per table, the median of `REPEATS` builds
//! (seconds), the BRDF at a few pairs (so that runs before and after a change can be compared),
//! and the time per pair of the exact path (`Material::brdf`, what `meso brdf --exact` runs).
//! Used for docs/benchmarks.md.
//!
//! cargo run --release -p meso-core --example tabulated_plan [-- REPEATS]

use glam::{DQuat, DVec3};
use meso_core::convolution::Form;
use meso_core::frame::spherical_direction_deg;
use meso_core::grid::EqualAreaGrid;
use meso_core::material::{Material, ShadowingKind};
use meso_core::ndf::{Distribution, Microfacet, Ndf, Tabulated};
use meso_core::shading::{FastBrdf, Policy};
use meso_core::transfer::{Fresnel, Transfer};
use std::time::Instant;

fn main() {
    let repeats: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(3);
    let grid = EqualAreaGrid::new(512, 64);
    let cases = [
        (
            "GGX α (0.2, 0.4) turned 30°",
            Distribution::Ggx,
            0.2,
            0.4,
            30.0,
        ),
        (
            "Beckmann α (0.35, 0.2) turned −60°",
            Distribution::Beckmann,
            0.35,
            0.2,
            -60.0,
        ),
    ];
    let pairs = [
        ((0.0, 0.0), (0.0, 0.0)),
        ((30.0, 10.0), (45.0, 200.0)),
        ((60.0, 100.0), (20.0, 300.0)),
        ((80.0, 45.0), (85.0, 225.0)),
        ((89.0, 0.0), (70.0, 180.0)),
    ];
    for (name, d, ax, ay, rot) in cases {
        let mf = Microfacet::new(d, ax, ay).unwrap();
        let q = DQuat::from_rotation_z(f64::to_radians(rot)).inverse();
        let table = Tabulated::from_fn(grid, 4, |m| mf.d(q * m)).unwrap();
        let material = Material {
            form: Form::Microfacet,
            shadowing: ShadowingKind::Smith,
            diffuse: [0.05, 0.1, 0.2],
            ..Material::new(
                Ndf::Tabulated(table),
                Transfer::Mirror {
                    fresnel: Fresnel::Schlick {
                        f0: [0.9, 0.6, 0.3],
                    },
                    specular: [0.8; 3],
                },
            )
        };
        let mut times = Vec::new();
        let mut plan = None;
        for _ in 0..repeats.max(1) {
            let t0 = Instant::now();
            let p = FastBrdf::with_policy(&material, Policy::Accurate);
            times.push(t0.elapsed().as_secs_f64());
            plan = Some(p);
        }
        times.sort_by(f64::total_cmp);
        let plan = plan.unwrap();
        println!(
            "{name}: plan build {:.3} s (median of {}; min {:.3}, max {:.3})",
            times[times.len() / 2],
            times.len(),
            times[0],
            times[times.len() - 1]
        );
        for ((ti, pi), (to, po)) in pairs {
            let (i, o): (DVec3, DVec3) = (
                spherical_direction_deg(ti, pi),
                spherical_direction_deg(to, po),
            );
            let f = plan.eval(i, o);
            println!(
                "  f({ti}°,{pi}° ; {to}°,{po}°) = {:.9e} {:.9e} {:.9e}",
                f[0], f[1], f[2]
            );
        }
        let t0 = Instant::now();
        let mut sum = 0.0;
        for _ in 0..repeats.max(1) {
            for ((ti, pi), (to, po)) in pairs {
                let f = material.brdf(
                    spherical_direction_deg(ti, pi),
                    spherical_direction_deg(to, po),
                );
                sum += f[0];
            }
        }
        println!(
            "  exact path: {:.3} ms per pair (Σ f_r {sum:.9e})",
            1e3 * t0.elapsed().as_secs_f64() / (repeats.max(1) * pairs.len()) as f64
        );
    }
}
