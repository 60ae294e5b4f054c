//! The pyramid (map) file reader never panics on any bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = meso_maps::Pyramid::from_bytes(std::path::Path::new("fuzz.map"), data);
});
