//! Environment-map loading (`meso_render::EnvironmentMap::from_file`: PNG, EXR, … sniffed from
//! the bytes, through a file as scenes load it) never panics and never allocates beyond the
//! memory budget (run with `MESO_MEMORY_BUDGET` and libFuzzer's `-malloc_limit_mb`).
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("meso-fuzz-{}.env", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let p = scratch();
    if std::fs::write(p, data).is_ok() {
        let _ = meso_render::EnvironmentMap::from_file(p, 1.0, 0.0);
    }
});
