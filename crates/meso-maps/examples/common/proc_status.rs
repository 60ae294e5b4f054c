//! The memory of this process as Linux reports it in `/proc/self/status`, for the examples that
//! measure an extraction's memory (`extract_mem`, `extract_phases`), which include this file by
//! `#[path]`.

/// `VmHWM` and `VmRSS` of this process in MB (Linux), or zeros.
pub fn mem() -> (f64, f64) {
    let text = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        text.lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map_or(0.0, |kb| kb / 1024.0)
    };
    (field("VmHWM:"), field("VmRSS:"))
}
