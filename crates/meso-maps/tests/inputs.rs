//! Image inputs as texture libraries ship them (issue #15 item 2 and its acceptance): TGA height
//! and normal maps read as the same pixels in PNG do, the warnings for a colour image or a
//! normal map given as a height map, and corrupt JPEGs refused with an error naming the file.
//! The images are encoded here by the `image` crate's own encoders (no data files).

use meso_maps::heightmap::{Border, HeightMap, NormalConvention, NormalMap};
use meso_maps::MapError;
use std::io::Cursor;
use std::path::Path;

/// `img` encoded in `format`.
fn encode(img: &image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, format).unwrap();
    out.into_inner()
}

/// A grey 8-bit height field with no symmetry (a ramp along x plus a ripple along y).
fn grey(n: u32) -> image::DynamicImage {
    image::DynamicImage::ImageLuma8(image::GrayImage::from_fn(n, n, |c, r| {
        let v = 40.0 + 8.0 * f64::from(c) + 30.0 * (f64::from(r) * 0.7).sin();
        image::Luma([v.round().clamp(0.0, 255.0) as u8])
    }))
}

/// An 8-bit OpenGL normal map with tilts varying over the image.
fn normals(n: u32) -> image::DynamicImage {
    image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(n, n, |c, r| {
        let (x, y) = (
            0.4 * (f64::from(c) * 0.5).sin(),
            0.3 * (f64::from(r) * 0.4).cos(),
        );
        let z = (1.0 - x * x - y * y).sqrt();
        let code = |v: f64| ((v * 0.5 + 0.5) * 255.0).round() as u8;
        image::Rgb([code(x), code(y), code(z)])
    }))
}

#[test]
fn tga_height_and_normal_maps_read_as_the_same_pixels_in_png() {
    let h = grey(16);
    let (png, tga) = (
        encode(&h, image::ImageFormat::Png),
        encode(&h, image::ImageFormat::Tga),
    );
    assert_ne!(png, tga);
    let load = |name: &str, bytes: &[u8]| {
        HeightMap::from_bytes(Path::new(name), bytes, 0.5, 2.0, Border::Wrap).unwrap()
    };
    let (a, b) = (load("h.png", &png), load("h.tga", &tga));
    assert_eq!(a.heights(), b.heights());
    // The ramp survives (x along columns): not all heights equal.
    assert!(a.heights().iter().any(|&v| v != a.heights()[0]));

    let n = normals(16);
    let (png, tga) = (
        encode(&n, image::ImageFormat::Png),
        encode(&n, image::ImageFormat::Tga),
    );
    let load = |name: &str, bytes: &[u8]| {
        NormalMap::from_bytes(Path::new(name), bytes, NormalConvention::Gl).unwrap()
    };
    let (a, b) = (load("n.png", &png), load("n.tga", &tga));
    assert_eq!(a.normals(), b.normals());
    assert!(a.normals().iter().all(|m| (m.length() - 1.0).abs() < 1e-9));
}

#[test]
fn colour_images_and_normal_maps_given_as_height_maps_are_warned_about() {
    let load = |img: &image::DynamicImage| {
        HeightMap::from_bytes(
            Path::new("given.png"),
            &encode(img, image::ImageFormat::Png),
            1.0,
            1.0,
            Border::Wrap,
        )
        .unwrap()
    };
    // A grey image: no warning (an 8-bit ramp without terraces).
    let plain = load(&grey(16));
    assert!(
        plain.warnings().iter().all(|w| !w.contains("colour")),
        "{:?}",
        plain.warnings()
    );
    // The same grey values stored as RGB (and as a float image, R = G = B): not colour.
    for rgb in [grey(16).into_rgb8().into(), grey(16).into_rgb32f().into()] {
        let rgb: image::DynamicImage = rgb;
        let fmt = if matches!(rgb, image::DynamicImage::ImageRgb32F(_)) {
            image::ImageFormat::OpenExr
        } else {
            image::ImageFormat::Png
        };
        let name = if fmt == image::ImageFormat::Png {
            "grey-rgb.png"
        } else {
            "grey-rgb.exr"
        };
        let m = HeightMap::from_bytes(Path::new(name), &encode(&rgb, fmt), 1.0, 1.0, Border::Wrap)
            .unwrap();
        assert!(
            m.warnings().iter().all(|w| !w.contains("colour")),
            "{name}: {:?}",
            m.warnings()
        );
    }
    // A colour float image: its first channel is used, and said so.
    let colour_f = image::DynamicImage::ImageRgb32F(image::Rgb32FImage::from_fn(16, 16, |c, r| {
        image::Rgb([c as f32 / 16.0, r as f32 / 16.0, 0.5])
    }));
    let m = HeightMap::from_bytes(
        Path::new("colour.exr"),
        &encode(&colour_f, image::ImageFormat::OpenExr),
        1.0,
        1.0,
        Border::Wrap,
    )
    .unwrap();
    let w = m.warnings().join("\n");
    assert!(w.contains("first (red) channel"), "{w}");
    // A colour photograph-like image: converted to luminance, and said so.
    let colour = image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(16, 16, |c, r| {
        image::Rgb([(c * 15) as u8, (r * 15) as u8, 40])
    }));
    let w = load(&colour).warnings().join("\n");
    assert!(w.contains("colour image used as a height map"), "{w}");
    // A tangent-space normal map (mean colour near (0.5, 0.5, 1)): told to give it as one.
    let w = load(&normals(16)).warnings().join("\n");
    assert!(
        w.contains("looks like a tangent-space normal map") && w.contains("normal map instead"),
        "{w}"
    );
}

#[test]
fn corrupt_jpegs_are_refused_naming_the_file() {
    let img = image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(32, 32, |c, r| {
        image::Rgb([(c * 8) as u8, (r * 8) as u8, 200])
    }));
    let jpeg = encode(&img, image::ImageFormat::Jpeg);
    assert!(NormalMap::from_bytes(Path::new("ok.jpg"), &jpeg, NormalConvention::Gl).is_ok());
    // Cut inside the header (before the frame is described), and garbage after the JPEG
    // signature: both are decode errors that name the file.
    // Where the (last) scan starts: a cut half way through its entropy-coded data, which the
    // decoder alone would fill with grey and accept.
    let sos = jpeg.windows(2).rposition(|w| w == [0xFF, 0xDA]).unwrap();
    let half = sos + (jpeg.len() - sos) / 2;
    let cases: [(&str, Vec<u8>); 3] = [
        ("cut.jpg", jpeg[..20].to_vec()),
        ("cut-in-data.jpg", jpeg[..half].to_vec()),
        ("garbage.jpg", {
            let mut b = jpeg[..4].to_vec();
            b.extend(std::iter::repeat_n(0x5Au8, 200));
            b
        }),
    ];
    for (name, bytes) in &cases {
        let e = HeightMap::from_bytes(Path::new(name), bytes, 1.0, 1.0, Border::Wrap).unwrap_err();
        assert!(matches!(e, MapError::Decode { .. }), "{name}: {e}");
        assert!(e.to_string().contains(name), "{name}: {e}");
        // One line, no trailing blank (the JPEG decoder's own messages end in newlines).
        assert_eq!(e.to_string().trim_end(), e.to_string(), "{name}: {e:?}");
        assert!(!e.to_string().contains('\n'), "{name}: {e:?}");
        if name.starts_with("cut") {
            assert!(e.to_string().contains("truncated"), "{name}: {e}");
        }
        let e = NormalMap::from_bytes(Path::new(name), bytes, NormalConvention::Gl).unwrap_err();
        assert!(matches!(e, MapError::Decode { .. }), "{name}: {e}");
        assert!(e.to_string().contains(name), "{name}: {e}");
    }
}

/// A height map that does not tile (a smooth ramp with a ripple: its left and right edges far
/// apart) is warned about when read with the wrapped border, the default, whose seam would be a
/// cliff; not with the clamped one, nor when it tiles (the same ripple, periodic).
#[test]
fn maps_that_do_not_tile_are_warned_about_under_wrap() {
    let n = 64u32;
    let ramp = image::DynamicImage::ImageLuma16(image::ImageBuffer::from_fn(n, n, |c, r| {
        let v = 8000.0 + 700.0 * f64::from(c) + 2000.0 * (f64::from(r) * 0.3).sin();
        image::Luma([v.round() as u16])
    }));
    let tiles = image::DynamicImage::ImageLuma16(image::ImageBuffer::from_fn(n, n, |c, r| {
        let t = std::f64::consts::TAU / f64::from(n);
        let v =
            30000.0 + 9000.0 * (t * f64::from(c)).sin() + 6000.0 * (2.0 * t * f64::from(r)).cos();
        image::Luma([v.round() as u16])
    }));
    let (ramp, tiles) = (
        encode(&ramp, image::ImageFormat::Png),
        encode(&tiles, image::ImageFormat::Png),
    );
    let warned = |bytes: &[u8], border: Border| {
        let m = HeightMap::from_bytes(Path::new("h.png"), bytes, 1.0, 10.0, border).unwrap();
        m.warnings()
            .iter()
            .find(|w| w.contains("does not tile"))
            .cloned()
    };
    let w = warned(&ramp, Border::Wrap).expect("the ramp is warned about");
    assert!(
        w.contains("left and right edges")
            && !w.contains("top and bottom")
            && w.contains("--clamp"),
        "{w}"
    );
    let m = HeightMap::from_bytes(Path::new("h.png"), &ramp, 1.0, 10.0, Border::Wrap).unwrap();
    let (x, y) = m.seam_ratios();
    // The seam: 63 steps of 700 codes against one of 700 inside, x; the ripple wraps along y
    // within about a step.
    assert!(x > 50.0 && y < meso_maps::heightmap::SEAM_RATIO, "{x} {y}");
    assert!(warned(&ramp, Border::Clamp).is_none());
    assert!(warned(&tiles, Border::Wrap).is_none());
}
