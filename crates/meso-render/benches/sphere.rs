//! The speed target: a 1024×1024 sphere with a 7-lobe multiple surface (flat-array
//! Phong shader) under 4 point lights at 1 sample per pixel; and the editor's 384×384 preview.
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
}

criterion_group!(benches, bench);
criterion_main!(benches);
