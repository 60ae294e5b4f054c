//! The sample CSV parser never panics, what it accepts obeys the documented ranges (θ in
//! [0, 90] degrees, finite non-negative RGB), and it formats and re-parses to the same samples.
#![no_main]
use libfuzzer_sys::fuzz_target;
use meso_measured::csv::{format_csv, parse_csv};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(samples) = parse_csv(text) {
        assert!(!samples.is_empty());
        for s in &samples {
            assert!((0.0..=90.0).contains(&s.theta_i) && (0.0..=90.0).contains(&s.theta_o));
            assert!(s.phi_i.is_finite() && s.phi_o.is_finite());
            assert!(s.rgb.iter().all(|v| v.is_finite() && *v >= 0.0));
            let (wi, wo) = (s.wi(), s.wo());
            assert!((wi.length() - 1.0).abs() < 1e-9 && wi.z >= -1e-12);
            assert!((wo.length() - 1.0).abs() < 1e-9 && wo.z >= -1e-12);
        }
        let back = parse_csv(&format_csv(&samples)).expect("formatted CSV parses");
        assert_eq!(back.len(), samples.len());
        for (a, b) in back.iter().zip(&samples) {
            assert_eq!(a, b);
        }
    }
});
