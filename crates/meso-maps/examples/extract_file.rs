//! `meso extract` of a height map with the in-memory layout chosen: the map file of a pyramid
//! kept entirely in `f64` (`ExtractParams::compact_texels = usize::MAX`) or with the default
//! `f32` levels, to compare with the files of earlier builds (docs/benchmarks.md, "Extraction
//! memory").
//!
//! ```text
//! cargo build --release -p meso-maps --example extract_file
//! ./target/release/examples/extract_file HEIGHTS.png TEXEL_SIZE HEIGHT_SCALE OUT.map [f64]
//! ```
use meso_maps::input::{load, InputKind};
use meso_maps::{extract, Border, ExtractParams};
use std::path::Path;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    assert!(
        a.len() >= 5,
        "usage: extract_file HEIGHTS TEXEL_SIZE HEIGHT_SCALE OUT.map [f64]"
    );
    let params = ExtractParams {
        compact_texels: if a.get(5).is_some_and(|s| s == "f64") {
            usize::MAX
        } else {
            ExtractParams::default().compact_texels
        },
        ..ExtractParams::default()
    };
    let kind = InputKind::Heights {
        texel_size: a[2].parse().expect("texel size"),
        height_scale: a[3].parse().expect("height scale"),
        border: Border::Wrap,
    };
    let (input, _) = load(Path::new(&a[1]), kind, &params).unwrap();
    let pyr = extract(input.source(), &params, &mut |_| {}).unwrap();
    pyr.write(Path::new(&a[4])).unwrap();
}
