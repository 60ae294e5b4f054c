//! Throughput of the core inner loops: Phong-peak evaluation (Eq. 12), the Eq. 2 quadrature per
//! BRDF value, and the closed-form approximation. Figures go to docs/benchmarks.md.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::DVec3;
use meso_core::convolution::{effective_brdf, phong_closed_form, Accuracy, Form};
use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;
use meso_core::ndf::{Ndf, PhongLobe, PhongPeaks};
use std::hint::black_box;

fn seven_lobes() -> PhongPeaks {
    PhongPeaks::new(
        (0..7)
            .map(|k| {
                PhongLobe::new(
                    spherical_direction_deg(10.0 * k as f64, 51.0 * k as f64),
                    1.0,
                    20.0 + 30.0 * k as f64,
                )
            })
            .collect(),
    )
    .unwrap()
}

fn bench(c: &mut Criterion) {
    let dirs: Vec<DVec3> = (0..4096)
        .map(|k| spherical_direction_deg((k % 90) as f64, (k * 7 % 360) as f64))
        .collect();
    let p = seven_lobes();
    let mut g = c.benchmark_group("lobes");
    g.throughput(Throughput::Elements((dirs.len() * 7) as u64));
    g.bench_function("phong_peaks_eval_7_lobes", |b| {
        b.iter(|| dirs.iter().map(|&d| p.eval(black_box(d))).sum::<f64>())
    });
    g.finish();

    let m = Material::from_toml_str(
        r#"
[ndf]
kind = "phong-peaks"
lobes = [
  { axis = [0.0, 0.0],  weight = 0.6, exponent = 40.0 },
  { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },
]
[transfer]
kind = "phong"
exponent = 50.0
specular = [1.0, 0.8, 0.6]
"#,
    )
    .unwrap();
    let (i, o) = (
        spherical_direction_deg(45.0, 90.0),
        spherical_direction_deg(20.0, 250.0),
    );
    let mut g = c.benchmark_group("eq2");
    g.throughput(Throughput::Elements(1));
    for (name, acc) in [
        ("fast", Accuracy::fast()),
        ("default", Accuracy::default()),
        ("fine", Accuracy::fine()),
    ] {
        g.bench_function(format!("quadrature_{name}"), |b| {
            b.iter(|| {
                effective_brdf(
                    &m.ndf,
                    &m.transfer,
                    Form::MultipleSurface,
                    black_box(i),
                    o,
                    acc,
                )
            })
        });
    }
    let Ndf::PhongPeaks(pp) = &m.ndf else {
        unreachable!()
    };
    g.bench_function("closed_form", |b| {
        b.iter(|| phong_closed_form(pp.lobes(), 50.0, [1.0, 0.8, 0.6], black_box(i), o))
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = bench
}
criterion_main!(benches);
