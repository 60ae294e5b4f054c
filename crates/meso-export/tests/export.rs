//! Checks of the exporter against independent truth: brute-force BRDF averaging, the `ktx2`
//! crate's reader, PNG decoding, and all-or-nothing writing.

use glam::DVec3;
use meso_export::export::{self, Inputs, Roughness};
use meso_export::{ggx, ktx2, mips};
use std::f64::consts::PI;
use std::path::PathBuf;

/// A fresh, empty scratch folder under the system temp dir.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-export-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// GGX written out independently of `meso_export::ggx`: D in the slope form
/// `1 / (π α² cos⁴θ (1 + tan²θ/α²)²)`, Smith's G₂ from `Λ = (√(1 + α² tan²θ) − 1)/2`.
fn shaded_ref(n: DVec3, a: f64, l: DVec3, v: DVec3) -> f64 {
    let (nl, nv) = (n.dot(l), n.dot(v));
    if nl <= 0.0 || nv <= 0.0 {
        return 0.0;
    }
    let h = (l + v).normalize();
    let c = n.dot(h);
    if c <= 0.0 {
        return 0.0;
    }
    let tan2 = (1.0 - c * c) / (c * c);
    let d = 1.0 / (PI * a * a * c.powi(4) * (1.0 + tan2 / (a * a)).powi(2));
    let lam = |x: f64| ((1.0 + a * a * (1.0 - x * x) / (x * x)).sqrt() - 1.0) / 2.0;
    d / (1.0 + lam(nl) + lam(nv)) / (4.0 * nv)
}

/// A dense set of (l, v) pairs over the upper hemisphere (both above z = 0.05).
fn dense_pairs() -> Vec<(DVec3, DVec3)> {
    let dirs: Vec<DVec3> = (0..14)
        .flat_map(|i| {
            let th = (i as f64 + 0.5) / 14.0 * 1.5;
            let np = 1 + (28.0 * th.sin()) as usize;
            (0..np).map(move |j| {
                let ph = (j as f64) / np as f64 * 2.0 * PI;
                DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())
            })
        })
        .collect();
    let mut p = Vec::new();
    for &l in &dirs {
        for &v in &dirs {
            p.push((l, v));
        }
    }
    p
}

/// A 2 × 2 level made of two known GGX normals (tilted ±θ about y, α₀ = 0.1): the exporter's
/// level-1 α and normal against brute force — the fine lobes averaged on a dense hemisphere of
/// direction pairs with an independent GGX, and α found by scanning 2000 values.
#[test]
fn two_known_normals_against_brute_force() {
    let a0 = 0.1;
    for &tilt_deg in &[5.0_f64, 10.0, 20.0] {
        let t = tilt_deg.to_radians();
        let n1 = DVec3::new(t.sin(), 0.0, t.cos());
        let n2 = DVec3::new(-t.sin(), 0.0, t.cos());
        let normals = vec![n1, n2, n2, n1];
        let inputs = Inputs {
            width: 2,
            height: 2,
            normals: normals.clone(),
            roughness: Roughness::Alpha(a0),
            metallic: 0.0,
            base_color: None,
            base_color_factor: [1.0; 4],
            anisotropic: false,
        };
        let ex = export::build(&inputs).unwrap();
        let l1 = &ex.levels[1];
        assert_eq!((l1.width, l1.height), (1, 1));
        // Renormalised average normal: +z exactly.
        assert!((l1.normals[0] - DVec3::Z).length() < 1e-12);
        let fitted = l1.alphas[0];

        // Brute force on the dense set, restricted to the fitted lobe's neighbourhood weighting
        // nothing: plain RMS over all pairs.
        let pairs = dense_pairs();
        let target: Vec<f64> = pairs
            .iter()
            .map(|&(l, v)| {
                normals
                    .iter()
                    .map(|&n| shaded_ref(n, a0, l, v))
                    .sum::<f64>()
                    / 4.0
            })
            .collect();
        let err = |a: f64| -> f64 {
            target
                .iter()
                .zip(&pairs)
                .map(|(t, &(l, v))| (t - shaded_ref(DVec3::Z, a, l, v)).powi(2))
                .sum::<f64>()
        };
        let (best, _) = (0..2000)
            .map(|k| 0.01 * (100.0_f64).powf(k as f64 / 1999.0))
            .map(|a| (a, err(a)))
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .unwrap();
        eprintln!("tilt {tilt_deg}°: fitted α = {fitted:.4}, brute force α = {best:.4}");
        assert!(fitted > a0, "the lost variance must widen the lobe");
        // Small tilts (a lobe-like average): the same α within 3%. At 20° the average has two
        // separate peaks and the two direction sets weigh them differently; the error
        // landscape is flat there, so compare the dense-set error instead (within 5%).
        let excess = err(fitted) / err(best) - 1.0;
        eprintln!(
            "  dense-set error of the fitted α exceeds the brute-force minimum by {:.2}%",
            100.0 * excess
        );
        if tilt_deg <= 10.0 {
            assert!(
                (fitted / best - 1.0).abs() < 0.03,
                "tilt {tilt_deg}°: fitted α {fitted} vs brute force {best}"
            );
        }
        assert!(excess < 0.05, "tilt {tilt_deg}°: {excess}");
        // The fitted lobe beats the standard mip (α₀ about the average normal) on the dense set.
        assert!(err(fitted) < err(a0));
    }
}

/// The exporter's GGX agrees with the independent one.
#[test]
fn ggx_matches_the_independent_formula() {
    let n = DVec3::new(0.1, -0.2, 1.0).normalize();
    for (l, v) in dense_pairs().into_iter().step_by(97) {
        for &a in &[0.02, 0.3, 0.9] {
            let (x, y) = (ggx::shaded(n, a, l, v), shaded_ref(n, a, l, v));
            assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "{x} vs {y}");
        }
    }
}

/// Wider spreads give wider lobes; a flat map keeps α₀ at every level with zero error.
#[test]
fn alpha_grows_with_the_lost_variance_and_flat_maps_keep_alpha() {
    let mut prev = 0.0;
    for &tilt in &[2.0_f64, 8.0, 16.0, 30.0] {
        let t = tilt.to_radians();
        let fine = [1.0, -1.0].map(|s| ggx::FineTexel {
            normal: DVec3::new(s * t.sin(), 0.0, t.cos()),
            alpha: 0.05,
        });
        let a = ggx::fit_alpha(&fine, DVec3::Z).alpha;
        assert!(a > prev, "tilt {tilt}: α {a} ≤ {prev}");
        prev = a;
    }
    let w = 16;
    let ex = export::build(&Inputs {
        width: w,
        height: w,
        normals: vec![DVec3::Z; w * w],
        roughness: Roughness::Alpha(0.2),
        metallic: 0.0,
        base_color: None,
        base_color_factor: [1.0; 4],
        anisotropic: false,
    })
    .unwrap();
    assert_eq!(ex.levels.len(), 5);
    for l in &ex.levels {
        assert!(l.alphas.iter().all(|a| (a - 0.2).abs() < 1e-6));
        assert!(l.errors.iter().all(|e| *e < 1e-6));
    }
}

fn bumpy(w: usize, h: usize) -> Vec<DVec3> {
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            DVec3::new(0.5 * (x * 0.9).sin(), 0.3 * (y * 1.3 + x * 0.2).cos(), 1.0).normalize()
        })
        .collect()
}

/// A full export: KTX2 files read back by our reader **and** the independent `ktx2` crate,
/// level bytes equal to the inspection PNGs (decoded by `image`), and the glTF's references.
#[test]
fn export_round_trip_through_independent_readers() {
    let (w, h) = (16, 8);
    let dir = scratch("roundtrip");
    let ex = export::build(&Inputs {
        width: w,
        height: h,
        normals: bumpy(w, h),
        roughness: Roughness::Alpha(0.09),
        metallic: 0.5,
        base_color: None,
        base_color_factor: [0.5, 0.5, 0.5, 1.0],
        anisotropic: false,
    })
    .unwrap();
    export::write(&ex, &dir, &[]).unwrap();
    for name in [export::NORMAL_KTX2, export::ROUGHNESS_KTX2] {
        let bytes = std::fs::read(dir.join(name)).unwrap();
        let own = ktx2::read(&bytes).unwrap();
        let other = ::ktx2::Reader::new(&bytes[..]).expect("ktx2 crate parses the file");
        let hd = other.header();
        assert_eq!(hd.format, Some(::ktx2::Format::R8G8B8A8_UNORM));
        assert_eq!((hd.pixel_width, hd.pixel_height), (w as u32, h as u32));
        assert_eq!(hd.level_count, 5);
        assert_eq!(hd.supercompression_scheme, None);
        assert_eq!(
            other.transfer_function(),
            Some(::ktx2::TransferFunction::Linear)
        );
        // The value is stored NUL-terminated, as the spec asks; the crate hands the NUL back.
        assert_eq!(other.writer(), Some("meso export 0.1.0\0"));
        for (k, (a, b)) in own.levels.iter().zip(other.levels()).enumerate() {
            assert_eq!(a.data, b.data, "level {k}");
            // The inspection PNG holds the same texels (RGB of the RGBA level).
            let png_name = if name == export::NORMAL_KTX2 {
                export::normal_png(k)
            } else {
                export::roughness_png(k)
            };
            let png = image::open(dir.join(png_name)).unwrap().to_rgb8();
            assert_eq!((png.width(), png.height()), (a.width, a.height));
            let rgb: Vec<u8> = a.data.chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
            assert_eq!(png.as_raw(), &rgb, "{name} level {k}");
            if name == export::ROUGHNESS_KTX2 {
                let grey = image::open(dir.join(export::roughness_grey_png(k)))
                    .unwrap()
                    .to_luma8();
                let g: Vec<u8> = a.data.chunks(4).map(|p| p[1]).collect();
                assert_eq!(grey.as_raw(), &g, "grey roughness level {k}");
            }
        }
        // Level 0 of the normal map: decoded texels are the input normals, image row order.
        if name == export::NORMAL_KTX2 {
            let n = bumpy(w, h);
            let d = &own.levels[0].data;
            for r in 0..h {
                for c in 0..w {
                    let px = &d[(r * w + c) * 4..][..3];
                    let m = n[(h - 1 - r) * w + c];
                    let dec = DVec3::new(
                        px[0] as f64 / 127.5 - 1.0,
                        px[1] as f64 / 127.5 - 1.0,
                        px[2] as f64 / 127.5 - 1.0,
                    );
                    assert!((dec - m).length() < 0.01, "texel ({r}, {c})");
                }
            }
        } else {
            // B = metallic 0.5, G = √α = 0.3 at level 0.
            assert!(own.levels[0]
                .data
                .chunks(4)
                .all(|p| p == [255, 77, 128, 255]));
        }
    }
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join(export::GLTF)).unwrap()).unwrap();
    for img in doc["images"].as_array().unwrap() {
        assert!(dir.join(img["uri"].as_str().unwrap()).is_file());
    }
    let bin_len = std::fs::metadata(dir.join(export::GLTF_BIN)).unwrap().len();
    assert_eq!(doc["buffers"][0]["byteLength"].as_u64(), Some(bin_len));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Bad inputs fail with clear errors; an unwritable target leaves no partial files.
#[test]
fn bad_inputs_and_unwritable_targets() {
    let mut inputs = Inputs {
        width: 0,
        height: 0,
        normals: vec![],
        roughness: Roughness::Alpha(0.1),
        metallic: 0.0,
        base_color: None,
        base_color_factor: [1.0; 4],
        anisotropic: false,
    };
    let e = export::build(&inputs).unwrap_err().to_string();
    assert!(e.contains("0 × 0"), "{e}");
    inputs.width = 4;
    inputs.height = 4;
    inputs.normals = vec![DVec3::Z; 16];
    inputs.roughness = Roughness::Alpha(0.0);
    assert!(export::build(&inputs)
        .unwrap_err()
        .to_string()
        .contains("GGX width"));
    inputs.roughness = Roughness::Map(vec![0.1; 15]);
    assert!(export::build(&inputs).is_err());
    inputs.roughness = Roughness::Alpha(0.1);
    let ex = export::build(&inputs).unwrap();

    // A target below a regular file.
    let dir = scratch("unwritable");
    let file = dir.join("plain-file");
    std::fs::write(&file, b"x").unwrap();
    let e = export::write(&ex, &file.join("out"), &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("plain-file"), "{e}");

    // The last file cannot be written (a non-empty folder of that name): none is put in place,
    // the folder holds exactly what it held before.
    let out = dir.join("out");
    let blocker = out.join(export::ERRORS_CSV);
    std::fs::create_dir_all(blocker.join("x")).unwrap();
    let e = export::write(&ex, &out, &[]).unwrap_err().to_string();
    assert!(e.contains(export::ERRORS_CSV), "{e}");
    let left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, vec![std::ffi::OsString::from(export::ERRORS_CSV)]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The fit error of a real-ish surface falls well below the standard mip's at coarse levels.
#[test]
fn fitted_chain_beats_the_standard_mip() {
    let (w, h) = (32, 32);
    let base = mips::BaseMaps::new(w, h, bumpy(w, h), vec![0.04; w * h]).unwrap();
    let chain = mips::build_chain(&base);
    for (k, l) in chain.iter().enumerate().skip(1) {
        let s = l.stats(k);
        eprintln!(
            "level {k}: mean α {:.4}, error {:.2}% (max {:.2}%), standard mip {:.2}%",
            s.mean_alpha, s.mean_error_pct, s.max_error_pct, s.mean_plain_error_pct
        );
        assert!(s.mean_error_pct < s.mean_plain_error_pct);
        assert!(s.mean_alpha > 0.04);
    }
}

/// Roughness maps: grey r → α = r² in map row order; a colour map takes G with a warning; a
/// size mismatch, an empty file and a 16-bit base colour are reported.
#[test]
fn roughness_and_base_color_loading() {
    let dir = scratch("loading");
    // 2 × 2 grey: image top row (map row 1) = 51, 102; bottom row (map row 0) = 153, 204.
    let grey = image::GrayImage::from_raw(2, 2, vec![51, 102, 153, 204]).unwrap();
    grey.save(dir.join("r.png")).unwrap();
    let (a, w) = export::load_roughness(&dir.join("r.png"), 2, 2).unwrap();
    assert!(w.is_empty());
    let want = [0.6_f64, 0.8, 0.2, 0.4].map(|r| r * r);
    for (x, y) in a.iter().zip(want) {
        assert!((x - y).abs() < 1e-6, "{x} vs {y}");
    }
    let rgb = image::RgbImage::from_raw(1, 1, vec![10, 51, 200]).unwrap();
    rgb.save(dir.join("mr.png")).unwrap();
    let (a, w) = export::load_roughness(&dir.join("mr.png"), 1, 1).unwrap();
    assert!((a[0] - 0.04).abs() < 1e-6 && w.len() == 1 && w[0].contains("green"));
    let e = export::load_roughness(&dir.join("r.png"), 4, 4)
        .unwrap_err()
        .to_string();
    assert!(e.contains("2 × 2") && e.contains("4 × 4"), "{e}");
    std::fs::write(dir.join("empty.png"), b"").unwrap();
    assert!(export::load_roughness(&dir.join("empty.png"), 1, 1).is_err());
    let deep =
        image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(1, 1, vec![65535u16, 0, 0]).unwrap();
    deep.save(dir.join("c16.png")).unwrap();
    let (bc, w) = export::load_base_color(&dir.join("c16.png")).unwrap();
    assert!(w.len() == 1 && w[0].contains("8-bit"), "{w:?}");
    let back = image::load_from_memory(&bc.png).unwrap().to_rgba8();
    assert_eq!(back.as_raw(), &vec![255, 0, 0, 255]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Writing is all or nothing and loses nothing of the user's: with a directory in the way of
/// the last file, the export fails naming it, an earlier export's files in the folder keep
/// their bytes, and no temporary file is left.
#[test]
fn a_failed_write_leaves_the_folder_as_it_was() {
    let (w, h) = (8, 8);
    let ex = export::build(&Inputs {
        width: w,
        height: h,
        normals: bumpy(w, h),
        ..Inputs::uniform(0.1, 0.0, [0.5, 0.5, 0.5])
    })
    .unwrap();
    let names: Vec<&str> = ex.files.iter().map(|(n, _)| n.as_str()).collect();
    let (first, last) = (names[0], *names.last().unwrap());
    assert_ne!(first, last);
    // An earlier export's first file, and a non-empty directory where the last file goes.
    let dir = scratch("failed-write");
    std::fs::write(dir.join(first), b"the user's earlier file").unwrap();
    std::fs::create_dir_all(dir.join(last).join("inside")).unwrap();
    let e = export::write(&ex, &dir, &[]).unwrap_err().to_string();
    assert!(e.contains(last), "{e}");
    assert_eq!(
        std::fs::read(dir.join(first)).unwrap(),
        b"the user's earlier file"
    );
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    let mut expected = vec![first.to_owned(), last.to_owned()];
    expected.sort();
    assert_eq!(left, expected, "only the user's entries remain");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// glTF multiplies `baseColorTexture` by `baseColorFactor`: with a base colour texture the
/// written factor is 1 whatever `Inputs::base_color_factor` holds (the 0.8 grey of the
/// constructors would draw the texture at 80 %); without one it is that factor.
#[test]
fn a_base_color_texture_gets_factor_one() {
    let map = meso_maps::NormalMap::from_normals(2, 2, vec![DVec3::Z; 4]).unwrap();
    let mut inputs = Inputs::from_normal_map(&map, 0.1);
    let factor = |inputs: &Inputs| -> Vec<f64> {
        let ex = export::build(inputs).unwrap();
        let json = &ex.files.iter().find(|(n, _)| n == export::GLTF).unwrap().1;
        let doc: serde_json::Value = serde_json::from_slice(json).unwrap();
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    assert_eq!(factor(&inputs), vec![0.8, 0.8, 0.8, 1.0]);
    let png = meso_export::texture::encode_png(1, 1, 4, &[200, 100, 50, 255]).unwrap();
    inputs.base_color = Some(export::BaseColor { png });
    assert_eq!(factor(&inputs), vec![1.0; 4]);
    assert_eq!(export::base_color_factor(&inputs), [1.0; 4]);
}
