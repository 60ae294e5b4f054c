use meso_maps::*;
use std::time::Instant;
fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(256);
    let map = fixtures::gaussian(n, 4.0, 0.1, 3, 0.01).unwrap();
    let t = Instant::now();
    let mut last = Instant::now();
    let pyr = extract(Source::Heights(&map), &ExtractParams::default(), &mut |p| {
        eprintln!(
            "level {}/{} {:.3}s",
            p.levels_done,
            p.levels,
            last.elapsed().as_secs_f64()
        );
        last = Instant::now();
    })
    .unwrap();
    println!("{:.2} s\n{}", t.elapsed().as_secs_f64(), pyr.info());
}
