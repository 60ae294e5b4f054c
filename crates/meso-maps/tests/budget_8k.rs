//! An 8192² height map is accepted by `meso extract` under the default memory budget (4 GiB):
//! the streamed extraction's estimate (`check_budget_streamed`: the larger of the image's load
//! and the heights + `extract_stream_bytes`, with the horizon angles in 16 bits) is checked on
//! the header of a 16-bit grey PNG of that size, built byte by byte (`meso_testkit::png`; only
//! its header is read). One test per binary: the budget is process-wide.

use meso_maps::input::check_budget_streamed;
use meso_maps::{Border, ExtractParams, InputKind};

#[test]
fn an_8k_height_map_fits_the_default_budget() {
    let dir = std::env::temp_dir().join(format!("meso-maps-8k-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let kind = InputKind::Heights {
        texel_size: 1.0,
        height_scale: 1.0,
        border: Border::Wrap,
    };
    let params = ExtractParams::default();
    let path = dir.join("h8k.png");
    std::fs::write(&path, meso_testkit::png::header_only(8192, 8192, 16, 0)).unwrap();
    meso_core::budget::set_budget(meso_core::budget::DEFAULT_BUDGET_BYTES);
    check_budget_streamed(&path, kind, &params).expect("8192² within the default 4 GiB");
    // The estimate is ≈ 3.97 GB (docs/limits.md): 3.5 GiB refuses it, naming the file.
    meso_core::budget::set_budget(3584 << 20);
    let e = check_budget_streamed(&path, kind, &params)
        .unwrap_err()
        .to_string();
    assert!(e.contains("h8k.png") && e.contains("memory"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
