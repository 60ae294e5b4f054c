//! Map format 3 (docs/map-format.md): what the quantisation costs against the `f32` pyramid of
//! format 2 (lobes, horizon statistics and the BRDF of texel materials through the resolver),
//! that format-2 files still read, and that damaged, truncated, oversized or bomb-like files are
//! refused with an error naming the file (never a panic).

use glam::DVec3;
use meso_core::frame::spherical_direction_deg as dir;
use meso_core::material::MaterialSpec;
use meso_maps::format::{SHADING_TAG, VERSION, VERSION_2};
use meso_maps::{extract, fixtures, ExtractParams, MapError, MapsResolver, Pyramid, Source};
use std::path::{Path, PathBuf};

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("map_format_v3");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn pyramid(map: &meso_maps::HeightMap) -> Pyramid {
    let mut p = ExtractParams::default();
    p.fit.max_lobes = 4;
    extract(Source::Heights(map), &p, &mut |_| {}).unwrap()
}

/// The f32 pyramid (as format 2 stores it) and the format-3 one, both read from files.
fn both(name: &str, p: &Pyramid) -> (PathBuf, Pyramid, PathBuf, Pyramid) {
    let f2 = tmp(&format!("{name}.v2.map"));
    let mut v2 = Vec::new();
    p.write_v2_to(&mut v2).unwrap();
    std::fs::write(&f2, &v2).unwrap();
    let f3 = tmp(&format!("{name}.v3.map"));
    p.write(&f3).unwrap();
    let bytes = std::fs::read(&f3).unwrap();
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
        VERSION
    );
    assert!(bytes.len() < v2.len());
    (
        f2.clone(),
        Pyramid::read(&f2).unwrap(),
        f3.clone(),
        Pyramid::read(&f3).unwrap(),
    )
}

#[derive(Default, Debug)]
struct Worst {
    axis_rad: f64,
    weight: f64,
    eta_rel: f64,
    horizon_mean_rad: f64,
    horizon_sd_rad: f64,
}

fn compare(a: &Pyramid, b: &Pyramid, w: &mut Worst) {
    assert_eq!(a.levels.len(), b.levels.len());
    for (la, lb) in a.levels.iter().zip(&b.levels) {
        assert_eq!(la.lobe_start, lb.lobe_start);
        // The NDF residual of the level table (format 2 does not record the shading error).
        let ndf = |r: &meso_maps::pyramid::Residual| (r.mean, r.max, r.texels);
        assert_eq!(ndf(&la.residual), ndf(&lb.residual));
        for (x, y) in la.lobes.iter().zip(&lb.lobes) {
            w.axis_rad = w.axis_rad.max(x.axis.angle_between(y.axis));
            w.weight = w.weight.max((x.weight - y.weight).abs());
            w.eta_rel = w
                .eta_rel
                .max((x.exponent - y.exponent).abs() / x.exponent.max(1e-300));
        }
        for t in 0..la.texels() {
            let ws: f64 = lb
                .lobes
                .range(lb.lobe_start[t] as usize, lb.lobe_start[t + 1] as usize)
                .map(|l| l.weight)
                .sum();
            assert!(
                la.lobe_start[t] == la.lobe_start[t + 1] || (ws - 1.0).abs() < 1e-12,
                "{ws}"
            );
        }
        match (&la.horizon, &lb.horizon) {
            (Some(ha), Some(hb)) => {
                for (x, y) in ha.iter().zip(hb) {
                    assert_eq!(x.weight, y.weight);
                    for d in 0..4 {
                        w.horizon_mean_rad = w.horizon_mean_rad.max((x.mean[d] - y.mean[d]).abs());
                        w.horizon_sd_rad = w
                            .horizon_sd_rad
                            .max((x.var[d].sqrt() - y.var[d].sqrt()).abs());
                    }
                }
            }
            (None, None) => {}
            _ => panic!("horizon statistics lost"),
        }
    }
}

/// The BRDF of texel `(level, row, col)` of the map `file` through `[ndf] kind = "map"`, with
/// a Beckmann facet of roughness `alpha` and the horizon shadowing: at 36 pairs on a grid and
/// at the mirror pairs of each of `axes` (incidence 0° and 30°), where the texel's BRDF peaks.
fn texel_brdf(
    file: &Path,
    level: usize,
    row: usize,
    col: usize,
    alpha: f64,
    axes: &[DVec3],
) -> Vec<f64> {
    let text = format!(
        "[ndf]\nkind = \"map\"\nfile = \"{}\"\nlevel = {level}\ntexel = [{row}, {col}]\n\
         [transfer]\nkind = \"microfacet\"\ndistribution = \"beckmann\"\nalpha = {alpha}\n\
         fresnel = \"none\"\n[shadowing]\nkind = \"horizon\"\n",
        file.file_name().unwrap().to_str().unwrap()
    );
    let m = MaterialSpec::parse(&text, file.parent().unwrap())
        .and_then(|s| s.build(&MapsResolver::new()))
        .unwrap();
    let mut pairs = Vec::new();
    for ti in [0.0, 30.0, 60.0] {
        for to in [0.0, 20.0, 45.0, 60.0] {
            for po in [0.0, 90.0, 180.0] {
                pairs.push((dir(ti, 0.0), dir(to, po)));
            }
        }
    }
    for a in axes {
        for i in [dir(0.0, 0.0), dir(30.0, 0.0)] {
            let o = 2.0 * i.dot(*a) * *a - i;
            if o.z > 0.05 {
                pairs.push((i, o));
            }
        }
    }
    pairs.iter().map(|&(i, o)| m.brdf(i, o)[0]).collect()
}

/// Measured on 2026-12-02 (the bounds below are these figures rounded up): lobe axes within
/// 2.51e-6 rad, weights within 1.13e-5, exponents within 1.08e-4 relative, horizon means and
/// standard deviations within 1.92e-4 and 9.6e-5 rad (half a step of their 12-bit codes); the
/// BRDF of 14 texels (every other level of a Gaussian and a woven map, horizon shadowing) at 36
/// grid pairs and at the mirror pairs of their lobes within 1.90e-3 of its peak (Beckmann
/// α = 0.1) and 1.94e-3 (α = 0.02), the horizon's quantisation the larger part.
#[test]
fn quantisation_moves_lobes_and_brdf_by_the_stated_bounds() {
    let maps = [
        (
            "gaussian",
            fixtures::gaussian(64, 3.0, 0.15, 11, 0.1).unwrap(),
        ),
        ("woven", fixtures::woven(64, 16, 0.1, 0.05).unwrap()),
    ];
    let mut w = Worst::default();
    let mut brdf_worst = [0.0f64; 2];
    for (name, map) in &maps {
        let p = pyramid(map);
        let (f2, p2, f3, p3) = both(name, &p);
        compare(&p2, &p3, &mut w);
        // A read map written again gives the same bytes (the cache and `meso extract` agree).
        assert!(
            p3.to_bytes() == p.to_bytes(),
            "{name}: re-encoding changed the file"
        );
        // Texels of every level: the corner and an inner one.
        for (k, l) in p2.levels.iter().enumerate().step_by(2) {
            for (row, col) in [(0, 0), (l.rows / 2, l.cols / 3)] {
                let axes: Vec<DVec3> = l
                    .texel_lobes(row, col)
                    .unwrap()
                    .iter()
                    .map(|l| l.axis)
                    .collect();
                for (a, alpha) in [0.1, 0.02].into_iter().enumerate() {
                    let b2 = texel_brdf(&f2, k, row, col, alpha, &axes);
                    let b3 = texel_brdf(&f3, k, row, col, alpha, &axes);
                    let peak = b2.iter().copied().fold(0.0, f64::max);
                    assert!(peak > 0.0);
                    for (x, y) in b2.iter().zip(&b3) {
                        brdf_worst[a] = brdf_worst[a].max((x - y).abs() / peak);
                    }
                }
            }
        }
    }
    eprintln!(
        "format 3 against f32: {w:?}; BRDF of peak: α 0.1 {:.2e}, α 0.02 {:.2e}",
        brdf_worst[0], brdf_worst[1]
    );
    assert!(w.axis_rad < 2.6e-6, "{w:?}");
    assert!(w.weight < 1.2e-5, "{w:?}");
    assert!(w.eta_rel < 1.1e-4, "{w:?}");
    assert!(w.horizon_mean_rad < 1.95e-4, "{w:?}");
    assert!(w.horizon_sd_rad < 9.7e-5, "{w:?}");
    assert!(brdf_worst[0] < 2.0e-3, "{brdf_worst:?}");
    assert!(brdf_worst[1] < 2.0e-3, "{brdf_worst:?}");
}

#[test]
fn version_2_files_still_read_and_are_larger() {
    let p = pyramid(&fixtures::v_grooves(32, 8, 0.2, 0.05).unwrap());
    let mut v2 = Vec::new();
    p.write_v2_to(&mut v2).unwrap();
    assert_eq!(u32::from_le_bytes(v2[8..12].try_into().unwrap()), VERSION_2);
    let r2 = Pyramid::from_bytes(Path::new("old.map"), &v2).unwrap();
    assert_eq!(r2.levels.len(), p.levels.len());
    for (a, b) in p.levels.iter().zip(&r2.levels) {
        for (x, y) in a.lobes.iter().zip(&b.lobes) {
            // f32 rounding only
            assert!(x.axis.angle_between(y.axis) < 1e-6);
            assert!((x.weight - y.weight).abs() < 1e-6);
        }
    }
    let v3 = p.to_bytes();
    assert!(v3.len() * 4 < v2.len(), "{} vs {}", v3.len(), v2.len());
    // Trailing bytes after a format-2 file are refused as before.
    let mut t = v2.clone();
    t.push(0);
    let e = Pyramid::from_bytes(Path::new("old.map"), &t).unwrap_err();
    assert!(e.to_string().contains("trailing"), "{e}");
}

/// Offsets of the streams of a format-3 file: (header offset, compressed length). The file
/// ends after them, or after the shading-error trailer (tag and 16 bytes a level).
fn streams(bytes: &[u8], levels: usize) -> Vec<(usize, usize)> {
    let mut pos = 48 + 36 * levels;
    let mut out = Vec::new();
    while pos < bytes.len() && bytes[pos..pos + 4] != SHADING_TAG {
        let comp = u64::from_le_bytes(bytes[pos + 12..pos + 20].try_into().unwrap()) as usize;
        out.push((pos, comp));
        pos += 20 + comp;
    }
    if pos < bytes.len() {
        pos += 4 + 16 * levels;
    }
    assert_eq!(pos, bytes.len());
    out
}

/// Issue #11 item 4: the level table's residuals and each level's shading error read back from
/// a format-3 file exactly; a format-3 file without the shading-error trailer (as written
/// before it existed) still reads, with the shading error not recorded; a truncated trailer is
/// refused.
#[test]
fn shading_error_trailer_round_trips_and_older_files_still_read() {
    let p = pyramid(&fixtures::gaussian(32, 2.0, 0.3, 5, 0.1).unwrap());
    for l in &p.levels {
        let (m, x) = (
            l.residual.shading_mean.unwrap(),
            l.residual.shading_max.unwrap(),
        );
        assert!(m.is_finite() && m >= 0.0 && x >= m && x < 1.0, "{m} {x}");
    }
    assert!(p.top().residual.shading_mean.unwrap() > 0.0);
    let bytes = p.to_bytes();
    let back = Pyramid::from_bytes(Path::new("new.map"), &bytes).unwrap();
    for (a, b) in p.levels.iter().zip(&back.levels) {
        assert_eq!(a.residual, b.residual);
    }
    // The same file without the trailer: an older format-3 file.
    let nlev = p.levels.len();
    let old = &bytes[..bytes.len() - 4 - 16 * nlev];
    assert_eq!(&bytes[old.len()..old.len() + 4], &SHADING_TAG);
    let r = Pyramid::from_bytes(Path::new("old.map"), old).unwrap();
    for (a, b) in back.levels.iter().zip(&r.levels) {
        assert_eq!(
            (a.residual.mean, a.residual.max),
            (b.residual.mean, b.residual.max)
        );
        assert_eq!(
            (b.residual.shading_mean, b.residual.shading_max),
            (None, None)
        );
        assert_eq!(a.lobes, b.lobes);
    }
    assert!(r.info().to_string().contains("not recorded"));
    Pyramid::check_bytes(Path::new("old.map"), old).unwrap();
    let e = Pyramid::from_bytes(Path::new("cut.map"), &bytes[..bytes.len() - 3])
        .unwrap_err()
        .to_string();
    assert!(e.contains("truncated"), "{e}");
}

fn deflate(raw: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(raw).unwrap();
    e.finish().unwrap()
}

/// `bytes` with stream `s`'s compressed data replaced by `comp` (raw length as given).
fn replace_stream(bytes: &[u8], levels: usize, s: usize, raw_len: u64, comp: &[u8]) -> Vec<u8> {
    let (pos, len) = streams(bytes, levels)[s];
    let mut out = bytes[..pos + 4].to_vec();
    out.extend_from_slice(&raw_len.to_le_bytes());
    out.extend_from_slice(&(comp.len() as u64).to_le_bytes());
    out.extend_from_slice(comp);
    out.extend_from_slice(&bytes[pos + 20 + len..]);
    out
}

fn refused(path: &Path, bytes: &[u8], needle: &str) {
    let e = Pyramid::from_bytes(path, bytes).unwrap_err();
    let s = e.to_string();
    assert!(matches!(e, MapError::MapFormat { .. }), "{s}");
    assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
    assert!(s.contains(&path.display().to_string()), "{s}");
}

#[test]
fn damaged_and_bomb_files_are_refused_naming_the_file() {
    let p = pyramid(&fixtures::gaussian(16, 2.0, 0.1, 3, 0.1).unwrap());
    let path = tmp("bad.map");
    p.write(&path).unwrap();
    let good = std::fs::read(&path).unwrap();
    let nlev = p.levels.len();
    let st = streams(&good, nlev);
    assert_eq!(st.len(), 6);
    let texels: usize = p.levels.iter().map(|l| l.texels()).sum();

    // Truncated anywhere, or followed by anything.
    for cut in [0, 47, 48 + 10, st[1].0 + 5, st[3].0 + 30, good.len() - 1] {
        let e = Pyramid::from_bytes(&path, &good[..cut])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("truncated") || e.contains("magic"),
            "cut {cut}: {e}"
        );
    }
    let mut t = good.clone();
    t.extend_from_slice(b"x");
    refused(&path, &t, "trailing");

    // A stream whose header claims more than the level table implies.
    let mut b = good.clone();
    b[st[0].0 + 4..st[0].0 + 12].copy_from_slice(&(texels as u64 + 1).to_le_bytes());
    refused(&path, &b, "the level table implies");

    // A bomb: the claimed size is refused before inflating (deflate cannot expand 1032:1+).
    let (big, lobes_per_texel) = (4096u32, 8u32);
    let mut bomb = Vec::new();
    bomb.extend_from_slice(b"MESOMAP\0");
    for v in [VERSION, big, big, big, big] {
        bomb.extend_from_slice(&v.to_le_bytes());
    }
    bomb.extend_from_slice(&1.0f64.to_le_bytes());
    bomb.extend_from_slice(&[0, 0, 0, 0]);
    let nb = meso_maps::pyramid::level_count(big as usize, big as usize);
    bomb.extend_from_slice(&lobes_per_texel.to_le_bytes());
    bomb.extend_from_slice(&(nb as u32).to_le_bytes());
    let mut n = big;
    let mut total = 0u64;
    for k in 0..nb {
        for v in [n, n, 1 << k, 0] {
            bomb.extend_from_slice(&v.to_le_bytes());
        }
        bomb.extend_from_slice(&[0; 20]);
        total += u64::from(n) * u64::from(n);
        n = n.div_ceil(2);
    }
    let zeros = deflate(&[0u8; 4096]);
    let mut head = vec![0u8, 0, 0, 0];
    head.extend_from_slice(&total.to_le_bytes());
    head.extend_from_slice(&(zeros.len() as u64).to_le_bytes());
    bomb.extend_from_slice(&head);
    bomb.extend_from_slice(&zeros);
    refused(&path, &bomb, "decompression bomb");

    // A stream that inflates to more than its header says is cut at one byte more and refused.
    let counts: Vec<u8> = p
        .levels
        .iter()
        .flat_map(|l| l.lobe_start.windows(2).map(|w| (w[1] - w[0]) as u8))
        .collect();
    let mut more = counts.clone();
    more.extend(std::iter::repeat_n(0u8, 100_000));
    let b = replace_stream(&good, nlev, 0, texels as u64, &deflate(&more));
    refused(&path, &b, "inflates to more than");
    // Fewer bytes, garbage, or bytes after the compressed data.
    let b = replace_stream(&good, nlev, 0, texels as u64, &deflate(&counts[1..]));
    refused(&path, &b, "inflates to");
    let b = replace_stream(&good, nlev, 0, texels as u64, &[0xff; 64]);
    refused(&path, &b, "corrupt compressed data");
    let mut padded = deflate(&counts);
    padded.extend_from_slice(&[0; 3]);
    let b = replace_stream(&good, nlev, 0, texels as u64, &padded);
    refused(&path, &b, "after the end of the compressed data");

    // Out-of-range values: a texel with more lobes than max_lobes, all-zero weights.
    let mut c = counts.clone();
    c[0] = 9;
    let b = replace_stream(&good, nlev, 0, texels as u64, &deflate(&c));
    refused(&path, &b, "lobes");
    let lobes: usize = p.levels.iter().map(|l| l.lobes.len()).sum();
    let b = replace_stream(
        &good,
        nlev,
        2,
        2 * lobes as u64,
        &deflate(&vec![0; 2 * lobes]),
    );
    refused(&path, &b, "weights are all 0");
    let mut hw = vec![0u8; 4 * texels];
    hw[3 * texels] = 0xff; // the top byte plane of the first weight: a negative NaN
    hw[2 * texels] = 0xc0;
    let b = replace_stream(&good, nlev, 4, 4 * texels as u64, &deflate(&hw));
    refused(&path, &b, "horizon weight");

    // No byte flipped anywhere makes the reader panic.
    for i in (0..good.len()).step_by(7) {
        let mut b = good.clone();
        b[i] ^= 0x5a;
        let _ = Pyramid::from_bytes(&path, &b);
    }

    // A pyramid with a NaN is refused by the writer, and nothing is written.
    let mut nan = p.clone();
    let mut bad = nan.levels[0].lobes.get(0);
    bad.exponent = f64::NAN;
    nan.levels[0].lobes.set(0, bad);
    let out = tmp("nan.map");
    let _ = std::fs::remove_file(&out);
    let e = nan.write(&out).unwrap_err().to_string();
    assert!(e.contains("not written") && e.contains("exponent"), "{e}");
    assert!(!out.exists());
    assert!(nan.to_bytes().is_empty());
}

/// The compact (`f32`) levels against the `f64` path (`ExtractParams::compact_texels`): the
/// same texels and lobe counts, residuals identical (measured on the `f64` fits), lobes and
/// horizon statistics within one `f32` rounding (axes 1.2e-7 rad, weights — renormalised per
/// texel by `texel_lobes` — 2.5e-7, exponents and horizon statistics 6e-8 relative), and the
/// map files they write within one code step of each other with identical level tables.
#[test]
fn compact_levels_match_the_f64_path_within_f32_rounding() {
    let map = fixtures::gaussian(64, 3.0, 0.15, 11, 0.1).unwrap();
    let with = |compact_texels| {
        let p = ExtractParams {
            compact_texels,
            ..ExtractParams::default()
        };
        extract(Source::Heights(&map), &p, &mut |_| {}).unwrap()
    };
    let full = with(usize::MAX);
    let comp = with(0);
    // By default (levels of ≥ 256² texels compact) a 64² map stays in f64.
    assert_eq!(with(meso_maps::COMPACT_TEXELS), full);
    assert!(full.levels.iter().all(|l| !l.lobes.is_compact()));
    assert!(comp
        .levels
        .iter()
        .all(|l| l.lobes.is_compact() && matches!(l.horizon, Some(meso_maps::Horizons::F32(_)))));
    let rel = |a: f64, b: f64| (a - b).abs() / a.abs().max(1e-300);
    for (a, b) in full.levels.iter().zip(&comp.levels) {
        assert_eq!(a.lobe_start, b.lobe_start);
        assert_eq!(a.residual, b.residual);
        assert!(2 * b.bytes() <= a.bytes() + 4 * a.lobe_start.len());
        for t in 0..a.texels() {
            let (r, c) = (t / a.cols, t % a.cols);
            let (la, lb) = (a.texel_lobes(r, c).unwrap(), b.texel_lobes(r, c).unwrap());
            for (x, y) in la.iter().zip(&lb) {
                assert!(x.axis.angle_between(y.axis) < 1.2e-7, "{x:?} {y:?}");
                assert!((x.weight - y.weight).abs() < 2.5e-7, "{x:?} {y:?}");
                assert!(rel(x.exponent, y.exponent) <= 6e-8, "{x:?} {y:?}");
            }
            let s: f64 = lb.iter().map(|l| l.weight).sum();
            assert!((s - 1.0).abs() < 1e-12);
            let (ha, hb) = (
                a.texel_horizon(r, c).unwrap().unwrap(),
                b.texel_horizon(r, c).unwrap().unwrap(),
            );
            assert_eq!(ha.weight, hb.weight);
            for d in 0..4 {
                assert!(rel(ha.mean[d], hb.mean[d]) <= 6e-8 || ha.mean[d] == 0.0);
                assert!(rel(ha.var[d], hb.var[d]) <= 6e-8 || ha.var[d] == 0.0);
            }
        }
    }
    // The files: the same level table (sizes, lobe counts, residuals), values within a code.
    let (fa, fb) = (full.to_bytes(), comp.to_bytes());
    let table = 48 + 36 * full.levels.len();
    assert_eq!(fa[..table], fb[..table]);
    let (ra, rb) = (
        Pyramid::from_bytes(Path::new("f64.map"), &fa).unwrap(),
        Pyramid::from_bytes(Path::new("f32.map"), &fb).unwrap(),
    );
    let mut w = Worst::default();
    compare(&ra, &rb, &mut w);
    eprintln!("format 3 of the f32 levels against the f64 ones: {w:?}");
    assert!(w.axis_rad < 6e-6, "{w:?}");
    assert!(w.weight < 2.0 / 65535.0, "{w:?}");
    assert!(w.eta_rel < 2.2e-4, "{w:?}");
    assert!(w.horizon_mean_rad < 4e-4, "{w:?}");
    assert!(w.horizon_sd_rad < 2e-4, "{w:?}");
    // A compact pyramid read back and written again gives the same bytes.
    let mut rc = Pyramid::from_bytes(Path::new("f32.map"), &fb).unwrap();
    rc.compact(0);
    assert!(rc.levels.iter().all(|l| l.lobes.is_compact()));
    assert_eq!(rc.to_bytes(), fb);
}
