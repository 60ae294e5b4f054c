//! The speed target: a 1024×1024 sphere with a 7-lobe multiple surface (flat-array
//! Phong shader) under 4 point lights at 1 sample per pixel (stream and per-hit paths); the
//! editor's 384×384 preview; and the stream path's lobe kernel alone.
//!
//! `cargo bench -p meso-render --bench sphere -- --warm-up-time 1 --measurement-time 3`

use criterion::{criterion_group, criterion_main, Criterion};
use meso_render::*;
use std::hint::black_box;

mod common;
use common::scene;

fn bench(c: &mut Criterion) {
    let opts = RenderOptions::default();
    let s = scene(1024);
    c.bench_function("sphere_1024_7lobes_4points_1spp", |bch| {
        bch.iter(|| black_box(render(black_box(&s), &opts, None)))
    });
    let p = scene(384);
    c.bench_function("preview_384_7lobes_4points_1spp", |bch| {
        bch.iter(|| black_box(render(black_box(&p), &opts, None)))
    });
    let ph = RenderOptions {
        per_hit: true,
        ..RenderOptions::default()
    };
    c.bench_function("sphere_1024_7lobes_4points_1spp_per_hit", |bch| {
        bch.iter(|| black_box(render(black_box(&s), &ph, None)))
    });
    // The stream path's lobe kernel alone: 7 Phong lobes × 4096 direction pairs per call
    // (28 672 lobe evaluations), one thread.
    let n = 4096;
    let dirs: Vec<[f32; 6]> = (0..n)
        .map(|k| {
            let a = 0.013 * k as f32;
            let (i, o) = ([a.cos(), a.sin(), 2.0], [0.3 * a.sin(), -0.2, 1.5]);
            let (li, lo) = (
                (i[0] * i[0] + i[1] * i[1] + i[2] * i[2]).sqrt(),
                (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt(),
            );
            [
                i[0] / li,
                i[1] / li,
                i[2] / li,
                o[0] / lo,
                o[1] / lo,
                o[2] / lo,
            ]
        })
        .collect();
    let col = |c: usize| -> Vec<f32> { dirs.iter().map(|d| d[c]).collect() };
    let (wi, wo) = ([col(0), col(1), col(2)], [col(3), col(4), col(5)]);
    let l = common::seven_lobes();
    let mut out = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    c.bench_function("lobe_pairs_7_lobes_4096_pairs", |bch| {
        bch.iter(|| {
            let [o0, o1, o2] = &mut out;
            l.eval_pairs(
                [&wi[0], &wi[1], &wi[2]],
                [&wo[0], &wo[1], &wo[2]],
                [o0, o1, o2],
            );
            black_box(&out);
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
