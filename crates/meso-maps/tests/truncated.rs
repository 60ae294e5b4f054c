//! Image files cut off in their pixel data say so ("truncated"), naming the file, instead of the
//! reader's "failed to fill whole buffer".

use meso_maps::{Border, HeightMap};

#[test]
fn truncated_tga_and_tiff_height_maps_say_truncated() {
    let d = std::env::temp_dir().join(format!("meso-truncated-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let img = image::GrayImage::from_fn(64, 64, |x, y| image::Luma([(x * 3 + y) as u8]));
    for ext in ["tga", "tiff"] {
        let whole = d.join(format!("whole.{ext}"));
        img.save(&whole).unwrap();
        HeightMap::load(&whole, 1.0, 1.0, Border::Wrap).unwrap();
        let bytes = std::fs::read(&whole).unwrap();
        let cut = d.join(format!("cut.{ext}"));
        // TIFF: the header and directory come first; keep them and half the strip.
        let keep = if ext == "tiff" {
            64 * 64 / 2
        } else {
            bytes.len() / 2
        };
        std::fs::write(&cut, &bytes[..keep.min(bytes.len() - 1)]).unwrap();
        let e = HeightMap::load(&cut, 1.0, 1.0, Border::Wrap)
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("cut.{ext}")), "{e}");
        assert!(e.contains("truncated"), "{ext}: {e}");
    }
    let _ = std::fs::remove_dir_all(&d);
}
