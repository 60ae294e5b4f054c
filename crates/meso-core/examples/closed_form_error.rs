//! Error of the vMF closed form (`phong_closed_form`) against the Eq. 2 quadrature, for one Phong
//! peak of exponent η_n tilted 20° and a Phong (N·H) transfer of exponent η_t, over 200 direction
//! pairs spread over the upper hemispheres. Prints median and 95th-percentile relative errors of the
//! pairs whose BRDF is above 1% of the largest value. Used for docs/benchmarks.md.
//!
//! cargo run --release -p meso-core --example closed_form_error

use meso_core::convolution::{effective_brdf, phong_closed_form, Accuracy, Form};
use meso_core::frame::spherical_direction_deg;
use meso_core::ndf::{Ndf, PhongLobe, PhongPeaks};
use meso_core::transfer::{PhongVariant, Transfer};

fn main() {
    println!("| η_n (NDF) | η_t (transfer) | median rel. error | 95th pct | max |");
    println!("|---|---|---|---|---|");
    let pairs: Vec<_> = (0..200)
        .map(|k| {
            let a = 85.0 * ((k * 37 % 200) as f64 + 0.5) / 200.0;
            let b = 360.0 * ((k * 61 % 200) as f64) / 200.0;
            let c = 85.0 * ((k * 89 % 200) as f64 + 0.5) / 200.0;
            let d = 360.0 * ((k * 13 % 200) as f64) / 200.0;
            (spherical_direction_deg(a, b), spherical_direction_deg(c, d))
        })
        .collect();
    for eta_n in [5.0, 20.0, 100.0, 1000.0] {
        for eta_t in [5.0, 50.0, 500.0] {
            let lobe = PhongLobe::new(spherical_direction_deg(20.0, 0.0), 1.0, eta_n);
            let ndf = Ndf::PhongPeaks(PhongPeaks::new(vec![lobe]).unwrap());
            let t = Transfer::Phong {
                exponent: eta_t,
                specular: [1.0; 3],
                variant: PhongVariant::Half,
            };
            let vals: Vec<(f64, f64)> = pairs
                .iter()
                .map(|&(i, o)| {
                    let q =
                        effective_brdf(&ndf, &t, Form::MultipleSurface, i, o, Accuracy::fine())[0];
                    let c = phong_closed_form(&[lobe], eta_t, [1.0; 3], i, o)[0];
                    (q, c)
                })
                .collect();
            let peak = vals.iter().map(|v| v.0).fold(0.0, f64::max);
            let mut errs: Vec<f64> = vals
                .iter()
                .filter(|v| v.0 > 0.01 * peak)
                .map(|v| (v.1 / v.0 - 1.0).abs())
                .collect();
            errs.sort_by(f64::total_cmp);
            let q = |p: f64| errs[((errs.len() - 1) as f64 * p) as usize];
            println!(
                "| {eta_n} | {eta_t} | {:.3} | {:.3} | {:.3} |",
                q(0.5),
                q(0.95),
                errs.last().copied().unwrap_or(0.0)
            );
        }
    }
}
