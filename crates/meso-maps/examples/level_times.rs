//! Time of each phase of an extraction (normals and horizons, then each level) next to its share
//! of the estimated work ([`meso_maps::extract_work`], the weights of the progress), to check the
//! weighting (issue #12, item 13).
//!
//! ```text
//! cargo run --release -p meso-maps --example level_times [N]
//! ```
use meso_maps::{extract, fixtures, ExtractParams, Source};
use std::time::Instant;

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(256);
    let map = fixtures::gaussian(n, 3.0, 0.15, 7, 0.1).unwrap();
    let mut last = Instant::now();
    let mut prev = 0u64;
    let t0 = Instant::now();
    println!("{n}x{n} Gaussian map; per call: time share vs work share");
    let mut rows = Vec::new();
    extract(Source::Heights(&map), &ExtractParams::default(), &mut |p| {
        let dt = last.elapsed().as_secs_f64();
        last = Instant::now();
        rows.push((
            p.levels_done,
            dt,
            (p.work_done - prev) as f64 / p.work_total as f64,
        ));
        prev = p.work_done;
    })
    .unwrap();
    let total = t0.elapsed().as_secs_f64();
    for (lv, dt, w) in rows {
        println!(
            "after level {lv:>2}: {dt:>8.3} s  time {:>5.1}%  work {:>5.1}%",
            100.0 * dt / total,
            100.0 * w
        );
    }
    println!("total {total:.2} s");
}
