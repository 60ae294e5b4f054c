//! Map formats 4 and 5 (5, written since 2026-12-07, is 4 with the diagonals' horizon
//! statistics) and the streamed extraction (docs/map-format.md): the file
//! `extract_to_file` streams band by band holds the bytes `Pyramid::write_to` (`write`,
//! `to_bytes`) writes for the pyramid `extract` returns, and reads back to a pyramid that writes
//! the same bytes again (that a version-3 file reads back to the same pyramid as its version-4
//! re-encoding: `tests/map_format_v3.rs`); a damaged file is refused with an error naming the
//! problem (never a panic); a pyramid a map file cannot hold is not written; a failed
//! extraction leaves no output and nothing of an existing file changed.

use meso_maps::format::{BAND_ROWS, VERSION, VERSION_5};
use meso_maps::{
    extract, extract_to_file, extract_to_writer, fixtures, ExtractParams, MapError, Pyramid, Source,
};
use std::path::{Path, PathBuf};

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("map_format_v4");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn refused(path: &Path, bytes: &[u8], what: &str) {
    let e = Pyramid::from_bytes(path, bytes).unwrap_err().to_string();
    assert!(e.contains(what), "expected {what:?} in: {e}");
    let c = Pyramid::check_bytes(path, bytes).unwrap_err().to_string();
    assert_eq!(c, e);
}

#[test]
fn streamed_extraction_matches_the_pyramid_in_memory_and_damage_is_refused() {
    let map = fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap();
    let params = ExtractParams::default();
    let p = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();

    // The streamed bytes are those of the pyramid in memory written in format 4.
    let path = tmp("g.map");
    let mut streamed = Vec::new();
    let mut last = None;
    let levels = extract_to_writer(
        Source::Heights(&map),
        &params,
        &mut streamed,
        &path,
        &mut |pr| last = Some(pr),
    )
    .unwrap();
    let last = last.unwrap();
    assert_eq!(last.levels_done, p.levels.len());
    assert_eq!(last.work_done, last.work_total);
    let mut v4 = Vec::new();
    p.write_to(&mut v4).unwrap();
    assert_eq!(VERSION, VERSION_5, "the version written");
    assert!(p.to_bytes() == v4, "to_bytes and write_to differ");
    assert_eq!(
        u32::from_le_bytes(streamed[8..12].try_into().unwrap()),
        VERSION_5
    );
    assert!(
        streamed == v4,
        "streamed and in-memory format-4 bytes differ"
    );
    assert_eq!(levels.len(), p.levels.len());
    for (s, l) in levels.iter().zip(&p.levels) {
        assert_eq!((s.cols, s.rows, s.lobes), (l.cols, l.rows, l.lobes.len()));
        assert_eq!(s.residual, l.residual);
    }

    // It reads back to a pyramid that writes the same bytes again (level 0, of 65 536 texels,
    // is kept in `f32`).
    let from_v4 = Pyramid::from_bytes(&path, &streamed).unwrap();
    assert!(from_v4.levels[0].lobes.is_compact());
    assert!(
        from_v4.to_bytes() == streamed,
        "the pyramid read back writes other bytes"
    );
    Pyramid::check_bytes(&path, &streamed).unwrap();

    // Through a file, written atomically.
    let _ = std::fs::remove_file(&path);
    extract_to_file(Source::Heights(&map), &params, &path, &mut |_| {}).unwrap();
    assert!(std::fs::read(&path).unwrap() == streamed);
    assert!(Pyramid::read(&path).unwrap() == from_v4);
    // And so does `Pyramid::write`.
    let written = tmp("written.map");
    p.write(&written).unwrap();
    assert!(std::fs::read(&written).unwrap() == streamed);

    damaged_files_are_refused(&path, &streamed, &p);
    // In the same test: the budget set above is global to the binary.
    a_failed_streamed_extraction_leaves_nothing();
}

/// Offsets of the chunks of a format-4 file: (offset, tag).
fn chunks(b: &[u8], has_h: bool) -> Vec<(usize, [u8; 4])> {
    let mut out = Vec::new();
    let mut pos = 48;
    while pos < b.len() {
        let tag: [u8; 4] = b[pos..pos + 4].try_into().unwrap();
        out.push((pos, tag));
        if &tag == b"LEND" {
            pos += 52;
        } else {
            pos += 20;
            for _ in 0..if has_h { 7 } else { 4 } {
                let comp = u64::from_le_bytes(b[pos + 12..pos + 20].try_into().unwrap());
                pos += 20 + comp as usize;
            }
        }
    }
    assert_eq!(pos, b.len());
    out
}

fn damaged_files_are_refused(path: &Path, good: &[u8], p: &Pyramid) {
    let ch = chunks(good, true);
    // Level 0 of 256 rows in bands of 64 rows, then its end; …; the top level's end last.
    assert_eq!(
        ch.iter().filter(|c| &c.1 == b"LEND").count(),
        p.levels.len()
    );
    assert_eq!(
        ch.iter().take_while(|c| &c.1 == b"BAND").count(),
        256usize.div_ceil(BAND_ROWS)
    );

    // Truncated anywhere.
    for cut in [
        48,
        60,
        ch[1].0,
        ch[1].0 + 30,
        good.len() / 2,
        good.len() - 52,
        good.len() - 1,
    ] {
        let e = Pyramid::from_bytes(path, &good[..cut])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("truncated") || e.contains("bands end"),
            "{cut}: {e}"
        );
    }
    // Trailing bytes.
    let mut b = good.to_vec();
    b.extend_from_slice(b"LEND");
    refused(path, &b, "trailing");

    // A band of the wrong level, or of rows out of order.
    let second = ch[1].0;
    let mut b = good.to_vec();
    b[second + 4..second + 8].copy_from_slice(&1u32.to_le_bytes());
    refused(path, &b, "a band of level 1");
    let mut b = good.to_vec();
    b[second + 8..second + 12].copy_from_slice(&0u32.to_le_bytes());
    refused(path, &b, "rows 64.. of level 0");
    let mut b = good.to_vec();
    b[second + 12..second + 16].copy_from_slice(&1000u32.to_le_bytes());
    refused(path, &b, "rows 64..1064");
    // Two bands swapped: the second in the first's place.
    let (a0, a1, a2) = (ch[0].0, ch[1].0, ch[2].0);
    let mut b = good[..a0].to_vec();
    b.extend_from_slice(&good[a1..a2]);
    b.extend_from_slice(&good[a0..a1]);
    b.extend_from_slice(&good[a2..]);
    refused(path, &b, "rows 0.. of level 0");
    // A band missing: the level's end comes early.
    let mut b = good[..a1].to_vec();
    b.extend_from_slice(&good[a2..]);
    refused(path, &b, "rows 64.. of level 0");
    // A band claiming more lobes than its texels may hold.
    let mut b = good.to_vec();
    b[a0 + 16..a0 + 20].copy_from_slice(&u32::MAX.to_le_bytes());
    refused(path, &b, "claims 4294967295 lobes");
    // A stream claiming more bytes than the file has.
    let mut b = good.to_vec();
    b[a0 + 20 + 12..a0 + 20 + 20].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
    let e = Pyramid::from_bytes(path, &b).unwrap_err().to_string();
    assert!(
        e.contains("truncated") || e.contains("decompression bomb"),
        "{e}"
    );
    stream_contents_are_checked(path, good, p, a0);
    // A level end whose lobe count is not its bands'.
    let end0 = ch.iter().find(|c| &c.1 == b"LEND").unwrap().0;
    let mut b = good.to_vec();
    b[end0 + 8..end0 + 12].copy_from_slice(&7u32.to_le_bytes());
    refused(path, &b, "claims 7 lobes");
    let mut b = good.to_vec();
    b[end0 + 4..end0 + 8].copy_from_slice(&3u32.to_le_bytes());
    refused(path, &b, "the end of level 3");
    let mut b = good.to_vec();
    b[end0..end0 + 4].copy_from_slice(b"XXXX");
    refused(path, &b, "expected a band or the level's end");
    // Memory: the whole pyramid is checked against the budget before anything is inflated.
    let limit = good.len() as u64 * 2;
    meso_core::budget::set_budget(limit);
    let e = Pyramid::from_bytes(path, good).unwrap_err();
    meso_core::budget::set_budget(0);
    assert!(matches!(e, MapError::Budget(_)), "{e}");

    // No byte flipped makes the reader panic: every byte of the header, the first band's header
    // and stream headers and the first level's end, and 400 bytes spread over the file.
    let first_end = end0 + 52;
    let spread = (0..good.len()).step_by(good.len() / 400 + 1);
    let heads = (0..a0 + 20 + 20).chain(end0..first_end);
    for i in heads.chain(spread) {
        let mut b = good.to_vec();
        b[i] ^= 0x5a;
        let _ = Pyramid::from_bytes(path, &b);
        let _ = Pyramid::check_bytes(path, &b);
    }
}

fn deflate(raw: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(raw).unwrap();
    e.finish().unwrap()
}

/// `good` with stream `s` of the band at `band` replaced by `comp` (filter 0, raw length as
/// given).
fn replace_stream(good: &[u8], band: usize, s: usize, raw_len: usize, comp: &[u8]) -> Vec<u8> {
    let mut pos = band + 20;
    for _ in 0..s {
        pos += 20 + u64::from_le_bytes(good[pos + 12..pos + 20].try_into().unwrap()) as usize;
    }
    let len = u64::from_le_bytes(good[pos + 12..pos + 20].try_into().unwrap()) as usize;
    let mut out = good[..pos].to_vec();
    out.extend_from_slice(&[s as u8, 0, 0, 0]);
    out.extend_from_slice(&(raw_len as u64).to_le_bytes());
    out.extend_from_slice(&(comp.len() as u64).to_le_bytes());
    out.extend_from_slice(comp);
    out.extend_from_slice(&good[pos + 20 + len..]);
    out
}

/// The checks of a stream's contents (shared with version 3), on the first band (at `a0`, the
/// first `BAND_ROWS` rows of level 0 of `p`): inflating to more or fewer bytes than its header
/// says, corrupt deflate data, bytes after it; values out of range (a texel with more lobes
/// than `max_lobes`, weights all 0, a NaN horizon weight).
fn stream_contents_are_checked(path: &Path, good: &[u8], p: &Pyramid, a0: usize) {
    let texels = BAND_ROWS * p.levels[0].cols;
    let lobes = u32::from_le_bytes(good[a0 + 16..a0 + 20].try_into().unwrap()) as usize;
    let counts: Vec<u8> = p.levels[0].lobe_start[..=texels]
        .windows(2)
        .map(|w| (w[1] - w[0]) as u8)
        .collect();
    assert_eq!(counts.iter().map(|&c| c as usize).sum::<usize>(), lobes);
    // The real counts, unfiltered: the file reads back.
    let b = replace_stream(good, a0, 0, texels, &deflate(&counts));
    Pyramid::from_bytes(path, &b).unwrap();
    // A stream that inflates to more than its header says is cut at one byte more and refused.
    let mut more = counts.clone();
    more.extend(std::iter::repeat_n(0u8, 100_000));
    let b = replace_stream(good, a0, 0, texels, &deflate(&more));
    refused(path, &b, "inflates to more than");
    // Fewer bytes, garbage, or bytes after the compressed data.
    let b = replace_stream(good, a0, 0, texels, &deflate(&counts[1..]));
    refused(path, &b, "inflates to");
    let b = replace_stream(good, a0, 0, texels, &[0xff; 64]);
    refused(path, &b, "corrupt compressed data");
    let mut padded = deflate(&counts);
    padded.extend_from_slice(&[0; 3]);
    let b = replace_stream(good, a0, 0, texels, &padded);
    refused(path, &b, "after the end of the compressed data");
    // Out-of-range values: a texel with more lobes than max_lobes, all-zero weights, a NaN
    // horizon weight.
    let mut c = counts.clone();
    c[0] = 9;
    let b = replace_stream(good, a0, 0, texels, &deflate(&c));
    refused(path, &b, "lobes");
    let b = replace_stream(good, a0, 2, 2 * lobes, &deflate(&vec![0; 2 * lobes]));
    refused(path, &b, "weights are all 0");
    let mut hw = vec![0u8; 4 * texels];
    hw[3 * texels] = 0xff; // the top byte plane of the first weight: a negative NaN
    hw[2 * texels] = 0xc0;
    let b = replace_stream(good, a0, 4, 4 * texels, &deflate(&hw));
    refused(path, &b, "horizon weight");
}

/// A pyramid holding a value a map file cannot (a NaN exponent) is refused by the writer, naming
/// the value, and nothing is written (`to_bytes` is empty, which every reader refuses).
#[test]
fn a_pyramid_with_a_nan_is_not_written() {
    let map = fixtures::gaussian(16, 2.0, 0.1, 3, 0.1).unwrap();
    let mut nan = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let mut bad = nan.levels[0].lobes.get(0);
    bad.exponent = f64::NAN;
    nan.levels[0].lobes.set(0, bad);
    let out = tmp("nan.map");
    let _ = std::fs::remove_file(&out);
    let e = nan.write(&out).unwrap_err().to_string();
    assert!(e.contains("not written") && e.contains("exponent"), "{e}");
    assert!(!out.exists());
    assert!(nan.to_bytes().is_empty());
    let e = nan.write_to(&mut Vec::new()).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
}

/// A writer that fails after `left` bytes.
struct Failing {
    left: usize,
}

impl std::io::Write for Failing {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if b.len() > self.left {
            return Err(std::io::Error::other("disk full (injected)"));
        }
        self.left -= b.len();
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

fn a_failed_streamed_extraction_leaves_nothing() {
    let map = fixtures::gaussian(64, 4.0, 0.1, 3, 0.01).unwrap();
    let params = ExtractParams::default();
    let path = tmp("fail.map");
    // A write failing mid-way: an error naming the output, no panic.
    let e = extract_to_writer(
        Source::Heights(&map),
        &params,
        &mut Failing { left: 5000 },
        &path,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(matches!(e, MapError::Write { .. }), "{e}");
    assert!(e.to_string().contains("fail.map"), "{e}");

    // An existing map is untouched by an extraction failing mid-way (an injected panic after
    // the first levels), and no temporary file is left.
    let dir = tmp("untouched");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("keep.map");
    std::fs::write(&out, b"the user's file").unwrap();
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        extract_to_file(Source::Heights(&map), &params, &out, &mut |p| {
            if p.levels_done == 3 {
                panic!("injected");
            }
        })
    }));
    assert!(r.is_err());
    assert_eq!(std::fs::read(&out).unwrap(), b"the user's file");
    assert!(temp_files(&dir).is_empty(), "{:?}", temp_files(&dir));
    // Bad parameters: refused before anything is written.
    let mut bad = params.clone();
    bad.fit.max_lobes = 0;
    let e = extract_to_file(Source::Heights(&map), &bad, &out, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("max_lobes"), "{e}");
    assert_eq!(std::fs::read(&out).unwrap(), b"the user's file");
    // An output whose directory cannot exist (its parent is a file): an error naming it.
    let blocked = out.join("x.map");
    let e = extract_to_file(Source::Heights(&map), &params, &blocked, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("x.map"), "{e}");
    assert!(temp_files(&dir).is_empty());
    // And a successful one replaces the file atomically.
    extract_to_file(Source::Heights(&map), &params, &out, &mut |_| {}).unwrap();
    let p = Pyramid::read(&out).unwrap();
    let q = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();
    assert!(p == Pyramid::from_bytes(&out, &q.to_bytes()).unwrap());
    assert!(temp_files(&dir).is_empty());
}
