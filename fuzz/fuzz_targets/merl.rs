//! The MERL reader never panics. Two paths: the raw input as a whole file (header and size
//! checks, format detection), and the input as a run of stored values at a flat index it chooses
//! (value decoding: NaN/inf are errors naming a cell inside the table, the rest are finite, scaled,
//! negative ones "missing" = −1).
#![no_main]
use libfuzzer_sys::fuzz_target;
use meso_measured::merl::{
    decode_values, MerlError, MerlTable, MERL_SCALES, N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H,
};

fuzz_target!(|data: &[u8]| {
    let _ = MerlTable::from_bytes(data);
    let _ = MerlTable::has_header(data);
    if data.len() < 4 {
        return;
    }
    let first = u32::from_le_bytes([data[0], data[1], data[2], data[3]]) as usize;
    let body = &data[4..];
    let mut out = Vec::new();
    match decode_values(body, first, &mut out) {
        Ok(()) => {
            assert_eq!(out.len(), body.len() / 8);
            for (j, v) in out.iter().enumerate() {
                let raw = f64::from_le_bytes(body[8 * j..8 * j + 8].try_into().unwrap());
                if raw < 0.0 {
                    assert_eq!(*v, -1.0);
                } else {
                    let c = (first + j) / N_CELLS;
                    assert!(v.is_finite() && *v >= 0.0);
                    assert_eq!(*v, raw * MERL_SCALES[c]);
                }
            }
        }
        Err(MerlError::NonFinite {
            ih,
            id,
            ip,
            channel,
            value,
            ..
        }) => {
            assert!(ih < N_THETA_H && id < N_THETA_D && ip < N_PHI_D && channel < 3);
            assert!(!value.is_finite());
        }
        Err(MerlError::BadSize { .. }) => assert!(first + body.len() / 8 > 3 * N_CELLS),
        Err(e) => panic!("unexpected error: {e}"),
    }
});
