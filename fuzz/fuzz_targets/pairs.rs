//! The pairs CSV parser never panics, and what it accepts are unit directions above the surface.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(pairs) = meso_core::pairs::parse_pairs(text) {
            for p in pairs {
                assert!((p.i.length() - 1.0).abs() < 1e-9 && p.i.z >= -1e-12);
                assert!((p.o.length() - 1.0).abs() < 1e-9 && p.o.z >= -1e-12);
            }
        }
    }
});
