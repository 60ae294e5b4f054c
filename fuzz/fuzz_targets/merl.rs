//! The MERL reader never panics. Two paths: the raw input as a whole file (header and size
//! checks), and the input patched into a valid full-size table at an offset it chooses (value
//! decoding: NaN/inf must be errors naming a cell inside the table, negative values "missing").
#![no_main]
use libfuzzer_sys::fuzz_target;
use meso_measured::merl::{MerlError, MerlTable, MERL_FILE_BYTES, N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H};
use std::sync::Mutex;

static FULL: Mutex<Vec<u8>> = Mutex::new(Vec::new());

fuzz_target!(|data: &[u8]| {
    let _ = MerlTable::from_bytes(data);
    let _ = MerlTable::has_header(data);
    if data.len() < 4 {
        return;
    }
    let mut full = FULL.lock().unwrap_or_else(|e| e.into_inner());
    if full.is_empty() {
        full.resize(MERL_FILE_BYTES as usize, 0);
        for (k, d) in [N_THETA_H, N_THETA_D, N_PHI_D].iter().enumerate() {
            full[4 * k..4 * k + 4].copy_from_slice(&(*d as i32).to_le_bytes());
        }
    }
    let patch = &data[4..];
    let span = full.len() - 12 - patch.len().min(full.len() - 12);
    let off = 12 + (u32::from_le_bytes([data[0], data[1], data[2], data[3]]) as usize % (span + 1));
    let end = (off + patch.len()).min(full.len());
    let saved = full[off..end].to_vec();
    full[off..end].copy_from_slice(&patch[..end - off]);
    match MerlTable::from_bytes(&full) {
        Ok(t) => {
            // Patched values are either scaled finite values or "missing" (< 0).
            let first = (off - 12) / 8;
            let cell = first % N_CELLS;
            let (ih, id, ip) = (cell / (N_THETA_D * N_PHI_D), (cell / N_PHI_D) % N_THETA_D, cell % N_PHI_D);
            assert!(t.value(first / N_CELLS, ih, id, ip).is_finite());
        }
        Err(MerlError::NonFinite { ih, id, ip, channel, .. }) => {
            assert!(ih < N_THETA_H && id < N_THETA_D && ip < N_PHI_D && channel < 3);
        }
        Err(e) => panic!("unexpected error on a full-size table: {e}"),
    }
    full[off..end].copy_from_slice(&saved);
});
