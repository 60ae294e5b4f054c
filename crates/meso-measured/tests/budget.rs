//! Issue #12 item 3: reading a MERL table is checked against the memory budget before its
//! buffers are allocated. (A test file of its own: the budget is process-wide.)

use meso_measured::merl::{MerlError, MerlTable, MERL_FILE_BYTES, MERL_READ_BYTES};

#[test]
fn item3_merl_read_above_the_memory_budget_is_refused() {
    let dir = std::env::temp_dir().join(format!("meso-merl-budget-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("zero.binary");
    let mut bytes = Vec::with_capacity(MERL_FILE_BYTES as usize);
    for dim in [90i32, 90, 180] {
        bytes.extend_from_slice(&dim.to_le_bytes());
    }
    bytes.resize(MERL_FILE_BYTES as usize, 0);
    std::fs::write(&path, &bytes).unwrap();
    drop(bytes);
    meso_core::budget::set_budget(MERL_READ_BYTES - 1);
    let e = MerlTable::read(&path).unwrap_err();
    assert!(matches!(e, MerlError::Budget(_)), "{e:?}");
    let msg = e.to_string();
    assert!(
        msg.contains("zero.binary: reading the MERL table needs about 66.7 MiB"),
        "{msg}"
    );
    meso_core::budget::set_budget(MERL_READ_BYTES);
    let t = MerlTable::read(&path).unwrap();
    assert_eq!(t.missing_count(), 0);
    assert_eq!(t.value(2, 89, 89, 179), 0.0);
    meso_core::budget::set_budget(0);
    std::fs::remove_dir_all(&dir).unwrap();
}
