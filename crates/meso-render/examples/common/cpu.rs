//! Process CPU time for the timing examples (`bench_sphere`, `bench_mapped`, `bench_facade`,
//! `bench_bvh`), which include this file by `#[path]`: CPU time stays meaningful on a loaded
//! machine.

/// User + system CPU seconds of this process (Linux `/proc/self/stat`, 100 ticks/s; 0 elsewhere).
pub fn cpu_seconds() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = s.rsplit_once(')').map_or("", |x| x.1);
    let f: Vec<&str> = after.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}
