//! Integration tests of meso-maps against independent truth.

use glam::DVec3;
use meso_core::convolution::{effective_brdf_with, Accuracy, Form, SmithMasking, Visibility};
use meso_core::frame::spherical_direction_deg as dir;
use meso_core::ndf::{Ndf, PhongLobe, PhongPeaks};
use meso_core::transfer::{PhongVariant, Transfer};
use meso_maps::limits::ETA_MAX;
use meso_maps::*;

fn pyr(map: &HeightMap, k: usize) -> Pyramid {
    let mut p = ExtractParams::default();
    p = p.with_max_lobes(k);
    extract(Source::Heights(map), &p, &mut |_| {}).unwrap()
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-12)
}

const LAMBERT: Transfer = Transfer::Lambert { albedo: [1.0; 3] };

/// Eq. 10 as written, the half-vector form: `specular · max(0, N·H)^η`.
fn phong(exponent: f64, specular: [f64; 3]) -> Transfer {
    Transfer::Phong {
        exponent,
        specular,
        variant: PhongVariant::Half,
    }
}

/// Fitted lobes as the core NDF.
fn lobes_ndf(lobes: &[PhongLobe]) -> Ndf {
    Ndf::PhongPeaks(PhongPeaks::new(lobes.to_vec()).unwrap())
}

/// Every triangle of a map as a delta (the brute-force reference).
fn facets_ndf(map: &HeightMap) -> Ndf {
    FacetNormals::from_heightmap(map, NormalMode::Triangles)
        .to_deltas()
        .unwrap()
}

/// The core's microfacet form (`meso brdf`, the renderer) at its default accuracy.
fn microfacet(ndf: &Ndf, t: &Transfer, vis: Visibility<'_>, i: DVec3, o: DVec3) -> [f64; 3] {
    effective_brdf_with(ndf, t, Form::Microfacet, vis, i, o, Accuracy::default())
}

mod inputs {
    use super::*;
    use std::path::Path;

    fn png16(w: u32, h: u32, f: impl Fn(u32, u32) -> u16) -> Vec<u8> {
        let img =
            image::ImageBuffer::<image::Luma<u16>, _>::from_fn(w, h, |x, y| image::Luma([f(x, y)]));
        let mut v = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png)
            .unwrap();
        v
    }

    #[test]
    fn png16_and_8_scale() {
        let b = png16(4, 3, |x, y| (x * 1000 + y * 7) as u16);
        let m = HeightMap::from_bytes(Path::new("a.png"), &b, 0.5, 2.0, Border::Wrap).unwrap();
        assert_eq!((m.width(), m.height()), (4, 3));
        // Column j = x; map row i = y is the image's row (rows − 1 − i): +y is up in the image.
        assert!((m.at(0, 3) - (3000.0 + 14.0) / 65535.0 * 2.0).abs() < 1e-12);
        assert!((m.at(2, 3) - 3000.0 / 65535.0 * 2.0).abs() < 1e-12);
        let img =
            image::GrayImage::from_fn(2, 2, |x, _| image::Luma([if x == 1 { 255 } else { 51 }]));
        let mut v = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png)
            .unwrap();
        let m = HeightMap::from_bytes(Path::new("b.png"), &v, 1.0, 3.0, Border::Wrap).unwrap();
        assert!((m.at(0, 1) - 3.0).abs() < 1e-12 && (m.at(1, 0) - 0.6).abs() < 1e-12);
    }

    #[test]
    fn exr_and_tiff_load() {
        let img = image::Rgb32FImage::from_fn(3, 2, |x, y| {
            image::Rgb([x as f32 * 0.25 + y as f32, 0.0, 0.0])
        });
        let mut v = Vec::new();
        image::DynamicImage::ImageRgb32F(img)
            .write_to(
                &mut std::io::Cursor::new(&mut v),
                image::ImageFormat::OpenExr,
            )
            .unwrap();
        let m = HeightMap::from_bytes(Path::new("a.exr"), &v, 1.0, 2.0, Border::Wrap).unwrap();
        assert!((m.at(0, 2) - (0.5 + 1.0) * 2.0).abs() < 1e-6);
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(3, 2, |x, _| {
            image::Luma([x as u16 * 30000])
        });
        let mut v = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Tiff)
            .unwrap();
        let m = HeightMap::from_bytes(Path::new("a.tif"), &v, 1.0, 1.0, Border::Wrap).unwrap();
        assert!((m.at(0, 2) - 60000.0 / 65535.0).abs() < 1e-12);
    }

    #[test]
    fn bad_images_are_clear_errors() {
        let good = png16(8, 8, |x, _| x as u16);
        let p = Path::new("x.png");
        let e =
            HeightMap::from_bytes(p, &good[..good.len() / 2], 1.0, 1.0, Border::Wrap).unwrap_err();
        assert!(matches!(e, MapError::Decode { .. }), "truncated: {e}");
        let e = HeightMap::from_bytes(p, b"this is not an image at all", 1.0, 1.0, Border::Wrap)
            .unwrap_err();
        assert!(matches!(e, MapError::Decode { .. }), "corrupt: {e}");
        let e = HeightMap::from_bytes(p, b"", 1.0, 1.0, Border::Wrap).unwrap_err();
        assert!(matches!(e, MapError::EmptyFile { .. }), "empty: {e}");
        assert_eq!(
            e.to_string(),
            "x.png is an empty file (0 bytes), not an image"
        );
        for (s, h) in [(0.0, 1.0), (-1.0, 1.0), (1.0, 0.0), (1.0, f64::NAN)] {
            let e = HeightMap::from_bytes(p, &good, s, h, Border::Wrap).unwrap_err();
            assert!(matches!(e, MapError::InvalidParameter { .. }), "{e}");
            assert!(e.to_string().contains("must be a finite number > 0"));
        }
        // Scales whose facets would overflow or underflow (a texel size of 1e-300 with a height
        // scale of 1e300 gave NaN lobes and a zero BRDF from the gonioreflectometer).
        for (s, h, what) in [
            (1e-300, 1e300, "between 1e-12 and 1e12"),
            (1e-13, 1e-13, "between 1e-12 and 1e12"),
            (1.0, 1e13, "between 1e-12 and 1e12"),
            (
                1e-3,
                2e3,
                "height_scale / texel_size = 2e6 must be at most 1e6",
            ),
        ] {
            let e = HeightMap::from_bytes(p, &good, s, h, Border::Wrap).unwrap_err();
            assert!(matches!(e, MapError::Scale { .. }), "{e}");
            assert!(e.to_string().starts_with("x.png: "), "names the file: {e}");
            assert!(e.to_string().contains(what), "{e}");
        }
        // The bounds themselves are usable.
        assert!(HeightMap::from_bytes(p, &good, 1e-3, 1e3, Border::Wrap).is_ok());
        let e = HeightMap::from_heights(2, 2, vec![0.0, f64::NAN, 0.0, 0.0], 1.0, Border::Wrap)
            .unwrap_err();
        assert_eq!(e.to_string(), "height at row 0, column 1 is not finite");
        let e =
            HeightMap::load(Path::new("/nonexistent/x.png"), 1.0, 1.0, Border::Wrap).unwrap_err();
        assert!(matches!(e, MapError::Io { .. }));
    }

    fn crc32(data: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }

    #[test]
    fn absurd_size_refused_from_header() {
        // A valid PNG header claiming 100000 × 100000 pixels, and no image data at all: the
        // refusal must come from the header, before any decoding or allocation.
        let mut f = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A, 0, 0, 0, 13];
        let mut chunk = b"IHDR".to_vec();
        chunk.extend_from_slice(&100_000u32.to_be_bytes());
        chunk.extend_from_slice(&100_000u32.to_be_bytes());
        chunk.extend_from_slice(&[16, 0, 0, 0, 0]);
        f.extend_from_slice(&chunk);
        f.extend_from_slice(&crc32(&chunk).to_be_bytes());
        let e =
            HeightMap::from_bytes(Path::new("big.png"), &f, 1.0, 1.0, Border::Wrap).unwrap_err();
        assert!(
            matches!(e, MapError::TooLarge { width: 100_000, .. }),
            "{e}"
        );
    }

    /// A tileable surface with no symmetry in y (a sawtooth ramp up the image plus a diagonal
    /// ripple), as an image: `img(c, r)` at image column `c`, image row `r` (row 0 at the top).
    fn asymmetric_surface(n: usize) -> impl Fn(f64, f64) -> f64 {
        move |c: f64, r: f64| {
            let t = std::f64::consts::TAU / n as f64;
            // Rises towards the top of the image over most of a period, drops steeply.
            let saw = ((n as f64 - r) * 3.0 / n as f64).fract();
            let saw = if saw < 0.8 {
                saw / 0.8
            } else {
                (1.0 - saw) / 0.2
            };
            0.35 * saw + 0.02 * ((c + 2.0 * r) * t * 2.0).sin()
        }
    }

    /// The standard formula: a tangent-space normal map from a height image, `n ∝ (−∂h/∂x,
    /// −∂h/∂y_up, 1)` with `y_up` up the image (central differences), encoded as 16-bit RGB with
    /// green = +y_up (OpenGL) or −y_up (DirectX).
    fn normal_map_png(n: usize, f: &dyn Fn(f64, f64) -> f64, scale: f64, gl: bool) -> Vec<u8> {
        let img = image::ImageBuffer::<image::Rgb<u16>, _>::from_fn(n as u32, n as u32, |c, r| {
            let (c, r) = (c as f64, r as f64);
            let dhdx = (f(c + 0.5, r) - f(c - 0.5, r)) * scale;
            // y_up grows as the image row shrinks.
            let dhdy_up = (f(c, r - 0.5) - f(c, r + 0.5)) * scale;
            let v = DVec3::new(-dhdx, -dhdy_up, 1.0).normalize();
            let g = if gl { v.y } else { -v.y };
            let q = |x: f64| ((x * 0.5 + 0.5) * 65535.0).round() as u16;
            image::Rgb([q(v.x), q(g), q(v.z)])
        });
        let mut v = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png)
            .unwrap();
        v
    }

    /// Binned distribution of unit normals (projected weights, 12×12 bins over n_x, n_y).
    fn histogram(normals: &[(DVec3, f64)]) -> Vec<f64> {
        let mut h = vec![0.0; 144];
        let mut total = 0.0;
        for (n, w) in normals {
            let bx = (((n.x + 0.6) / 1.2 * 12.0).floor()).clamp(0.0, 11.0) as usize;
            let by = (((n.y + 0.6) / 1.2 * 12.0).floor()).clamp(0.0, 11.0) as usize;
            h[by * 12 + bx] += w * n.z;
            total += w * n.z;
        }
        h.iter().map(|v| v / total).collect()
    }

    fn l1(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum()
    }

    /// Issue #15 item 1: a normal map derived from a height map by the standard formula has the
    /// height map's NDF in its own convention (`gl` for OpenGL maps, `dx` for DirectX ones), and
    /// the other convention's NDF is visibly different (mirrored in y).
    #[test]
    fn normal_map_from_height_map_has_its_ndf_in_both_conventions() {
        let n = 64;
        let f = asymmetric_surface(n);
        let (s, hscale) = (1.0, 6.0);
        // The height image, 16-bit, image rows top-down.
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(n as u32, n as u32, |c, r| {
            image::Luma([((f(c as f64, r as f64) + 0.5) / 1.0 * 65535.0).round() as u16])
        });
        let mut hb = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut hb), image::ImageFormat::Png)
            .unwrap();
        let hm = HeightMap::from_bytes(Path::new("h.png"), &hb, s, hscale, Border::Wrap).unwrap();
        let from_heights = histogram(
            &FacetNormals::from_heightmap(&hm, NormalMode::CentralDifferences).normalized(),
        );
        // Projected share of the facets leaning towards −y.
        let down = |v: &[(DVec3, f64)]| {
            let all: f64 = v.iter().map(|(n, w)| n.z * w).sum();
            v.iter()
                .filter(|(n, _)| n.y < 0.0)
                .map(|(n, w)| n.z * w)
                .sum::<f64>()
                / all
        };
        let hn = FacetNormals::from_heightmap(&hm, NormalMode::CentralDifferences).normalized();
        // The sawtooth rises up the image over 80% of its period: most facets lean down the
        // image, i.e. towards −y (meso's +y is up in the image).
        assert!(down(&hn) > 0.7, "share leaning to −y {}", down(&hn));
        for (gl, conv, other) in [
            (true, NormalConvention::Gl, NormalConvention::Dx),
            (false, NormalConvention::Dx, NormalConvention::Gl),
        ] {
            let bytes = normal_map_png(n, &f, hscale / s, gl);
            let dir_ = std::env::temp_dir().join(format!("meso-nm-{}-{gl}", std::process::id()));
            std::fs::create_dir_all(&dir_).unwrap();
            let p = dir_.join("n.png");
            std::fs::write(&p, &bytes).unwrap();
            let right = NormalMap::load(&p, conv).unwrap();
            let wrong = NormalMap::load(&p, other).unwrap();
            std::fs::remove_dir_all(&dir_).unwrap();
            let hr = histogram(&FacetNormals::from_normal_map(&right).normalized());
            let hw = histogram(&FacetNormals::from_normal_map(&wrong).normalized());
            let (dr, dw) = (l1(&hr, &from_heights), l1(&hw, &from_heights));
            assert!(
                dr < 0.3,
                "{conv:?}: NDF L1 distance {dr} (wrong convention {dw})"
            );
            assert!(dw > 1.0, "{other:?} should differ: {dw} (right one {dr})");
            // Texel by texel: the map's normal at sample (row i, col j) matches the height
            // map's slope there (the map's rows are reversed like the height map's).
            let nm = right.normals();
            let mut dot = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let a = nm[i * n + j];
                    let dhdx = (hm.at(i as isize, j as isize + 1)
                        - hm.at(i as isize, j as isize - 1))
                        / (2.0 * s);
                    let dhdy = (hm.at(i as isize + 1, j as isize)
                        - hm.at(i as isize - 1, j as isize))
                        / (2.0 * s);
                    dot += a.dot(DVec3::new(-dhdx, -dhdy, 1.0).normalize());
                }
            }
            let mean_dot = dot / (n * n) as f64;
            assert!(mean_dot > 0.98, "{conv:?}: mean n·n' {mean_dot}");
        }
    }

    #[test]
    fn normal_maps_jpeg_two_channel_and_below_horizon() {
        let dir_ = std::env::temp_dir().join(format!("meso-maps-nm-{}", std::process::id()));
        std::fs::create_dir_all(&dir_).unwrap();
        // JPEG (8-bit, lossy): a uniform tilt comes back within the codec's error.
        let img = image::RgbImage::from_fn(16, 16, |_, _| image::Rgb([128, 200, 220]));
        let p = dir_.join("n.jpg");
        img.save(&p).unwrap();
        let gl = NormalMap::load(&p, NormalConvention::Gl).unwrap();
        let dx = NormalMap::load(&p, NormalConvention::Dx).unwrap();
        let (a, b) = (gl.normals()[0], dx.normals()[0]);
        // Green above mid-grey: up in the image, +y for OpenGL maps.
        assert!(a.y > 0.3 && (a.y + b.y).abs() < 1e-9 && (a.x - b.x).abs() < 1e-9);
        // Two channels (grey + alpha as x, y): z rebuilt.
        let la = image::GrayAlphaImage::from_fn(4, 4, |_, _| image::LumaA([200, 128]));
        let p2 = dir_.join("rg.png");
        la.save(&p2).unwrap();
        let m = NormalMap::load(&p2, NormalConvention::Gl).unwrap();
        let x = 2.0 * 200.0 / 255.0 - 1.0;
        let v = m.normals()[0];
        assert!((v.x - x).abs() < 1e-6 && (v.z - (1.0 - x * x - v.y * v.y).sqrt()).abs() < 1e-6);
        // RGB with an all-zero blue channel (BC5-style RG): z rebuilt too.
        let rg = image::RgbImage::from_fn(4, 4, |_, _| image::Rgb([128, 60, 0]));
        let p3 = dir_.join("rg0.png");
        rg.save(&p3).unwrap();
        let m = NormalMap::load(&p3, NormalConvention::Gl).unwrap();
        assert!(m.normals()[0].z > 0.8 && m.normals()[0].y < -0.4);
        // Below the horizon: clamped and counted, not refused.
        let low = image::RgbImage::from_fn(4, 4, |x, _| {
            image::Rgb(if x == 0 {
                [255, 128, 100]
            } else {
                [128, 128, 255]
            })
        });
        let p4 = dir_.join("low.png");
        low.save(&p4).unwrap();
        let m = NormalMap::load(&p4, NormalConvention::Gl).unwrap();
        assert_eq!(m.clamped(), 4);
        assert!(
            (m.normals()[0].z - meso_maps::heightmap::MIN_NORMAL_Z).abs() < 1e-12
                && m.normals()[0].x > 0.99
        );
        // A "no data" grey texel (128, 128, 128) off-centre in an 8 × 8 map: refused, the
        // texel named by its image row (from the top) and column.
        let grey = image::RgbImage::from_fn(8, 8, |x, y| {
            image::Rgb(if (x, y) == (2, 1) {
                [128, 128, 128]
            } else {
                [128, 128, 255]
            })
        });
        let p5 = dir_.join("grey.png");
        grey.save(&p5).unwrap();
        let e = NormalMap::load(&p5, NormalConvention::Gl)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("grey.png") && e.contains("image row 1 (from the top), column 2"),
            "{e}"
        );
        assert!(e.contains("not a normal") && e.contains("no data"), "{e}");
        assert!(e.contains("the first of 1 such texels of 64"), "{e}");
        // A map all of "no data" grey: the first texel in reading order (row 0, column 0), and
        // how many.
        let p5b = dir_.join("all-grey.png");
        image::RgbImage::from_pixel(4, 3, image::Rgb([128, 128, 128]))
            .save(&p5b)
            .unwrap();
        let e = NormalMap::load(&p5b, NormalConvention::Gl)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("image row 0 (from the top), column 0")
                && e.contains("first of 12 such texels of 12"),
            "{e}"
        );
        // A single-channel grey image (a height map given as a normal map, 8- and 16-bit; a
        // grey of 200 would read as a uniform 55° tilt): refused, naming the file and saying
        // what it looks like; grey + alpha stays a two-channel normal map (above).
        let p5c = dir_.join("heights8.png");
        image::GrayImage::from_fn(8, 8, |x, y| image::Luma([(20 * x + 7 * y) as u8]))
            .save(&p5c)
            .unwrap();
        let p5d = dir_.join("heights16.png");
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(8, 8, |x, _| {
            image::Luma([5000 * x as u16])
        })
        .save(&p5d)
        .unwrap();
        for p in [&p5c, &p5d] {
            let e = NormalMap::load(p, NormalConvention::Gl)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&p.display().to_string())
                    && e.contains(meso_maps::heightmap::GREY_NOT_NORMALS),
                "{e}"
            );
        }
        // A NaN in a float map at the same place: the same image row.
        let mut f = image::Rgb32FImage::from_fn(8, 8, |_, _| image::Rgb([0.5, 0.5, 1.0]));
        f.put_pixel(2, 1, image::Rgb([f32::NAN, 0.5, 1.0]));
        let p6 = dir_.join("nan.exr");
        image::DynamicImage::ImageRgb32F(f).save(&p6).unwrap();
        let e = NormalMap::load(&p6, NormalConvention::Gl)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("nan.exr") && e.contains("image row 1 (from the top), column 2"),
            "{e}"
        );
        // A NaN height in a float height map: named by its image row too.
        let mut hf = image::Rgb32FImage::from_fn(8, 8, |_, _| image::Rgb([0.5, 0.5, 0.5]));
        hf.put_pixel(2, 1, image::Rgb([f32::NAN, f32::NAN, f32::NAN]));
        let p7 = dir_.join("hnan.exr");
        image::DynamicImage::ImageRgb32F(hf).save(&p7).unwrap();
        let e = HeightMap::load(&p7, 1.0, 1.0, Border::Wrap)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("hnan.exr") && e.contains("image row 1 (from the top), column 2"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir_).unwrap();
        let e = NormalMap::from_normals(1, 1, vec![DVec3::ZERO]).unwrap_err();
        assert!(e.to_string().contains("row 0, column 0"), "{e}");
        assert!(e.to_string().contains("zero length"), "{e}");
        let e = NormalMap::from_normals(1, 1, vec![DVec3::new(f64::NAN, 0.0, 1.0)]).unwrap_err();
        assert!(e.to_string().contains("NaN"), "{e}");
    }

    /// A real texture set (ambientCG Facade005, CC0, tests/data/README.md): the normals derived
    /// from its height map point the same way as its OpenGL normal map read as `gl` (and the
    /// opposite way in y read as `dx`). Its flat tiles are real, not terraces: not dequantised.
    #[test]
    fn real_texture_set_height_and_gl_normal_map_agree() {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
        let hm =
            HeightMap::load(&data.join("facade_disp_256.png"), 1.0, 8.0, Border::Wrap).unwrap();
        assert!(hm.warnings().is_empty(), "{:?}", hm.warnings());
        let from_h = FacetNormals::from_heightmap(&hm, NormalMode::CentralDifferences);
        let corr = |conv| {
            let nm = NormalMap::load(&data.join("facade_normal_256.png"), conv).unwrap();
            let (n, w) = (nm.width(), hm.width());
            assert_eq!(n, w);
            // Cell (i, j) of the height map is centred half a texel from sample (i, j).
            let (mut sx, mut sy, mut xx, mut yy, mut hx, mut hy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for i in 0..n {
                for j in 0..n {
                    let a = nm.normals()[i * n + j];
                    let b = from_h.normals[i * n + j];
                    sx += a.x * b.x;
                    sy += a.y * b.y;
                    xx += a.x * a.x;
                    yy += a.y * a.y;
                    hx += b.x * b.x;
                    hy += b.y * b.y;
                }
            }
            (sx / (xx * hx).sqrt(), sy / (yy * hy).sqrt())
        };
        let (gx, gy) = corr(NormalConvention::Gl);
        let (dx, dy) = corr(NormalConvention::Dx);
        eprintln!("facade: gl corr x {gx:.3} y {gy:.3}; dx corr x {dx:.3} y {dy:.3}");
        assert!(gx > 0.3 && gy > 0.3, "gl {gx} {gy}");
        assert!(dy < -0.3 && (dx - gx).abs() < 1e-12, "dx {dx} {dy}");
    }

    /// Issue #11 item 5: an 8-bit height map's terraces (many exactly flat cells) are removed on
    /// load, so its NDF has no false spike at +z and stays close to the float surface's.
    #[test]
    fn eight_bit_terraces_are_dequantised() {
        let n = 128;
        // Broad valleys with a few high ridges (the cube of a smooth random field), as a real
        // displacement map has: the gentle low ground turns into terraces at 8 bits.
        let field = fixtures::gaussian(n, 10.0, 1.0, 7, 1.0).unwrap();
        let (flo, fhi) = field.range();
        let truth = HeightMap::from_heights(
            n,
            n,
            field
                .heights()
                .iter()
                .map(|h| 4.0 * ((h - flo) / (fhi - flo)).powi(6))
                .collect(),
            1.0,
            Border::Wrap,
        )
        .unwrap();
        let (lo, hi) = truth.range();
        let img = image::GrayImage::from_fn(n as u32, n as u32, |c, r| {
            let h = truth.at((n - 1 - r as usize) as isize, c as isize);
            image::Luma([((h - lo) / (hi - lo) * 255.0).round() as u8])
        });
        let mut b = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut b), image::ImageFormat::Png)
            .unwrap();
        let hscale = hi - lo;
        let m =
            HeightMap::from_bytes(Path::new("rock.png"), &b, 1.0, hscale, Border::Wrap).unwrap();
        // The raw codes: many flat cells.
        let mut raw = m.clone();
        let raw_h: Vec<f64> = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .map(|(i, j)| {
                let r = n - 1 - i;
                img.get_pixel(j as u32, r as u32).0[0] as f64 / 255.0 * hscale
            })
            .collect();
        raw = HeightMap::from_heights(n, n, raw_h, 1.0, Border::Wrap).unwrap_or(raw);
        assert!(
            raw.flat_cell_fraction() > 0.05,
            "fixture: {}",
            raw.flat_cell_fraction()
        );
        assert!(
            m.flat_cell_fraction() < 0.005,
            "after: {}",
            m.flat_cell_fraction()
        );
        assert!(
            m.warnings().iter().any(|w| w.contains("dequantised")),
            "{:?}",
            m.warnings()
        );
        // No height moved by more than half a code.
        for (a, b) in m.heights().iter().zip(raw.heights()) {
            assert!((a - b).abs() <= 0.5 * hscale / 255.0 + 1e-12);
        }
        // The spike: share of projected area exactly at +z.
        let spike = |map: &HeightMap| {
            FacetNormals::from_heightmap(map, NormalMode::Triangles)
                .normalized()
                .iter()
                .filter(|(v, _)| v.z > 1.0 - 1e-12)
                .map(|(v, w)| w * v.z)
                .sum::<f64>()
        };
        let (s_truth, s_raw, s_deq) = (spike(&truth), spike(&raw), spike(&m));
        assert!(
            s_truth < 0.01 && s_raw > 0.05,
            "raw {s_raw} truth {s_truth}"
        );
        assert!(s_deq < 0.02, "dequantised {s_deq} truth {s_truth}");
        // And the slopes: the dequantised facets are closer to the truth's, texel by texel.
        let err = |map: &HeightMap| {
            let a = FacetNormals::from_heightmap(map, NormalMode::Triangles);
            let b = FacetNormals::from_heightmap(&truth, NormalMode::Triangles);
            a.normals
                .iter()
                .zip(&b.normals)
                .map(|(x, y)| x.angle_between(*y))
                .sum::<f64>()
                / a.normals.len() as f64
        };
        let (e_raw, e_deq) = (err(&raw), err(&m));
        eprintln!(
            "mean facet angle error: raw {:.3}°, dequantised {:.3}°",
            e_raw.to_degrees(),
            e_deq.to_degrees()
        );
        assert!(e_deq < 0.8 * e_raw, "raw {e_raw} dequantised {e_deq}");
    }
}

mod pyramid {
    use super::*;

    /// Maps of faces and walls get six lobes a texel by default, other maps four
    /// (`ExtractParams::walls_max_lobes`): the shares of a terraced map in closed form (a step
    /// of 3 cells' height every 4 cells along x: of each 8 cells 2 are walls at 71.6°, 6 flat
    /// faces), its extraction's header and a texel of more than four lobes; a steep Gaussian
    /// relief (walls, no faces) and a gentle one keep four; a K asked for applies to every map.
    #[test]
    fn maps_of_faces_and_walls_get_six_lobes() {
        let terraces = HeightMap::from_fn(64, 64, 1.0, Border::Wrap, |x, y| {
            3.0 * (((x as i64) / 4 + (y as i64) / 8) % 2) as f64
        })
        .unwrap();
        let (faces, walls) = relief_shares(Source::Heights(&terraces), NormalMode::Triangles);
        assert!(faces > 0.5 && walls > 0.2, "{faces} {walls}");
        let p = ExtractParams::default();
        assert_eq!(p.max_lobes_for(Source::Heights(&terraces)), WALLS_MAX_LOBES);
        let pyr = extract(Source::Heights(&terraces), &p, &mut |_| {}).unwrap();
        assert_eq!(pyr.max_lobes, 6);
        let most = pyr
            .levels
            .iter()
            .flat_map(|l| (0..l.rows * l.cols).map(move |t| (l, t)))
            .map(|(l, t)| l.texel_lobes(t / l.cols, t % l.cols).unwrap().len())
            .max()
            .unwrap();
        assert!(most > 4, "at most {most} lobes a texel");
        let asked = p.clone().with_max_lobes(4);
        assert_eq!(asked.max_lobes_for(Source::Heights(&terraces)), 4);
        assert_eq!(
            extract(Source::Heights(&terraces), &asked, &mut |_| {})
                .unwrap()
                .max_lobes,
            4
        );
        // A step along x only: exactly 2 wall cells of 8, 6 flat.
        let steps = HeightMap::from_fn(64, 8, 1.0, Border::Wrap, |x, _| {
            3.0 * (((x as i64) / 4) % 2) as f64
        })
        .unwrap();
        let (faces, walls) = relief_shares(Source::Heights(&steps), NormalMode::Triangles);
        assert!(
            (faces - 0.75).abs() < 1e-12 && (walls - 0.25).abs() < 1e-12,
            "{faces} {walls}"
        );
        // Continuous reliefs: the steep Gaussian has walls but no faces, the gentle one no walls.
        for (g, steep) in [
            (fixtures::gaussian(64, 4.0, 0.1, 3, 0.01).unwrap(), true),
            (fixtures::gaussian(64, 3.0, 0.15, 11, 0.1).unwrap(), false),
        ] {
            let (faces, walls) = relief_shares(Source::Heights(&g), NormalMode::Triangles);
            if steep {
                assert!(faces < FACE_SHARE && walls > 0.5, "{faces} {walls}");
            } else {
                assert!(walls < WALL_SHARE, "{faces} {walls}");
            }
            assert_eq!(p.max_lobes_for(Source::Heights(&g)), 4);
        }
    }

    /// Issue #11 item 4, as a property over random maps: steep Gaussian surfaces (RMS slope up
    /// to ≈ 2) and random normal maps with texels below the horizon. Every fitted lobe of every
    /// level has its axis above the horizon and a bounded exponent; weights sum to 1.
    #[test]
    fn no_lobe_below_the_horizon_or_flat_on_random_maps() {
        use meso_maps::limits::{AXIS_MIN_Z, ETA_MIN};
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut checked = 0;
        for seed in 0..6u64 {
            let rms = 0.2 + 0.4 * seed as f64;
            let corr = 1.5 + (seed % 3) as f64;
            let map = fixtures::gaussian(32, corr, rms, seed, 1.0).unwrap();
            let normals: Vec<DVec3> = (0..32 * 32)
                .map(|_| {
                    let z = rng.random::<f64>() * 1.2 - 0.3;
                    DVec3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, z)
                })
                .map(|v| if v.length() < 1e-3 { DVec3::Z } else { v })
                .collect();
            let nm = NormalMap::from_normals(32, 32, normals).unwrap();
            assert!(nm.clamped() > 0);
            for k in [1, 4, 8] {
                let mut p = ExtractParams::default();
                p = p.with_max_lobes(k);
                for src in [Source::Heights(&map), Source::Normals(&nm)] {
                    let pyr = extract(src, &p, &mut |_| {}).unwrap();
                    for l in &pyr.levels {
                        for t in 0..l.texels() {
                            let lobes = l.texel_lobes(t / l.cols, t % l.cols).unwrap();
                            let w: f64 = lobes.iter().map(|x| x.weight).sum();
                            assert!((w - 1.0).abs() < 1e-9, "weights {w}");
                            for x in lobes {
                                assert!(x.axis.z >= AXIS_MIN_Z - 1e-9, "axis {:?}", x.axis);
                                assert!(x.exponent >= ETA_MIN && x.exponent <= ETA_MAX);
                                checked += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked}");
    }

    #[test]
    fn flat_gives_one_delta_lobe_everywhere() {
        let map = fixtures::flat(24, 0.1).unwrap(); // not a power of two: ragged levels
        let p = pyr(&map, 4);
        assert_eq!(p.levels.len(), 6); // 24, 12, 6, 3, 2, 1
        assert_eq!((p.levels[4].cols, p.levels[4].rows), (2, 2));
        for l in &p.levels {
            for t in 0..l.texels() {
                let lobes = l.texel_lobes(t / l.cols, t % l.cols).unwrap();
                assert_eq!(lobes.len(), 1);
                assert!((lobes[0].axis - DVec3::Z).length() < 1e-12);
                assert!((lobes[0].weight - 1.0).abs() < 1e-12 && lobes[0].exponent == ETA_MAX);
            }
            assert!(l.residual.max < 1e-12);
        }
    }

    #[test]
    fn v_grooves_give_two_exact_lobes() {
        let map = fixtures::v_grooves(32, 8, 0.2, 0.1).unwrap();
        let p = pyr(&map, 4);
        let top = p.top().texel_lobes(0, 0).unwrap();
        assert_eq!(top.len(), 2);
        let slope: f64 = 2.0 * 0.2 / 0.8;
        let expect = DVec3::new(slope, 0.0, 1.0).normalize();
        for l in top {
            assert!((l.weight - 0.5).abs() < 1e-9);
            assert!((l.axis.x.abs() - expect.x).abs() < 1e-9 && l.axis.y.abs() < 1e-12);
            assert_eq!(l.exponent, ETA_MAX);
        }
    }

    #[test]
    fn half_cylinders_spread_on_a_great_circle() {
        let map = fixtures::half_cylinders(64, 16, 0.1, 1.0).unwrap();
        let p = pyr(&map, 7);
        let lobes = p.top().texel_lobes(0, 0).unwrap();
        assert!(lobes.len() >= 3, "{} lobes", lobes.len());
        // Eq. 15: the cylinder's normals lie on the great circle y = 0 (axis along y).
        let mut spread = 0.0f64;
        for l in &lobes {
            assert!(
                l.axis.y.abs() < 1e-6,
                "axis {:?} off the great circle",
                l.axis
            );
            spread = spread.max(l.axis.x.abs());
        }
        assert!(
            spread > 0.5,
            "lobes spread along the circle: max |x| = {spread}"
        );
        // The lobe sum matches the histogram of the normals.
        // Isotropic lobes cannot be as thin as the great circle, so the binned L2 error stays
        // high, but it must fall as lobes are added.
        let r7 = p.top().residual.mean;
        let r1 = pyr(&map, 1).top().residual.mean;
        assert!(r7 < 0.9 && r7 < r1 - 0.05, "K=1 {r1}, K=7 {r7}");
        // Symmetric: the weighted mean axis is +z.
        let mean: DVec3 = lobes.iter().map(|l| l.axis * l.weight).sum();
        assert!(mean.x.abs() < 0.02, "{mean}");
    }

    #[test]
    fn residual_is_bounded_and_falls_with_k() {
        let map = fixtures::gaussian(64, 3.0, 0.15, 7, 0.1).unwrap();
        let e1 = pyr(&map, 1).top().residual.mean;
        let e4 = pyr(&map, 4).top().residual.mean;
        assert!(e4 <= e1 + 1e-9 && e4 < 0.35, "K=1 {e1}, K=4 {e4}");
        let woven = fixtures::woven(64, 16, 0.1, 0.05).unwrap();
        let w1 = pyr(&woven, 1).top().residual.mean;
        let w4 = pyr(&woven, 4).top().residual.mean;
        assert!(w4 < w1, "woven K=1 {w1}, K=4 {w4}");
    }

    #[test]
    fn map_file_round_trip_and_errors() {
        let map = fixtures::gaussian(20, 2.0, 0.1, 3, 0.1).unwrap();
        let p = pyr(&map, 3);
        let dir_ = std::env::temp_dir().join(format!("meso-maps-fmt-{}", std::process::id()));
        std::fs::create_dir_all(&dir_).unwrap();
        let path = dir_.join("a.map");
        p.write(&path).unwrap();
        let q = Pyramid::read(&path).unwrap();
        assert_eq!(q.levels.len(), p.levels.len());
        for (a, b) in p.levels.iter().zip(&q.levels) {
            assert_eq!(a.lobe_start, b.lobe_start);
            // The map file quantises (format 3's codes, docs/map-format.md): axes to 2.9e-6
            // rad, weights to 1/65 535, exponents to 1.06e-4 (1 + 1/η) relative.
            for (x, y) in a.lobes.iter().zip(&b.lobes) {
                assert!(x.axis.angle_between(y.axis) < 2.9e-6);
                assert!((y.weight - x.weight).abs() < 1.0 / 65535.0);
                assert!(rel(y.exponent, x.exponent) < 1.06e-4 * (1.0 + 1.0 / x.exponent));
            }
            assert_eq!(a.residual, b.residual);
        }
        assert_eq!(q.info(), p.info());
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes, p.to_bytes());
        assert_eq!(bytes[8..12], meso_maps::format::VERSION.to_le_bytes());
        for cut in [0, 7, 30, bytes.len() / 2, bytes.len() - 1] {
            let e = Pyramid::from_bytes(&path, &bytes[..cut]).unwrap_err();
            assert!(
                e.to_string().contains("truncated") || e.to_string().contains("magic"),
                "{e}"
            );
        }
        let mut v2 = bytes.clone();
        v2[8] = 1; // version 1 (projected-area lobe weights) is no longer read
        let e = Pyramid::from_bytes(&path, &v2).unwrap_err();
        assert!(
            matches!(
                e,
                MapError::MapVersion {
                    found: 1,
                    expected: 5,
                    ..
                }
            ),
            "{e}"
        );
        let mut big = bytes.clone();
        big[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(Pyramid::from_bytes(&path, &big)
            .unwrap_err()
            .to_string()
            .contains("outside"));
        // A failing write leaves nothing behind.
        let e = p.write(&dir_.join("no/such/dir/x.map")).unwrap_err();
        // item 12: a write failure is reported as one, not as "cannot read".
        assert!(matches!(e, MapError::Write { .. }));
        assert!(e.to_string().starts_with("cannot write "), "{e}");
        std::fs::remove_dir_all(&dir_).unwrap();
        assert!(p.info().to_string().contains("level"));
    }
}

mod shadowing {
    use super::*;

    #[test]
    fn v_groove_horizon_angles_are_analytic() {
        let (n, period, depth, s) = (32usize, 16usize, 0.3, 0.05);
        let map = fixtures::v_grooves(n, period, depth, s).unwrap();
        let hz = HorizonMap::compute(&map);
        let p = period as f64 * s;
        let wall = (2.0 * depth / p).atan();
        for j in 0..n {
            let x = (j % period) as f64 * s;
            let h = map.at(0, j as isize);
            // Looking +x: on the descending wall the far rim is the horizon; on the rising wall,
            // the wall itself.
            let expect_px = if x <= 0.5 * p {
                ((depth - h) / (p - x)).atan()
            } else {
                wall
            };
            let xr = if x == 0.0 { p } else { x }; // looking −x: mirror image
            let expect_mx = if xr >= 0.5 * p {
                ((depth - h) / xr).atan()
            } else {
                wall
            };
            // Stored to 16 bits: within half a step (and the exact code of the rounded angle).
            let half = 0.5 * meso_maps::horizon::ANGLE_STEP + 1e-12;
            assert!(
                (hz.angle(0, j) - expect_px).abs() < half,
                "j {j}: {} vs {expect_px}",
                hz.angle(0, j)
            );
            assert_eq!(
                hz.angles[0][j],
                (expect_px / meso_maps::horizon::ANGLE_STEP).round() as u16
            );
            assert!((hz.angle(2, j) - expect_mx).abs() < half, "j {j}");
            assert!(hz.angles[1][j] == 0 && hz.angles[3][j] == 0);
        }
    }

    #[test]
    fn horizon_stats_merge_exactly() {
        let map = fixtures::gaussian(16, 2.0, 0.1, 1, 0.1).unwrap();
        let p = pyr(&map, 1);
        let hz = HorizonMap::compute(&map);
        let all = hz.total_stats();
        let top = p.top().texel_horizon(0, 0).unwrap().unwrap();
        for d in 0..4 {
            let vals: Vec<f64> = (0..hz.angles[d].len()).map(|k| hz.angle(d, k)).collect();
            let mean = vals.iter().sum::<f64>() / vals.len() as f64;
            let var = vals.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / vals.len() as f64;
            assert!((top.mean[d] - mean).abs() < 1e-12 && (top.var[d] - var).abs() < 1e-12);
            assert!((all.mean[d] - mean).abs() < 1e-12);
        }
        // Visibility: straight up always visible, below the horizon never; monotone in elevation.
        assert_eq!(top.visibility(DVec3::Z), 1.0);
        let mut last = 0.0;
        for t in (0..=89).rev() {
            let v = top.visibility(dir(t as f64, 30.0));
            assert!(v >= last - 1e-12);
            last = v;
        }
    }

    #[test]
    fn smith_lambda_of_v_groove_is_exact() {
        // For a symmetric V-groove with wall slope s, in the plane of the grooves:
        // 1 + Λ(ω) = (Σ_m p_m max(0, ω·m)/m_z)/cos θ = (½)(|tanθ| + s)... for tanθ > s: tanθ/tanθ=1.
        let map = fixtures::v_grooves(16, 8, 0.1, 0.05).unwrap();
        let ndf = facets_ndf(&map);
        let b = SmithMasking::new(&ndf, Accuracy::default());
        let s: f64 = 2.0 * 0.1 / 0.4;
        for t in [10.0f64, 40.0, 70.0, 85.0] {
            let w = dir(t, 0.0);
            let tt = t.to_radians().tan();
            // Facets at ±s: ω·m/m_z = −(±s)·sinθ... = cosθ(1 ∓ s tanθ) when positive.
            let sum = 0.5 * ((1.0 + s * tt).max(0.0) + (1.0 - s * tt).max(0.0));
            assert!((b.lambda(w) - (sum - 1.0)).abs() < 1e-12, "θ {t}");
        }
    }
}

mod brdf {
    use super::*;

    fn pairs() -> Vec<(DVec3, DVec3)> {
        let mut v = Vec::new();
        for ti in [0.0, 30.0, 60.0] {
            for to in [0.0, 20.0, 45.0, 60.0] {
                for po in [0.0, 90.0, 180.0] {
                    v.push((dir(ti, 0.0), dir(to, po)));
                }
            }
        }
        v
    }

    #[test]
    fn top_level_lobes_match_brute_force_facet_sum() {
        let phong = phong(20.0, [1.0; 3]);
        for (name, map) in [
            (
                "gaussian",
                fixtures::gaussian(64, 3.0, 0.15, 11, 0.1).unwrap(),
            ),
            (
                "cylinders",
                fixtures::half_cylinders(64, 16, 0.1, 1.0).unwrap(),
            ),
        ] {
            let p = pyr(&map, 7);
            let fit = lobes_ndf(&p.top().texel_lobes(0, 0).unwrap());
            let exact = facets_ndf(&map);
            // Errors relative to the largest value of the set (a peaked BRDF's far tail is
            // reported, not bounded: see docs/heightmaps.md).
            for f in [&LAMBERT, &phong] {
                let vals: Vec<(f64, f64)> = pairs()
                    .into_iter()
                    .map(|(i, o)| {
                        (
                            microfacet(&fit, f, Visibility::None, i, o)[0],
                            microfacet(&exact, f, Visibility::None, i, o)[0],
                        )
                    })
                    .collect();
                let peak = vals.iter().map(|v| v.1).fold(0.0, f64::max);
                let worst = vals
                    .iter()
                    .map(|(a, b)| (a - b).abs() / peak)
                    .fold(0.0, f64::max);
                assert!(worst < 0.10, "{name}: worst BRDF error {worst} of the peak");
            }
        }
    }

    #[test]
    fn flat_facet_sum_is_the_facet_brdf() {
        let map = fixtures::flat(8, 0.1).unwrap();
        let b = facets_ndf(&map);
        let phong = phong(30.0, [1.0, 0.5, 0.25]);
        for (i, o) in pairs() {
            let a = microfacet(&b, &phong, Visibility::Smith, i, o);
            let e = phong.eval(i, o);
            for c in 0..3 {
                assert!((a[c] - e[c]).abs() < 1e-12 * (1.0 + e[c]));
            }
        }
    }

    #[test]
    fn baselines_fit_their_moments() {
        let map = fixtures::gaussian(32, 2.0, 0.1, 5, 0.1).unwrap();
        let normals = FacetNormals::from_heightmap(&map, NormalMode::Triangles).normalized();
        let mean: DVec3 = normals.iter().map(|(n, w)| *n * *w).sum();
        for m in [
            Baseline::MipNormal,
            Baseline::Toksvig,
            Baseline::Lean,
            Baseline::Vmf,
        ] {
            let ndf = fit_baseline(m, &normals);
            // 64² draws of the core NDF's own sampler on a Fibonacci lattice (every draw its
            // own stratum in both coordinates: the tabulated sampler picks its cell from u₀
            // alone), equal weights.
            let n = 64 * 64;
            let golden = 0.5 * (5f64.sqrt() - 1.0);
            let nodes: Vec<(DVec3, f64)> = (0..n)
                .map(|k| {
                    let u = [(k as f64 + 0.5) / n as f64, (k as f64 * golden).fract()];
                    (ndf.sample(u), 1.0 / n as f64)
                })
                .collect();
            let s: f64 = nodes.iter().map(|p| p.1).sum();
            let nm: DVec3 = nodes.iter().map(|(n, w)| *n * *w).sum();
            assert!((s - 1.0).abs() < 1e-9);
            // Mean normal direction preserved.
            assert!((nm.normalize() - mean.normalize()).length() < 0.02, "{m:?}");
            // Density integrates to 1 (quadrature over an equal-area grid).
            if m != Baseline::MipNormal {
                let g = meso_maps::sphgrid::SphereGrid { res: 128 };
                let tot: f64 = (0..g.bins())
                    .map(|k| ndf.eval(g.point(k, 0.5, 0.5)))
                    .sum::<f64>()
                    * g.bin_solid_angle();
                assert!((tot - 1.0).abs() < 2e-2, "{m:?}: {tot}");
            }
        }
    }
}

mod gonio {
    use super::*;

    #[test]
    fn flat_map_gives_exactly_the_facet_brdf() {
        let map = fixtures::flat(8, 0.1).unwrap();
        let g = Gonio::new(&map).unwrap();
        let phong = phong(10.0, [1.0; 3]);
        let gp = GonioParams {
            rays_per_side: 16,
            ..Default::default()
        };
        for (i, o) in [
            (dir(30.0, 0.0), dir(30.0, 180.0)),
            (dir(60.0, 45.0), dir(10.0, 100.0)),
        ] {
            let a = g.measure(&phong, i, o, &gp)[0];
            let e = phong.eval(i, o)[0];
            assert!((a - e).abs() < 1e-12 * (1.0 + e), "{a} vs {e}");
        }
    }

    #[test]
    fn v_groove_without_masking_equals_facet_sum() {
        // Wall slope 0.5 (26.6°): directions within 20° of the normal in the groove plane
        // neither mask nor shadow, so the gonio result is the plain facet sum.
        let map = fixtures::v_grooves(16, 8, 0.1, 0.05).unwrap();
        let g = Gonio::new(&map).unwrap();
        let ndf = facets_ndf(&map);
        let gp = GonioParams {
            rays_per_side: 64,
            ..Default::default()
        };
        for (i, o) in [
            (dir(10.0, 0.0), dir(15.0, 180.0)),
            (dir(0.0, 0.0), dir(20.0, 90.0)),
        ] {
            let a = g.measure(&LAMBERT, i, o, &gp)[0];
            let b = microfacet(&ndf, &LAMBERT, Visibility::None, i, o)[0];
            assert!(rel(a, b) < 0.01, "{a} vs {b}");
        }
    }

    #[test]
    fn random_surface_gonio_matches_microfacet_smith() {
        let map = fixtures::gaussian(64, 4.0, 0.12, 21, 0.1).unwrap();
        let g = Gonio::new(&map).unwrap();
        let ndf = facets_ndf(&map);
        let gp = GonioParams {
            rays_per_side: 160,
            ..Default::default()
        };
        let mut worst_smith: f64 = 0.0;
        let mut worst_none: f64 = 0.0;
        for (ti, to, po) in [
            (0.0, 0.0, 0.0),
            (30.0, 30.0, 180.0),
            (45.0, 60.0, 90.0),
            (60.0, 60.0, 180.0),
            (60.0, 45.0, 0.0),
        ] {
            let (i, o) = (dir(ti, 0.0), dir(to, po));
            let a = g.measure(&LAMBERT, i, o, &gp)[0];
            let smith = microfacet(&ndf, &LAMBERT, Visibility::Smith, i, o)[0];
            let none = microfacet(&ndf, &LAMBERT, Visibility::None, i, o)[0];
            worst_smith = worst_smith.max(rel(smith, a));
            worst_none = worst_none.max(rel(none, a));
        }
        assert!(worst_smith < 0.05, "Smith vs gonio: {worst_smith}");
        assert!(
            worst_none > worst_smith,
            "shadowing matters: none {worst_none}, Smith {worst_smith}"
        );
    }

    #[test]
    fn interreflection_conserves_energy_under_a_white_furnace() {
        // White Lambert facets (albedo 1) on steep V-grooves (walls at 56°): with enough
        // bounces every photon eventually leaves, so the directional albedo
        // ∫ f cos θ_o dω_o is 1; a single bounce loses what hits the other wall.
        let map = fixtures::v_grooves(16, 8, 0.3, 0.05).unwrap();
        let g = Gonio::new(&map).unwrap();
        let i = dir(30.0, 0.0);
        let albedo = |bounces: usize| {
            let gp = GonioParams {
                rays_per_side: 24,
                bounces,
                ..Default::default()
            };
            // Cosine-weighted stratified directions: albedo = π · mean of f.
            let n = 12;
            let mut s = 0.0;
            for a in 0..n {
                for b in 0..n {
                    let u = (a as f64 + 0.5) / n as f64;
                    let v = (b as f64 + 0.5) / n as f64;
                    let t = u.sqrt().asin().to_degrees();
                    s += g.measure(&LAMBERT, i, dir(t, 360.0 * v), &gp)[0];
                }
            }
            std::f64::consts::PI * s / (n * n) as f64
        };
        let one = albedo(1);
        let many = albedo(24);
        assert!(one < 0.9, "single bounce albedo {one}");
        assert!((many - 1.0).abs() < 0.04, "24 bounces albedo {many}");
    }

    #[test]
    fn bumps_and_grooves_same_ndf_different_brdf() {
        let bumps = fixtures::half_cylinders(64, 16, 0.1, 1.0).unwrap();
        let grooves = bumps.negated();
        // Same NDF: the two normal sets are mirror images about the groove axis (x → −x) and
        // the set is symmetric, so their histograms coincide.
        let grid = meso_maps::sphgrid::SphereGrid { res: 32 };
        let (mut a, mut b) = (vec![0.0; grid.bins()], vec![0.0; grid.bins()]);
        meso_maps::fit::ndf_bin_mass(&facets_ndf(&bumps), grid, &mut a);
        meso_maps::fit::ndf_bin_mass(&facets_ndf(&grooves), grid, &mut b);
        let d: f64 = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum();
        assert!(d < 0.02, "histograms differ by {d}");
        // Different BRDFs at grazing light across the cylinders.
        let gp = GonioParams {
            rays_per_side: 96,
            ..Default::default()
        };
        let (i, o) = (dir(70.0, 0.0), dir(30.0, 180.0));
        let fb = Gonio::new(&bumps).unwrap().measure(&LAMBERT, i, o, &gp)[0];
        let fg = Gonio::new(&grooves).unwrap().measure(&LAMBERT, i, o, &gp)[0];
        assert!(rel(fb, fg) > 0.05, "bumps {fb}, grooves {fg}");
        // The horizon model sees the difference, Smith (NDF only) cannot.
        let pb = pyr(&bumps, 4);
        let pg = pyr(&grooves, 4);
        let hb = pb.top().texel_horizon(0, 0).unwrap().unwrap();
        let hg = pg.top().texel_horizon(0, 0).unwrap().unwrap();
        assert!(
            (hb.visibility(i) - hg.visibility(i)).abs() > 0.05,
            "{} {}",
            hb.visibility(i),
            hg.visibility(i)
        );
    }
}

/// The Eq. 1 convention: fitted lobes and raw facets are densities per unit microsurface area,
/// and the effective BRDF is the core's microfacet form.
mod convention {
    use super::*;
    use meso_core::frame::Frame;

    /// An independent reference for the microfacet form over Phong peaks: `n × n` stratified
    /// draws of each lobe's exact sampler, each carrying `weight/n²`, summed with Smith `Λ` from
    /// the same nodes (not the core's warped product rule).
    fn stratified_microfacet(
        lobes: &[PhongLobe],
        n: usize,
        smith: bool,
        t: &Transfer,
        i: DVec3,
        o: DVec3,
    ) -> f64 {
        let mut nodes = Vec::new();
        for l in lobes {
            for a in 0..n {
                for b in 0..n {
                    let u = [(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64];
                    nodes.push((l.sample(u), l.weight / (n * n) as f64));
                }
            }
        }
        let tot: f64 = nodes.iter().map(|p| p.1).sum();
        let projected: f64 = nodes.iter().map(|p| p.1 * p.0.z.max(0.0)).sum::<f64>() / tot;
        let lambda = |w: DVec3| {
            let s: f64 = nodes
                .iter()
                .filter(|p| p.0.z > 0.0)
                .map(|p| p.1 * w.dot(p.0).max(0.0))
                .sum();
            (s / (tot * projected * w.z) - 1.0).max(0.0)
        };
        let g = if smith {
            1.0 / (1.0 + lambda(i) + lambda(o))
        } else {
            1.0
        };
        let mut acc = 0.0;
        for (m, w) in &nodes {
            let (im, om) = (i.dot(*m), o.dot(*m));
            if m.z <= 0.0 || im <= 0.0 || om <= 0.0 {
                continue;
            }
            let fr = Frame::from_normal_tangent(*m, DVec3::X);
            acc += w / tot * t.eval(fr.to_local(i), fr.to_local(o))[0] * im * om;
        }
        acc * g / (projected * i.z * o.z)
    }

    #[test]
    fn lobe_weights_are_true_area_shares() {
        // Asymmetric sawtooth along x, period 8 cells: rises by d over 2 cells, falls over 6.
        // Projected shares 1/4 and 3/4; true areas ∝ share·√(1 + slope²).
        let (s, d) = (0.1, 0.3);
        let map = HeightMap::from_fn(32, 32, s, Border::Wrap, |x, _| {
            let u = (x / s).round() as i64 % 8;
            if u <= 2 {
                d * u as f64 / 2.0
            } else {
                d * (8 - u) as f64 / 6.0
            }
        })
        .unwrap();
        let (g1, g2) = (d / (2.0 * s), d / (6.0 * s));
        let (a1, a2) = (0.25 * (1.0 + g1 * g1).sqrt(), 0.75 * (1.0 + g2 * g2).sqrt());
        let p = pyr(&map, 4);
        let top = p.top().texel_lobes(0, 0).unwrap();
        assert_eq!(top.len(), 2);
        for l in top {
            let (expect, g) = if l.axis.x < 0.0 {
                (a1 / (a1 + a2), g1)
            } else {
                (a2 / (a1 + a2), g2)
            };
            assert!((l.weight - expect).abs() < 1e-9, "{} vs {expect}", l.weight);
            assert!((l.axis.x.abs() - g / (1.0 + g * g).sqrt()).abs() < 1e-9);
        }
        // The raw facets carry the same areas.
        let f = FacetNormals::from_heightmap(&map, NormalMode::Triangles).normalized();
        let steep: f64 = f.iter().filter(|(n, _)| n.x < 0.0).map(|p| p.1).sum();
        assert!((steep - a1 / (a1 + a2)).abs() < 1e-12);
        // The microfacet form's projected area ∫ n m_z is the macro/micro area ratio.
        let ndf = facets_ndf(&map);
        let b = SmithMasking::new(&ndf, Accuracy::default());
        assert!((b.projected_area - 1.0 / (a1 + a2)).abs() < 1e-12);
    }

    #[test]
    fn effective_brdf_is_the_core_microfacet_form() {
        // Smooth lobes from a Gaussian surface: meso-core's quadrature (what `meso brdf` and
        // the renderer run, at the accuracy of the materials) against stratified lobe samples.
        let map = fixtures::gaussian(64, 3.0, 0.15, 11, 0.1).unwrap();
        let p = pyr(&map, 3);
        let lobes = p.top().texel_lobes(0, 0).unwrap().to_vec();
        let core = lobes_ndf(&lobes);
        let transfer = LAMBERT;
        for (smith, vis) in [(false, Visibility::None), (true, Visibility::Smith)] {
            for (ti, to, po) in [(0.0, 0.0, 0.0), (30.0, 45.0, 180.0), (60.0, 20.0, 90.0)] {
                let (i, o) = (dir(ti, 0.0), dir(to, po));
                let a = stratified_microfacet(&lobes, 64, smith, &transfer, i, o);
                let b = microfacet(&core, &transfer, vis, i, o)[0];
                assert!(
                    rel(a, b) < 0.01,
                    "Smith {smith} θi {ti} θo {to}: {a} vs core {b}"
                );
            }
        }
    }
}
