//! Time of each phase of a 1024² extraction (K ≤ 4; the map of `extract_mem` and
//! `extract_bench`): the normals and horizons, then each level, wall seconds between the
//! progress calls (docs/benchmarks.md, "Extraction speed").
//!
//! ```text
//! cargo build --release -p meso-maps --example extract_phases
//! ./target/release/examples/extract_phases [N] [none|plain|all]
//! ```
//!
//! The second argument sets `FitParams::merge_levels` (default: its default, plain).
use meso_maps::fit::MergeLevels;
use meso_maps::{extract, fixtures, ExtractParams, Source};
use std::hash::{Hash, Hasher};
use std::time::Instant;

#[path = "common/proc_status.rs"]
mod proc_status;
use proc_status::mem;

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map_or(1024, |s| s.parse().expect("a side in samples"));
    let map = fixtures::gaussian(n, 4.0, 0.1, 3, 0.01).unwrap();
    let t0 = Instant::now();
    let mut last = Instant::now();
    let mut calls = 0usize;
    let mut params = ExtractParams::default();
    params.fit.merge_levels = match std::env::args().nth(2).as_deref() {
        None | Some("plain") => MergeLevels::Plain,
        Some("none") => MergeLevels::None,
        Some("all") => MergeLevels::All,
        Some(o) => panic!("{o}: none, plain or all"),
    };
    let pyr = extract(Source::Heights(&map), &params, &mut |p| {
        let dt = last.elapsed().as_secs_f64();
        last = Instant::now();
        let (peak, rss) = mem();
        match calls {
            0 => {}
            1 => println!(
                "normals and horizons: {dt:.3} s (peak {peak:.0} MB, resident {rss:.0} MB)"
            ),
            _ => println!(
                "level {:>2}: {dt:.3} s (peak {peak:.0} MB, resident {rss:.0} MB)",
                p.levels_done - 1
            ),
        }
        calls += 1;
    })
    .unwrap();
    println!("total: {:.3} s", t0.elapsed().as_secs_f64());
    // A checksum of every stored value (lobes, lobe starts, horizon statistics, residuals), to
    // tell whether a change of the code changed any result.
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for l in &pyr.levels {
        l.lobe_start.hash(&mut h);
        for i in 0..l.lobes.len() {
            let p = l.lobes.get(i);
            for v in [p.axis.x, p.axis.y, p.axis.z, p.weight, p.exponent] {
                v.to_bits().hash(&mut h);
            }
        }
        for t in 0..l.texels() {
            if let Some(hz) = &l.horizon {
                let s = hz.get(t);
                s.weight.to_bits().hash(&mut h);
                for d in 0..meso_maps::HORIZON_DIRECTIONS {
                    s.mean[d].to_bits().hash(&mut h);
                    s.var[d].to_bits().hash(&mut h);
                }
            }
        }
        let r = l.residual;
        for v in [
            r.mean,
            r.max,
            r.shading_mean.unwrap_or(-1.0),
            r.shading_max.unwrap_or(-1.0),
        ] {
            v.to_bits().hash(&mut h);
        }
        println!(
            "  level {:>2}: lobes {:>8}, residual {:.6}/{:.6}, shading {:.6}/{:.6}",
            l.span.trailing_zeros(),
            l.lobes.len(),
            r.mean,
            r.max,
            r.shading_mean.unwrap_or(-1.0),
            r.shading_max.unwrap_or(-1.0)
        );
    }
    println!("checksum of all results: {:016x}", h.finish());
}
