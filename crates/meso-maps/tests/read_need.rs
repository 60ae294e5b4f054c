//! `Pyramid::read_compact_bytes`: what reading a map file compactly will need, from its headers
//! alone, is exactly the memory `Pyramid::read_compact` checks against the budget (refused one
//! byte under it, read at it); a file whose chunks cannot be walked gets 4 × its size. One test
//! in this binary: it sets the process's memory budget.

use meso_maps::{extract, fixtures, ExtractParams, Pyramid, Source};
use std::path::Path;

#[test]
fn the_need_from_the_headers_is_what_reading_checks() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("read_need");
    std::fs::create_dir_all(&dir).unwrap();
    let map = fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap();
    let mut params = ExtractParams::default();
    params = params.with_max_lobes(3);
    let p = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();
    let path = dir.join("g256.map");
    p.write(&path).unwrap();

    let need = Pyramid::read_compact_bytes(&path).unwrap();
    assert_eq!(need.max_lobes, 3);
    let size = std::fs::metadata(&path).unwrap().len();
    // The coded pyramid and one band: more than the (deflated) file.
    assert!(
        need.bytes > size,
        "need {} B for a file of {size} B",
        need.bytes
    );
    meso_core::budget::set_budget(need.bytes - 1);
    let refused = Pyramid::read_compact(&path);
    meso_core::budget::set_budget(need.bytes);
    let read = Pyramid::read_compact(&path);
    meso_core::budget::set_budget(0);
    let e = refused
        .expect_err("read one byte under its need")
        .to_string();
    assert!(e.contains("g256.map") && e.contains("budget"), "{e}");
    assert_eq!(
        read.unwrap().info().to_string(),
        Pyramid::read(&path).unwrap().info().to_string()
    );

    // A map file cut in its levels: 4 × its size, the header's lobe count; reading it says why.
    let cut = dir.join("cut.map");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() / 3]).unwrap();
    let need = Pyramid::read_compact_bytes(&cut).unwrap();
    let cut_size = (bytes.len() / 3) as u64;
    assert_eq!(need.bytes, meso_maps::format::read_bytes(cut_size));
    assert_eq!(need.max_lobes, 3);
    let e = Pyramid::read_compact(&cut)
        .expect_err("a cut file")
        .to_string();
    assert!(e.contains("cut.map") && e.contains("truncated"), "{e}");
    // Cut within its header: the largest lobe count.
    std::fs::write(&cut, &bytes[..30]).unwrap();
    let need = Pyramid::read_compact_bytes(&cut).unwrap();
    assert_eq!(need.bytes, meso_maps::format::read_bytes(30));
    assert_eq!(need.max_lobes, meso_maps::fit::MAX_LOBES);
    // A file that is not there is an error naming it.
    let e = Pyramid::read_compact_bytes(&dir.join("missing.map"))
        .expect_err("no file")
        .to_string();
    assert!(e.contains("missing.map"), "{e}");
}
