//! Map format 3's codes and the readers of formats 2 and 3 (docs/map-format.md). What the
//! quantisation (format 3's codes, which format 4 writes per band) costs against the unquantised
//! pyramid (lobes, horizon statistics and the BRDF of texel materials through the resolver);
//! that files of versions 2 and 3, no longer written, still read: fixtures written by the last
//! build that wrote them (`tests/data/README.md`), a version-2 and a version-3 file of the same
//! pyramid read back to the same values within the quantisation, a version-3 file to the very
//! pyramid its version-4 re-encoding reads back to; and that damaged, truncated, oversized or
//! bomb-like version-3 files are refused with an error naming the file (never a panic).

use glam::DVec3;
use meso_core::frame::spherical_direction_deg as dir;
use meso_core::material::{MaterialError, MaterialSpec, NdfResolver, ResolvedNdf};
use meso_maps::format::{SHADING_TAG, VERSION, VERSION_2, VERSION_3, VERSION_4};
use meso_maps::{
    extract, fixtures, ExtractParams, HorizonStats, MapError, MapsResolver, Pyramid, Source,
};
use std::path::{Path, PathBuf};

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("map_format_v3");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn pyramid(map: &meso_maps::HeightMap) -> Pyramid {
    let mut p = ExtractParams::default();
    p = p.with_max_lobes(4);
    extract(Source::Heights(map), &p, &mut |_| {}).unwrap()
}

/// A fixture of `tests/data` (its README says how it was made): `heights16` (a 16² Gaussian
/// height map, horizon statistics) or `normals32` (a 32² normal map, none), `v2` or `v3`.
fn fixture(name: &str, version: &str) -> (PathBuf, Vec<u8>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(format!("{name}.{version}.map"));
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes)
}

fn version_of(bytes: &[u8]) -> u32 {
    u32::from_le_bytes(bytes[8..12].try_into().unwrap())
}

/// `[ndf] kind = "map"` resolved from a pyramid in memory (the unquantised values), as
/// `MapsResolver` resolves it from a map file.
struct InMemory<'a>(&'a Pyramid);

impl NdfResolver for InMemory<'_> {
    fn resolve(
        &self,
        _kind: &str,
        table: &toml::Table,
        _file: &Path,
    ) -> Result<ResolvedNdf, MaterialError> {
        let int = |v: &toml::Value| v.as_integer().unwrap() as usize;
        let texel = table["texel"].as_array().unwrap();
        meso_maps::resolver::texel_ndf(
            self.0,
            int(&table["level"]),
            int(&texel[0]),
            int(&texel[1]),
            "<memory>",
        )
    }
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

/// The BRDF of texel `(level, row, col)` of the map `file` through `[ndf] kind = "map"` (resolved
/// by `resolver`), with a Beckmann facet of roughness `alpha` and the horizon shadowing: at 36
/// pairs on a grid and at the mirror pairs of each of `axes` (incidence 0° and 30°), where the
/// texel's BRDF peaks.
fn texel_brdf(
    resolver: &dyn NdfResolver,
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
        .and_then(|s| s.build(resolver))
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

/// The map file (format 4) read back against the pyramid in memory. Measured on 2026-12-02
/// against the `f32` pyramid of format 2 (the bounds below are these figures rounded up): lobe
/// axes within 2.51e-6 rad, weights within 1.13e-5, exponents within 1.08e-4 relative, horizon
/// means and standard deviations within 1.92e-4 and 9.6e-5 rad (half a step of their 12-bit
/// codes); the BRDF of 14 texels (every other level of a Gaussian and a woven map, horizon
/// shadowing) at 36 grid pairs and at the mirror pairs of their lobes within 1.90e-3 of its
/// peak (Beckmann α = 0.1) and 1.94e-3 (α = 0.02), the horizon's quantisation the larger part.
/// Against the `f64` pyramid in memory since 2026-12-04 (format 2 no longer written): axes
/// 2.52e-6 rad, weights 1.14e-5, exponents 1.08e-4, horizon 1.92e-4 and 9.6e-5 rad, BRDF
/// 1.90e-3 and 1.94e-3 of the peak: the same bounds hold.
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
        let file = tmp(&format!("{name}.map"));
        p.write(&file).unwrap();
        assert_eq!(version_of(&std::fs::read(&file).unwrap()), VERSION);
        let stored = Pyramid::read(&file).unwrap();
        compare(&p, &stored, &mut w);
        // A read map written again gives the same bytes (the cache and `meso extract` agree).
        assert!(
            stored.to_bytes() == p.to_bytes(),
            "{name}: re-encoding changed the file"
        );
        // Texels of every level: the corner and an inner one.
        for (k, l) in p.levels.iter().enumerate().step_by(2) {
            for (row, col) in [(0, 0), (l.rows / 2, l.cols / 3)] {
                let axes: Vec<DVec3> = l
                    .texel_lobes(row, col)
                    .unwrap()
                    .iter()
                    .map(|l| l.axis)
                    .collect();
                for (a, alpha) in [0.1, 0.02].into_iter().enumerate() {
                    let exact = texel_brdf(&InMemory(&p), &file, k, row, col, alpha, &axes);
                    let read = texel_brdf(&MapsResolver::new(), &file, k, row, col, alpha, &axes);
                    let peak = exact.iter().copied().fold(0.0, f64::max);
                    assert!(peak > 0.0);
                    for (x, y) in exact.iter().zip(&read) {
                        brdf_worst[a] = brdf_worst[a].max((x - y).abs() / peak);
                    }
                }
            }
        }
    }
    eprintln!(
        "the map file against the pyramid in memory: {w:?}; BRDF of peak: α 0.1 {:.2e}, α 0.02 {:.2e}",
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

/// The quantisation bounds of format 3's codes (docs/map-format.md: axes 2.9e-6 rad, weights
/// 1/65 535, exponents 1.06e-4·(1 + 1/η) relative, horizon means 1.92e-4 rad, standard
/// deviations 9.6e-5 rad) plus `f32` rounding (1e-6): `a` unquantised (format 2), `b` quantised.
fn within_the_codes(a: &Pyramid, b: &Pyramid) {
    assert_eq!(
        (
            a.width,
            a.height,
            a.texel_size,
            a.border,
            a.normal_mode,
            a.max_lobes
        ),
        (
            b.width,
            b.height,
            b.texel_size,
            b.border,
            b.normal_mode,
            b.max_lobes
        )
    );
    let mut w = Worst::default();
    compare(a, b, &mut w);
    for (la, lb) in a.levels.iter().zip(&b.levels) {
        for (x, y) in la.lobes.iter().zip(&lb.lobes) {
            assert!(x.axis.angle_between(y.axis) < 2.9e-6 + 1e-6, "{x:?} {y:?}");
            assert!(
                (x.weight - y.weight).abs() < 1.0 / 65535.0 + 1e-6,
                "{x:?} {y:?}"
            );
            let eta = (x.exponent - y.exponent).abs() / x.exponent;
            assert!(
                eta < 1.06e-4 * (1.0 + 1.0 / x.exponent) + 1e-6,
                "{x:?} {y:?}"
            );
        }
    }
    assert!(w.horizon_mean_rad < 1.92e-4 + 1e-6, "{w:?}");
    assert!(w.horizon_sd_rad < 9.6e-5 + 1e-6, "{w:?}");
    assert!(w.axis_rad > 0.0 && w.weight > 0.0, "quantised: {w:?}");
}

/// Version-2 files (uncompressed `f32`) still read: the fixtures of a height map (horizon
/// statistics) and a normal map (none) read back to the values of their version-3 twins within
/// the codes' steps, and are far larger than the version-4 file of the same pyramid; damaged
/// ones are refused (truncated, trailing bytes), never with a panic.
#[test]
fn version_2_files_still_read_and_are_larger() {
    for (name, has_h, smaller) in [("heights16", true, 2), ("normals32", false, 10)] {
        let (path, v2) = fixture(name, "v2");
        assert_eq!(version_of(&v2), VERSION_2);
        let r2 = Pyramid::from_bytes(&path, &v2).unwrap();
        Pyramid::check_bytes(&path, &v2).unwrap();
        assert_eq!(r2.levels[0].horizon.is_some(), has_h);
        let (p3, v3) = fixture(name, "v3");
        let r3 = Pyramid::from_bytes(&p3, &v3).unwrap();
        within_the_codes(&r2, &r3);
        let v4 = r2.to_bytes();
        eprintln!(
            "{name}: version 2 {} B, 3 {} B, 4 {} B",
            v2.len(),
            v3.len(),
            v4.len()
        );
        assert!(
            v4.len() * smaller < v2.len(),
            "{} vs {}",
            v4.len(),
            v2.len()
        );
        // Trailing bytes after a format-2 file are refused as before.
        let mut t = v2.clone();
        t.push(0);
        let e = Pyramid::from_bytes(Path::new("old.map"), &t).unwrap_err();
        assert!(e.to_string().contains("trailing"), "{e}");
        for cut in [47, 48 + 20, 48 + 40, v2.len() / 2, v2.len() - 1] {
            let e = Pyramid::from_bytes(&path, &v2[..cut])
                .unwrap_err()
                .to_string();
            assert!(e.contains("truncated"), "cut {cut}: {e}");
        }
        // No byte flipped makes the reader panic.
        for i in (0..v2.len()).step_by(5) {
            let mut b = v2.clone();
            b[i] ^= 0x5a;
            let _ = Pyramid::from_bytes(&path, &b);
            let _ = Pyramid::check_bytes(&path, &b);
        }
    }
}

/// A version-3 file reads back to the very pyramid its version-4 re-encoding (what this build
/// writes for it) reads back to: the same codes, the same values, bit for bit; and re-encoding
/// that pyramid gives the same version-4 bytes again.
#[test]
fn version_3_files_read_as_their_version_4_re_encoding() {
    for name in ["heights16", "normals32"] {
        let (path, v3) = fixture(name, "v3");
        assert_eq!(version_of(&v3), VERSION_3);
        let r3 = Pyramid::from_bytes(&path, &v3).unwrap();
        Pyramid::check_bytes(&path, &v3).unwrap();
        let v4 = r3.to_bytes();
        assert_eq!(version_of(&v4), VERSION);
        let r4 = Pyramid::from_bytes(&path, &v4).unwrap();
        assert!(
            r4 == r3,
            "{name}: version 4 reads back differently from version 3"
        );
        assert!(r4.to_bytes() == v4, "{name}: re-encoding changed the file");
        let lobes: usize = r3.levels.iter().map(|l| l.lobes.len()).sum();
        assert!(lobes > r3.levels[0].texels(), "{name}: {lobes} lobes");
    }
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

/// Issue #11 item 4: each level's shading error reads back from a format-3 file's trailer (and
/// is kept by its format-4 re-encoding); a format-3 file without the trailer (as written before
/// it existed) still reads, with the shading error not recorded; a truncated trailer, or one
/// holding a value that is not finite, is refused.
#[test]
fn shading_error_trailer_reads_and_older_files_still_read() {
    let (path, bytes) = fixture("heights16", "v3");
    let back = Pyramid::from_bytes(&path, &bytes).unwrap();
    for l in &back.levels {
        let (m, x) = (
            l.residual.shading_mean.unwrap(),
            l.residual.shading_max.unwrap(),
        );
        assert!(m.is_finite() && m >= 0.0 && x >= m && x < 1.0, "{m} {x}");
    }
    assert!(back.top().residual.shading_mean.unwrap() > 0.0);
    let again = Pyramid::from_bytes(&path, &back.to_bytes()).unwrap();
    for (a, b) in back.levels.iter().zip(&again.levels) {
        assert_eq!(a.residual, b.residual);
    }
    // The same file without the trailer: an older format-3 file.
    let nlev = back.levels.len();
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
    let mut nan = bytes.clone();
    let at = nan.len() - 8;
    nan[at..].copy_from_slice(&f64::NAN.to_le_bytes());
    refused(&path, &nan, "bad shading error");
}

fn deflate(raw: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(raw).unwrap();
    e.finish().unwrap()
}

fn refused(path: &Path, bytes: &[u8], needle: &str) {
    let e = Pyramid::from_bytes(path, bytes).unwrap_err();
    let s = e.to_string();
    assert!(matches!(e, MapError::MapFormat { .. }), "{s}");
    assert!(s.contains(needle), "expected \"{needle}\" in: {s}");
    assert!(s.contains(&path.display().to_string()), "{s}");
}

/// What is particular to version 3 (its level table and one set of streams for the whole
/// pyramid): a truncated file, trailing bytes, a stream whose raw length is not the table's, a
/// decompression bomb sized by its table, and bytes flipped anywhere. The checks of a stream's
/// contents, which versions 3 and 4 share, are tested on version-4 bytes
/// (`tests/map_format_v4.rs`).
#[test]
fn damaged_and_bomb_files_are_refused_naming_the_file() {
    let (path, good) = fixture("heights16", "v3");
    let p = Pyramid::from_bytes(&path, &good).unwrap();
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
    for v in [VERSION_3, big, big, big, big] {
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

    // No byte flipped anywhere makes the reader panic.
    for i in (0..good.len()).step_by(7) {
        let mut b = good.clone();
        b[i] ^= 0x5a;
        let _ = Pyramid::from_bytes(&path, &b);
        let _ = Pyramid::check_bytes(&path, &b);
    }
}

/// The compact (`f32`) levels against the `f64` path (`ExtractParams::compact_texels`): the
/// same texels and lobe counts, residuals identical (measured on the `f64` fits), lobes and
/// horizon statistics within one `f32` rounding (axes 1.2e-7 rad, weights — renormalised per
/// texel by `texel_lobes` — 2.5e-7, exponents and horizon statistics 6e-8 relative), and the
/// map files they write within one code step of each other with identical levels (sizes, lobe
/// counts, residuals).
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
    // The files: the same header, levels (sizes, lobe counts, residuals), values within a code.
    let (fa, fb) = (full.to_bytes(), comp.to_bytes());
    assert_eq!(fa[..48], fb[..48]);
    let (ra, rb) = (
        Pyramid::from_bytes(Path::new("f64.map"), &fa).unwrap(),
        Pyramid::from_bytes(Path::new("f32.map"), &fb).unwrap(),
    );
    let mut w = Worst::default();
    compare(&ra, &rb, &mut w);
    for (a, b) in ra.levels.iter().zip(&rb.levels) {
        assert_eq!((a.cols, a.rows, a.span), (b.cols, b.rows, b.span));
        assert_eq!(a.residual, b.residual);
    }
    eprintln!("the map file of the f32 levels against the f64 ones: {w:?}");
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

/// A version-4 file (four horizon azimuths; `tests/data/heights16.v4.map`, the version-3
/// fixture written by the last build that wrote version 4) reads back to the very pyramid of its
/// version-3 twin: the diagonals' statistics filled in from the axes', each diagonal's mean the
/// mean of its two neighbours' and its variance the mean of theirs (within the codes' steps);
/// re-encoded as version 5 it reads back the same.
#[test]
fn version_4_files_read_with_their_diagonals_filled_in_from_the_axes() {
    let (path, v4) = fixture("heights16", "v4");
    assert_eq!(version_of(&v4), VERSION_4);
    let r4 = Pyramid::from_bytes(&path, &v4).unwrap();
    Pyramid::check_bytes(&path, &v4).unwrap();
    let (p3, v3) = fixture("heights16", "v3");
    let r3 = Pyramid::from_bytes(&p3, &v3).unwrap();
    assert!(r4 == r3, "version 4 reads back differently from version 3");
    let mut checked = 0;
    for l in &r4.levels {
        let h = l.horizon.as_ref().unwrap();
        for t in 0..l.texels() {
            let s = h.get(t);
            let mean: [f64; 4] = std::array::from_fn(|d| s.mean[d]);
            let var: [f64; 4] = std::array::from_fn(|d| s.var[d]);
            let want = HorizonStats::from_axes(s.weight, mean, var);
            for d in 4..8 {
                // Half a mean code (1.92e-4 rad) plus the f32 rounding; the standard
                // deviation within half an sd code (9.6e-5 rad).
                assert!((s.mean[d] - want.mean[d]).abs() < 2e-4, "{s:?}");
                assert!((s.var[d].sqrt() - want.var[d].sqrt()).abs() < 1e-4, "{s:?}");
            }
            checked += usize::from(s.mean[..4].iter().any(|&m| m > 0.01));
        }
    }
    assert!(checked > 20, "{checked} texels with a rising horizon");
    let v5 = r4.to_bytes();
    assert_eq!(version_of(&v5), VERSION);
    assert!(Pyramid::from_bytes(&path, &v5).unwrap() == r4);
}
