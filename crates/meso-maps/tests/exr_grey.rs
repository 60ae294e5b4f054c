//! Float EXR height maps without all of R, G and B (one `Y`, `H`, `Z` or `R` channel; `R` and `G`)
//! (docs: "32-bit float EXR (first channel)"), which the `image` crate's decoder refuses ("image
//! does not contain non-deep rgb channels").

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, LayerAttributes, SmallVec, WritableImage,
};
use meso_maps::{Border, HeightMap};

/// A `w × h` EXR of one float channel named `name` holding `values` (row 0 at the top).
fn grey_exr(path: &std::path::Path, name: &str, w: usize, h: usize, values: Vec<f32>) {
    let mut list = SmallVec::new();
    list.push(AnyChannel::new(name, FlatSamples::F32(values)));
    let layer = exr::prelude::Layer::new(
        (w, h),
        LayerAttributes::named("heights"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

#[test]
fn one_channel_float_exr_height_maps_are_read() {
    let d = std::env::temp_dir().join(format!("meso-exr-grey-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let (w, h) = (6usize, 4usize);
    // Distinct heights: value (x + 10·y) / 100 at image row y (from the top), column x.
    let values: Vec<f32> = (0..w * h)
        .map(|k| ((k % w) as f32 + 10.0 * (k / w) as f32) / 100.0)
        .collect();
    for name in ["Y", "H", "Z", "R"] {
        let p = d.join(format!("h{name}.exr"));
        grey_exr(&p, name, w, h, values.clone());
        let header = meso_maps::probe(&p).unwrap();
        assert_eq!((header.width, header.height, header.color), (6, 4, false));
        let m = HeightMap::load(&p, 1.0, 2.0, Border::Wrap).unwrap();
        assert_eq!((m.width(), m.height()), (w, h));
        // The map's row 0 is the image's bottom row; heights are value × height_scale.
        for y in 0..h {
            for x in 0..w {
                let want = 2.0 * values[(h - 1 - y) * w + x] as f64;
                assert!(
                    (m.heights()[y * w + x] - want).abs() < 1e-6,
                    "{name} ({x},{y})"
                );
            }
        }
        // The same from bytes (the server and the Python package read those).
        let bytes = std::fs::read(&p).unwrap();
        let b = HeightMap::from_bytes(&p, &bytes, 1.0, 2.0, Border::Wrap).unwrap();
        assert_eq!(b.heights(), m.heights());
    }
    // Two channels without B: red is the height (not `G`, first by name).
    let p = d.join("hRG.exr");
    let mut list = SmallVec::new();
    list.push(AnyChannel::new("R", FlatSamples::F32(values.clone())));
    list.push(AnyChannel::new("G", FlatSamples::F32(vec![5.0; w * h])));
    let layer = exr::prelude::Layer::new(
        (w, h),
        LayerAttributes::named("heights"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer).write().to_file(&p).unwrap();
    let m = HeightMap::load(&p, 1.0, 2.0, Border::Wrap).unwrap();
    assert!((m.heights()[0] - 2.0 * values[(h - 1) * w] as f64).abs() < 1e-6);
    let _ = std::fs::remove_dir_all(&d);
}
