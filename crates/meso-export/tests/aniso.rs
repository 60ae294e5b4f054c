//! Checks of the anisotropic export (`Inputs::anisotropic`, `meso export --anisotropic`) against
//! independent truth: height maps of parallel grooves whose direction is known (axis-aligned and
//! rotated 45°, 8- and 16-bit PNGs read through meso's own loader), an isotropic Gaussian random
//! surface, the written KTX2/PNG files read back with the independent `ktx2` and `image` crates
//! and decoded by the KHR_materials_anisotropy rules written out here, and bad inputs.
//!
//! `cargo test --release -p meso-export --test aniso -- --nocapture` prints the measured
//! numbers quoted in docs/export.md.

use glam::DVec3;
use meso_export::export::{self, Inputs, Roughness};
use meso_export::MipLevel;
use meso_maps::{Border, HeightMap};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// A fresh, empty scratch folder under the system temp dir.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-aniso-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const N: usize = 64;

/// Write heights in `[0, 1]` given in **map order** (row 0 = y = 0 = the image's bottom row) as a
/// grey PNG of `bits` (8 or 16) bits, top row first.
fn write_png(path: &Path, heights: &[f64], bits: u32) {
    let code = |v: f64, max: f64| (v.clamp(0.0, 1.0) * max).round();
    if bits == 16 {
        let mut img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(N as u32, N as u32);
        for r in 0..N {
            for c in 0..N {
                let v = heights[(N - 1 - r) * N + c];
                img.put_pixel(c as u32, r as u32, image::Luma([code(v, 65535.0) as u16]));
            }
        }
        img.save(path).unwrap();
    } else {
        let mut img = image::GrayImage::new(N as u32, N as u32);
        for r in 0..N {
            for c in 0..N {
                let v = heights[(N - 1 - r) * N + c];
                img.put_pixel(c as u32, r as u32, image::Luma([code(v, 255.0) as u8]));
            }
        }
        img.save(path).unwrap();
    }
}

/// Parallel sinusoidal grooves `h = 0.5 + 0.4 sin(2π (m_x x + m_y y)/N)` (map coordinates, y up
/// the image): the slopes, hence the wide direction of the lobes, lie along `(m_x, m_y)`.
fn grooves(mx: f64, my: f64) -> Vec<f64> {
    (0..N * N)
        .map(|k| {
            let (y, x) = ((k / N) as f64, (k % N) as f64);
            0.5 + 0.4 * (2.0 * PI * (mx * x + my * y) / N as f64).sin()
        })
        .collect()
}

/// An isotropic Gaussian random surface: white noise (a fixed LCG, Box–Muller) blurred by a
/// periodic Gaussian of σ = 2 texels, scaled to `0.5 ± 0.15` (3 σ), periodic like the map.
fn gaussian_surface() -> Vec<f64> {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut u = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let noise: Vec<f64> = (0..N * N)
        .map(|_| (-2.0 * u().ln()).sqrt() * (2.0 * PI * u()).cos())
        .collect();
    let sigma: f64 = 2.0;
    let kern: Vec<f64> = (-8i32..=8)
        .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let blur = |src: &[f64], along_x: bool| -> Vec<f64> {
        (0..N * N)
            .map(|k| {
                let (i, j) = ((k / N) as i32, (k % N) as i32);
                kern.iter()
                    .enumerate()
                    .map(|(t, w)| {
                        let d = t as i32 - 8;
                        let (ii, jj) = if along_x { (i, j + d) } else { (i + d, j) };
                        w * src[(ii.rem_euclid(N as i32) * N as i32 + jj.rem_euclid(N as i32))
                            as usize]
                    })
                    .sum()
            })
            .collect()
    };
    let h = blur(&blur(&noise, true), false);
    let mean = h.iter().sum::<f64>() / h.len() as f64;
    let sd = (h.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / h.len() as f64).sqrt();
    h.iter().map(|v| 0.5 + 0.05 * (v - mean) / sd).collect()
}

/// Load a PNG height map the way `meso export` does and build the anisotropic export in memory.
fn export_png(path: &Path, height_scale: f64, alpha: f64) -> export::Export {
    let map = HeightMap::load(path, 1.0, height_scale, Border::Wrap).unwrap();
    let mut inputs = Inputs::from_heightmap(&map, alpha);
    inputs.anisotropic = true;
    export::build(&inputs).unwrap()
}

/// Smallest angle between two axes (radians, mod π), in degrees.
fn axis_diff_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Per level: `(aniso mean error %, iso mean error %, mean α_t/α_b, worst direction error °
/// over anisotropic texels, share of texels with α_t/α_b > 1.5)`.
fn level_numbers(l: &MipLevel, truth: f64) -> (f64, f64, f64, f64, f64) {
    let a = l.aniso.as_ref().unwrap();
    let ratios: Vec<f64> = a
        .alpha_t
        .iter()
        .zip(&l.alphas)
        .map(|(t, b)| t / b)
        .collect();
    let mut worst: f64 = 0.0;
    let mut aniso = 0;
    for (k, &r) in ratios.iter().enumerate() {
        if r > 1.5 {
            aniso += 1;
            worst = worst.max(axis_diff_deg(a.angles[k], truth));
        }
    }
    (
        100.0 * mean(&l.errors),
        100.0 * mean(&a.errors_iso),
        mean(&ratios),
        worst,
        aniso as f64 / ratios.len() as f64,
    )
}

/// Parallel sinusoidal grooves along x, rotated 45° and 20.6° (frequency (8, 3): off the fit's
/// direction set), from 16- and 8-bit PNGs: at every
/// coarse level the fitted direction is the grooves' slope direction within 2°, every texel of
/// a footprint of a period or more is anisotropic (`α_t/α_b > 1.5`), and the anisotropic lobe's BRDF error is below `bound` × the isotropic
/// fit's on the same direction set: 0.7 for grooves of slope amplitude 0.094 (H = 0.3, about
/// 2 α₀), 0.9 for steep ones (0.31, H = 1), whose averaged lobe is two separate peaks at the
/// extreme slopes that no single lobe can take.
#[test]
fn grooves_give_their_direction_and_beat_the_isotropic_fit() {
    let dir = scratch("grooves");
    let cases = [
        (8.0, 0.0, 16, 0.3, 0.7),
        (8.0, 0.0, 8, 0.3, 0.7),
        (8.0, 8.0, 16, 0.3, 0.7),
        (8.0, 8.0, 8, 0.3, 0.7),
        (8.0, 3.0, 16, 0.3, 0.7),
        (8.0, 0.0, 16, 1.0, 0.9),
    ];
    for &(mx, my, bits, hs, bound) in &cases {
        let truth = f64::atan2(my, mx);
        let name = format!("{:.0}°, {bits}-bit, H = {hs}", truth.to_degrees());
        let path = dir.join(format!("grooves-{mx}-{my}-{bits}-{hs}.png"));
        write_png(&path, &grooves(mx, my), bits);
        let ex = export_png(&path, hs, 0.05);
        println!("grooves {name} (α₀ = 0.05):");
        println!("level  size   aniso err %  iso err %  mean α_t/α_b  worst Δψ °  anisotropic");
        for (k, l) in ex.levels.iter().enumerate().skip(1) {
            let (ea, ei, ratio, worst, share) = level_numbers(l, truth);
            println!(
                "{k:>5}  {:>2}²   {ea:>10.2}  {ei:>9.2}  {ratio:>12.2}  {worst:>10.2}  {:>10.0} %",
                l.width,
                100.0 * share
            );
            assert!(worst < 2.0, "{name} level {k}: direction off by {worst}°");
            if k >= 2 {
                assert!(ea < bound * ei, "{name} level {k}: {ea} % vs iso {ei} %");
            }
            // Footprints of at least a period (7.5 texels at 20.6°): every texel anisotropic.
            if k >= 3 {
                assert!(share > 0.99, "{name} level {k}: {share} anisotropic");
            }
            // Never worse than isotropic, texel by texel.
            let a = l.aniso.as_ref().unwrap();
            assert!(l.errors.iter().zip(&a.errors_iso).all(|(x, y)| x <= y));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An isotropic Gaussian random surface: where a texel covers many correlation lengths
/// (footprints of 16² texels and more) the fitted lobe is nearly isotropic (mean α_t/α_b < 1.15,
/// strength small) and its error no worse than the isotropic fit's.
#[test]
fn isotropic_random_surface_stays_isotropic() {
    let dir = scratch("gaussian");
    let path = dir.join("gaussian.png");
    write_png(&path, &gaussian_surface(), 16);
    let ex = export_png(&path, 1.0, 0.05);
    println!("isotropic Gaussian surface (σ = 2 texels, H = 1, α₀ = 0.05):");
    println!("level  size   aniso err %  iso err %  mean α_t/α_b  mean strength");
    for (k, l) in ex.levels.iter().enumerate().skip(1) {
        let (ea, ei, ratio, _, _) = level_numbers(l, 0.0);
        let s = ex.stats[k].aniso.unwrap().mean_strength;
        println!(
            "{k:>5}  {:>2}²   {ea:>10.2}  {ei:>9.2}  {ratio:>12.3}  {s:>13.3}",
            l.width
        );
        assert!(ea <= ei + 1e-12, "level {k}: aniso {ea} % > iso {ei} %");
        if k >= 4 {
            assert!(ratio < 1.15, "level {k}: mean α_t/α_b = {ratio}");
            assert!(s < 0.25, "level {k}: mean strength {s}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The written anisotropy chain decoded by rules written out here (KHR_materials_anisotropy:
/// direction = RG·2 − 1, strength = B, `α_t = mix(α_b, 1, s²)`, `α_b = G_mr²`) from files read
/// by the independent `ktx2` crate gives the fitted values within 8-bit quantisation; the PNG
/// levels hold the same texels; the glTF material carries the extension.
#[test]
fn written_anisotropy_decodes_to_the_fitted_values() {
    let dir = scratch("roundtrip");
    let path = dir.join("grooves.png");
    write_png(&path, &grooves(8.0, 8.0), 16);
    let ex = export_png(&path, 1.0, 0.05);
    let out = dir.join("out");
    export::write(&ex, &out, &[]).unwrap();
    let read = |name: &str| -> Vec<Vec<u8>> {
        let bytes = std::fs::read(out.join(name)).unwrap();
        let r = ::ktx2::Reader::new(&bytes[..]).expect("ktx2 crate parses the file");
        assert_eq!(r.header().format, Some(::ktx2::Format::R8G8B8A8_UNORM));
        assert_eq!(r.header().level_count as usize, ex.levels.len());
        r.levels().map(|l| l.data.to_vec()).collect()
    };
    let an = read(export::ANISOTROPY_KTX2);
    let mr = read(export::ROUGHNESS_KTX2);
    let q = 0.5 / 255.0;
    let (mut worst_t, mut worst_b, mut worst_psi) = (0.0f64, 0.0f64, 0.0f64);
    for (k, l) in ex.levels.iter().enumerate() {
        let a = l.aniso.as_ref().unwrap();
        let png = image::open(out.join(export::anisotropy_png(k)))
            .unwrap()
            .to_rgb8();
        let rgb: Vec<u8> = an[k].chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        assert_eq!(png.as_raw(), &rgb, "PNG level {k}");
        for r in 0..l.height {
            for c in 0..l.width {
                let px = (r * l.width + c) * 4;
                let m = (l.height - 1 - r) * l.width + c; // image row r = map row H−1−r
                let (at, ab, psi) = (a.alpha_t[m], l.alphas[m], a.angles[m]);
                let rough = mr[k][px + 1] as f64 / 255.0;
                let ab_dec = rough * rough;
                let s = an[k][px + 2] as f64 / 255.0;
                let at_dec = ab_dec * (1.0 - s * s) + s * s;
                // Bounds from ±½ code in √α_b and in s.
                let rb = ab.sqrt();
                let db = (rb + q).powi(2) - rb * rb + 1e-12;
                let s_fit = ((at - ab) / (1.0 - ab)).max(0.0).sqrt();
                let dt = db + (1.0 - ab) * (2.0 * s_fit * q + q * q) + 1e-12;
                assert!((ab_dec - ab).abs() <= db, "level {k}: α_b {ab} → {ab_dec}");
                assert!((at_dec - at).abs() <= dt, "level {k}: α_t {at} → {at_dec}");
                worst_b = worst_b.max((ab_dec - ab).abs());
                worst_t = worst_t.max((at_dec - at).abs());
                let x = an[k][px] as f64 / 255.0 * 2.0 - 1.0;
                let y = an[k][px + 1] as f64 / 255.0 * 2.0 - 1.0;
                if at > ab {
                    let d = axis_diff_deg(y.atan2(x), psi);
                    assert!(d < 0.5, "level {k}: direction {psi} off by {d}°");
                    worst_psi = worst_psi.max(d);
                } else {
                    assert_eq!(an[k][px + 2], 0, "isotropic texel with strength");
                }
                assert_eq!(an[k][px + 3], 255);
            }
        }
    }
    println!(
        "decoded vs fitted: |Δα_t| ≤ {worst_t:.4}, |Δα_b| ≤ {worst_b:.4}, |Δψ| ≤ {worst_psi:.3}°"
    );
    // Level 0 is the isotropic input: strength 0 everywhere.
    assert!(an[0].chunks(4).all(|p| p[2] == 0));
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join(export::GLTF)).unwrap()).unwrap();
    assert_eq!(doc["extensionsUsed"][0], "KHR_materials_anisotropy");
    let ext = &doc["materials"][0]["extensions"]["KHR_materials_anisotropy"];
    assert_eq!(ext["anisotropyStrength"], 1.0);
    assert_eq!(ext["anisotropyRotation"], 0.0);
    let t = ext["anisotropyTexture"]["index"].as_u64().unwrap() as usize;
    let img = doc["textures"][t]["source"].as_u64().unwrap() as usize;
    assert_eq!(
        doc["images"][img]["uri"],
        export::anisotropy_png(0).as_str()
    );
    // Every mesh primitive carries TANGENT (the direction needs a frame).
    for m in doc["meshes"].as_array().unwrap() {
        assert!(m["primitives"][0]["attributes"]["TANGENT"].is_u64());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The isotropic default writes no anisotropy files and no extension, and its roughness chain
/// is the plain α fit of `mips::build_level`.
#[test]
fn the_isotropic_default_is_untouched() {
    let heights = grooves(8.0, 0.0);
    let map = HeightMap::from_heights(N, N, heights, 1.0, Border::Wrap).unwrap();
    let inputs = Inputs::from_heightmap(&map, 0.05);
    assert!(!inputs.anisotropic);
    let ex = export::build(&inputs).unwrap();
    assert!(ex.files.iter().all(|(n, _)| !n.starts_with("anisotropy")));
    assert!(ex.levels.iter().all(|l| l.aniso.is_none()));
    let gltf = &ex.files.iter().find(|(n, _)| n == export::GLTF).unwrap().1;
    assert!(!String::from_utf8_lossy(gltf).contains("anisotropy"));
    // The isotropic chain is the plain α fit, level by level.
    let base = meso_export::BaseMaps::new(N, N, inputs.normals.clone(), vec![0.05; N * N]).unwrap();
    let l3 = meso_export::mips::build_level(&base, 3);
    assert_eq!(l3.alphas, ex.levels[3].alphas);
}

/// Where the option cannot apply, a clear error: a 1 × 1 map has no coarser level.
#[test]
fn anisotropic_export_of_a_single_texel_is_refused() {
    let mut inputs = Inputs {
        width: 1,
        height: 1,
        normals: vec![DVec3::Z],
        roughness: Roughness::Alpha(0.1),
        metallic: 0.0,
        base_color: None,
        base_color_factor: [1.0; 4],
        anisotropic: true,
    };
    let e = export::build(&inputs).unwrap_err().to_string();
    assert!(e.contains("1 × 1") && e.contains("anisotropic"), "{e}");
    inputs.anisotropic = false;
    assert!(export::build(&inputs).is_ok());
}

/// A 64² crop (map rows 192–255, columns 0–63) of the real facade height map
/// (`crates/meso-maps/tests/data/facade_disp_256.png`, ambientCG Facade005, CC0) at S = 1,
/// H = 3: the map rows `meso export crop64.png --texel-size 1 --height-scale 3` reads from the
/// image's top-left 64 × 64 pixels.
fn facade_crop() -> HeightMap {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../meso-maps/tests/data/facade_disp_256.png");
    let full = HeightMap::load(&path, 1.0, 3.0, Border::Wrap).unwrap();
    let (w, h) = (full.width(), full.height());
    assert_eq!((w, h), (256, 256));
    let mut v = Vec::with_capacity(N * N);
    for i in h - N..h {
        for j in 0..N {
            v.push(full.at(i as isize, j as isize));
        }
    }
    HeightMap::from_heights(N, N, v, 1.0, Border::Wrap).unwrap()
}

/// A filtered NDF (the base lobes spread by the footprint's normals) is nowhere narrower than
/// the narrowest base lobe it averages: on a real texture crop every coarse texel's `α_t` and
/// `α_b` are at least the base α (0.05), and with a varying roughness map at least the smallest
/// base α of the texels the footprint covers (2ᵏ × 2ᵏ level-0 texels at level k, written out
/// here). Before the bound, `α_b` went down to ≈ 0.028 on this crop (`meso export` of the same
/// crop: 6 % of level 1 and 50 % of level 2 below 0.045).
#[test]
fn anisotropic_widths_are_never_below_the_base_alpha() {
    let map = facade_crop();
    let mut inputs = Inputs::from_heightmap(&map, 0.05);
    inputs.anisotropic = true;
    let ex = export::build(&inputs).unwrap();
    let mut lowest = f64::INFINITY;
    for (k, l) in ex.levels.iter().enumerate() {
        let a = l.aniso.as_ref().unwrap();
        for (t, (&ab, &at)) in l.alphas.iter().zip(&a.alpha_t).enumerate() {
            assert!(
                ab >= 0.05 - 1e-12 && at >= ab,
                "level {k} texel {t}: α_b {ab}, α_t {at}"
            );
            lowest = lowest.min(ab);
        }
    }
    println!("facade crop, α = 0.05: lowest α_b over levels 1–6 = {lowest:.5}");
    // A varying roughness map: α from 0.02 to 0.12 in a pattern that does not follow the levels.
    let alphas: Vec<f64> = (0..N * N)
        .map(|t| 0.02 + 0.025 * ((t / N * 7 + t % N * 3) % 5) as f64)
        .collect();
    inputs.roughness = Roughness::Map(alphas.clone());
    let ex = export::build(&inputs).unwrap();
    for (k, l) in ex.levels.iter().enumerate().skip(1) {
        let a = l.aniso.as_ref().unwrap();
        let (wk, side) = (l.width, 1usize << k);
        for (t, (&ab, &at)) in l.alphas.iter().zip(&a.alpha_t).enumerate() {
            let (r, c) = (t / wk, t % wk);
            let floor = (r * side..(r + 1) * side)
                .flat_map(|i| (c * side..(c + 1) * side).map(move |j| i * N + j))
                .map(|i| alphas[i])
                .fold(f64::INFINITY, f64::min);
            assert!(
                ab >= floor - 1e-12 && at >= ab,
                "level {k} texel {t}: α_b {ab} below the footprint's base {floor}"
            );
        }
    }
}
