//! The scene TOML parser never panics; materials resolve to a Lambert shader.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::sync::Arc;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let resolver = |_: &std::path::Path| -> Result<Arc<dyn meso_render::Shader>, meso_render::ResolveError> {
            Ok(Arc::new(meso_render::Lambert { albedo: [0.5; 3] }))
        };
        let _ = meso_render::Scene::from_toml_str(text, std::path::Path::new("."), &resolver);
    }
});
