//! OBJ mesh loading (`meso_render::Mesh::from_obj`, through a file as scenes load it) never
//! panics, never opens `mtllib` files, and never allocates beyond the memory budget (run with
//! `MESO_MEMORY_BUDGET` and libFuzzer's `-malloc_limit_mb`, docs/limits.md).
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("meso-fuzz-{}.obj", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let p = scratch();
    if std::fs::write(p, data).is_ok() {
        let _ = meso_render::Mesh::from_obj(p);
    }
});
