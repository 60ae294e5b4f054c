//! Any bytes given to the material parser give a material or an error, never a panic; a material
//! that parses evaluates to finite values.
#![no_main]
use libfuzzer_sys::fuzz_target;
use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(mut m) = Material::from_toml_str(text) {
            m.accuracy = meso_core::convolution::Accuracy { radial: 4, azimuth: 8 };
            let f = m.brdf(spherical_direction_deg(30.0, 10.0), spherical_direction_deg(40.0, 200.0));
            assert!(f.iter().all(|v| v.is_finite()), "non-finite BRDF {f:?}");
        }
    }
});
