//! A map file's level 0 held by band (`Pyramid::read_lazy`, `meso_maps::LazyLevel`,
//! docs/map-format.md "Rendering a map file"): every lobe and texel reads as `Pyramid::read`
//! gives it, bit for bit, whatever the order of the reads; the lobe statistics of a rectangle
//! are those of the pyramid in memory and decode each band once; a corrupt band is refused
//! when the file is read, with an error naming the file; `meso map info`'s summary is the same
//! however the pyramid is held.

use meso_maps::{
    extract, fixtures, rect_lobe_stats_by_cell, ExtractParams, Horizons, Lobes, Pyramid, Source,
};
use std::path::{Path, PathBuf};

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("map_lazy");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// A Gaussian surface of `n`² samples extracted and written to `name`.
fn written(n: usize, name: &str) -> PathBuf {
    let map = fixtures::gaussian(n, 4.0, 0.1, 3, 0.01).unwrap();
    let p = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let path = tmp(name);
    p.write(&path).unwrap();
    path
}

/// The byte offsets of a map file's `BAND` tags, in order (level 0's bands first).
fn band_tags(bytes: &[u8]) -> Vec<usize> {
    bytes
        .windows(4)
        .enumerate()
        .filter(|(_, w)| *w == b"BAND")
        .map(|(i, _)| i)
        .collect()
}

fn lazy_level(p: &Pyramid) -> &meso_maps::LazyLevel {
    match &p.levels[0].lobes {
        Lobes::Lazy(l) => l,
        other => panic!("level 0 is not held by band: {}", other.len()),
    }
}

#[test]
fn a_level_held_by_band_reads_as_the_file() {
    let path = written(256, "g256.map");
    let full = Pyramid::read(&path).unwrap();
    let lazy = Pyramid::read_lazy(&path).unwrap();
    assert_eq!(full.levels.len(), lazy.levels.len());
    let (a, b) = (&full.levels[0], &lazy.levels[0]);
    let l = lazy_level(&lazy);
    assert!(matches!(b.horizon, Some(Horizons::Lazy(_))));
    assert_eq!(l.bands(), 4, "256 rows in bands of 64");
    assert_eq!(l.decoded_bands(), 0, "nothing decoded until read");
    assert_eq!(a.lobe_start, b.lobe_start);
    assert_eq!(a.lobes.len(), b.lobes.len());
    // Texel by texel, as a tile is built: each band decoded once.
    let (ha, hb) = (a.horizon.as_ref().unwrap(), b.horizon.as_ref().unwrap());
    for t in 0..a.texels() {
        let (s, e) = (a.lobe_start[t] as usize, a.lobe_start[t + 1] as usize);
        for (x, y) in a.lobes.range(s, e).zip(b.lobes.range(s, e)) {
            assert_eq!(x, y, "texel {t}");
            assert_eq!(
                x.axis.to_array().map(f64::to_bits),
                y.axis.to_array().map(f64::to_bits)
            );
            assert_eq!(
                (x.weight.to_bits(), x.exponent.to_bits()),
                (y.weight.to_bits(), y.exponent.to_bits())
            );
        }
        assert_eq!(ha.get(t), hb.get(t), "texel {t}");
    }
    assert_eq!(l.decoded_bands(), 4, "each band decoded once, in order");
    // In any order: backwards, every lobe and texel.
    for i in (0..a.lobes.len()).rev() {
        assert_eq!(a.lobes.get(i), b.lobes.get(i), "lobe {i}");
    }
    for t in (0..a.texels()).rev().step_by(7) {
        assert_eq!(ha.get(t), hb.get(t), "texel {t}");
    }
    // The other levels are read_coded's, which read as read's.
    for (x, y) in full.levels[1..].iter().zip(&lazy.levels[1..]) {
        assert_eq!(x.lobe_start, y.lobe_start);
        assert!(x.lobes.iter().eq(y.lobes.iter()));
        assert!(x
            .horizon
            .as_ref()
            .unwrap()
            .iter()
            .eq(y.horizon.as_ref().unwrap().iter()));
    }
    // Written back, the same file.
    assert!(lazy.to_bytes() == std::fs::read(&path).unwrap());
    // The lobe statistics of rectangles, level 0 and coarser: the same bits.
    for (k, rows, cols) in [
        (0, 60..130, 3..70),
        (1, 0..128, 0..64),
        (2, 10..64, 0..64),
        (6, 0..4, 0..4),
        (8, 0..1, 0..1),
    ] {
        let x = rect_lobe_stats_by_cell(&full, k, rows.clone(), cols.clone(), true);
        let y = rect_lobe_stats_by_cell(&lazy, k, rows, cols, true);
        assert_eq!(x, y, "level {k}");
    }
}

/// A coarse rectangle's lobe statistics visit level 0's rows in order: each band decoded
/// once, even with a cache of one band (the footprint of a level-8 texel of a 512² map is 4
/// bands; visited texel by texel, the second texel of a row would decode them all again).
#[test]
fn a_coarse_rectangle_decodes_each_band_once() {
    let path = written(512, "g512.map");
    let lazy = Pyramid::read_lazy(&path).unwrap();
    let l = lazy_level(&lazy);
    assert_eq!(l.bands(), 8);
    l.set_cache_bands(1);
    let before = l.decoded_bands();
    let y = rect_lobe_stats_by_cell(&lazy, 8, 0..2, 0..2, true);
    // Each band once, and band 0 again: the cells of the last row read row 0 (the map wraps).
    // Texel by texel, the second texel of each row would decode its 4 bands again.
    assert_eq!(l.decoded_bands() - before, 9, "each band once");
    let full = Pyramid::read(&path).unwrap();
    assert_eq!(y, rect_lobe_stats_by_cell(&full, 8, 0..2, 0..2, true));
}

/// Bytes changed inside a band of level 0 (its deflate data made invalid, in its first and its
/// second stream; its lobe count): refused when the file is read, naming the file, by
/// `read_lazy` as by `read` (the same message), never a panic. (Bytes flipped in the middle of
/// a stream may decode to other valid values: the format has no checksum.)
#[test]
fn a_corrupt_band_is_an_error_naming_the_file() {
    let path = written(256, "g256c.map");
    let bytes = std::fs::read(&path).unwrap();
    let at = band_tags(&bytes);
    // Level 0's second band: rows 64..128; its band header (20 bytes), then stream 0's header
    // (20 bytes: id, filter, 2 reserved, raw and compressed lengths) and data, then stream 1.
    let a = at[1];
    let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
    assert_eq!((u32_at(a + 4), u32_at(a + 8)), (0, 64), "level 0, row 64");
    let comp0 = u64::from_le_bytes(bytes[a + 32..a + 40].try_into().unwrap()) as usize;
    let s1 = a + 40 + comp0;
    assert_eq!(bytes[s1], 1, "stream 1's id");
    let cases: [(usize, u8, &str); 3] = [
        (a + 40, 0xFF, "corrupt compressed data"),
        (s1 + 20, 0xFF, "corrupt compressed data"),
        (a + 16, 0x01, "claims"),
    ];
    for (n, (i, x, what)) in cases.into_iter().enumerate() {
        let mut bad = bytes.clone();
        bad[i] ^= x;
        if x == 0xFF {
            // BFINAL 1, BTYPE 11: a reserved block type.
            bad[i] = 0xFF;
        }
        let p = tmp(&format!("corrupt{n}.map"));
        std::fs::write(&p, &bad).unwrap();
        let e = match Pyramid::read_lazy(&p) {
            Ok(_) => panic!("case {n}: the corrupt band was accepted"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains(&p.display().to_string()), "{e}");
        assert!(e.contains(what), "case {n}: {e}");
        let full = match Pyramid::read(&p) {
            Ok(_) => panic!("case {n}: accepted by read"),
            Err(e) => e.to_string(),
        };
        assert_eq!(e, full);
    }
}

/// A band of level 0 made invalid *after* the file was read (changed in place while mapped, as
/// another program writing into the file would): reading its lobes again does not panic; they
/// read as zero-weight, and `check_mapped` (what `meso render`, `meso export --lobes`, Python
/// and `Pyramid::write` check before writing) says which file and band, while the other bands
/// read as before.
#[test]
fn a_band_changed_while_mapped_is_reported_not_a_panic() {
    use std::io::{Seek, SeekFrom, Write};
    let path = written(256, "g256m.map");
    let full = Pyramid::read(&path).unwrap();
    let a = band_tags(&std::fs::read(&path).unwrap())[1];
    let lazy = Pyramid::read_lazy(&path).unwrap();
    let l = lazy_level(&lazy);
    l.set_cache_bands(1);
    lazy.check_mapped().unwrap();
    // Level 0's second band (rows 64..128): its first stream's deflate data, a reserved block
    // type, written into the file in place (not replaced).
    let mut f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.seek(SeekFrom::Start((a + 40) as u64)).unwrap();
    f.write_all(&[0xFF]).unwrap();
    f.sync_all().unwrap();
    drop(f);
    let l0 = &lazy.levels[0];
    let t = 64 * 256 + 7;
    let (s, e) = (l0.lobe_start[t] as usize, l0.lobe_start[t + 1] as usize);
    let lobes: Vec<_> = l0.lobes.range(s, e).collect();
    assert!(lobes.iter().all(|p| p.weight == 0.0), "{lobes:?}");
    let h = l0.horizon.as_ref().unwrap().get(t);
    assert_eq!(h.weight, 0.0);
    let err = lazy.check_mapped().unwrap_err().to_string();
    assert!(err.contains(&path.display().to_string()), "{err}");
    assert!(err.contains("band 1") || err.contains("row 64"), "{err}");
    assert!(err.contains("changed in place"), "{err}");
    // The first band still reads as the file was.
    let (s, e) = (l0.lobe_start[3] as usize, l0.lobe_start[4] as usize);
    for (x, y) in full.levels[0].lobes.range(s, e).zip(l0.lobes.range(s, e)) {
        assert_eq!(x, y);
    }
    // Writing the pyramid refuses, naming the source file, and writes nothing.
    let out = tmp("from_changed.map");
    std::fs::remove_file(&out).ok();
    let err = lazy.write(&out).unwrap_err().to_string();
    assert!(err.contains(&path.display().to_string()), "{err}");
    assert!(!out.exists());
}

/// The map file cut short by another program while level 0 is held by band: reading a band
/// past the cut would fault (SIGBUS) through the mapping; the level sees the file's length first,
/// reads that band as zero-weight lobes, and `check_mapped` says the file was cut. A band read
/// before the cut and still cached reads as before.
#[test]
fn a_file_cut_while_mapped_is_reported_not_a_fault() {
    let path = written(256, "g256cut.map");
    let full = Pyramid::read(&path).unwrap();
    let size = std::fs::metadata(&path).unwrap().len();
    let lazy = Pyramid::read_lazy(&path).unwrap();
    let l = lazy_level(&lazy);
    l.set_cache_bands(1);
    let l0 = &lazy.levels[0];
    let t0 = 5;
    let (s0, e0) = (l0.lobe_start[t0] as usize, l0.lobe_start[t0 + 1] as usize);
    let before: Vec<_> = l0.lobes.range(s0, e0).collect();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(size / 4)
        .unwrap();
    // The last band lies past the cut.
    let t = 255 * 256 + 9;
    let (s, e) = (l0.lobe_start[t] as usize, l0.lobe_start[t + 1] as usize);
    let lobes: Vec<_> = l0.lobes.range(s, e).collect();
    assert!(lobes.iter().all(|p| p.weight == 0.0), "{lobes:?}");
    let err = lazy.check_mapped().unwrap_err().to_string();
    assert!(err.contains(&path.display().to_string()), "{err}");
    assert!(
        err.contains("when it was opened: cut while being read"),
        "{err}"
    );
    assert!(err.contains("band 3"), "{err}");
    let again: Vec<_> = l0.lobes.range(s0, e0).collect();
    assert_eq!(before, again);
    for (x, y) in full.levels[0].lobes.range(s0, e0).zip(again) {
        assert_eq!(x, y);
    }
}

/// The map file cut short by another program while it is being read (after the first band,
/// through the progress report): an error naming the file, not a fault (SIGBUS) on the cut
/// pages of the mapping.
#[test]
fn a_file_cut_while_being_read_is_an_error_not_a_fault() {
    let path = written(256, "g256cutread.map");
    let size = std::fs::metadata(&path).unwrap().len();
    let mut bands = 0;
    let r = Pyramid::read_compact_reporting(&path, &mut |_| {
        bands += 1;
        if bands == 2 {
            std::fs::OpenOptions::new()
                .write(true)
                .open(&path)
                .unwrap()
                .set_len(size / 3)
                .unwrap();
        }
    });
    let err = match r {
        Ok(_) => panic!("read a cut file"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains(&path.display().to_string()), "{err}");
    assert!(err.contains("cut while being read"), "{err}");
}

/// `meso map info` reads with `Pyramid::read_compact` (coded, or level 0 by band when the
/// coded pyramid would take more than half the budget): its summary (levels, lobe counts per
/// texel, residuals) is the same as from `Pyramid::read`, whichever way the pyramid is held.
#[test]
fn the_summary_is_the_same_however_the_pyramid_is_held() {
    let path = written(256, "info256.map");
    let full = Pyramid::read(&path).unwrap().info().to_string();
    assert!(full.lines().count() > 8, "{full}");
    for (how, p) in [
        ("coded", Pyramid::read_coded(&path).unwrap()),
        ("by band", Pyramid::read_lazy(&path).unwrap()),
        ("compact", Pyramid::read_compact(&path).unwrap()),
    ] {
        assert_eq!(p.info().to_string(), full, "{how}");
    }
}

/// Python's `meso.Pyramid.read` and `meso export --lobes` read with `Pyramid::read_compact`;
/// Python's `write` of a pyramid read so writes the same file as one read whole, whichever way
/// it is held (coded, level 0 by band), and that file reads back as the first.
#[test]
fn a_pyramid_writes_the_same_file_however_it_is_held() {
    let path = written(256, "write256.map");
    let whole = tmp("write256_whole.map");
    Pyramid::read(&path).unwrap().write(&whole).unwrap();
    let bytes = std::fs::read(&whole).unwrap();
    for (how, p) in [
        ("coded", Pyramid::read_coded(&path).unwrap()),
        ("by band", Pyramid::read_lazy(&path).unwrap()),
        ("compact", Pyramid::read_compact(&path).unwrap()),
    ] {
        let out = tmp(&format!("write256_{}.map", how.replace(' ', "_")));
        p.write(&out).unwrap();
        assert!(std::fs::read(&out).unwrap() == bytes, "{how}: another file");
    }
    assert_eq!(
        Pyramid::read(&whole).unwrap().info().to_string(),
        Pyramid::read(&path).unwrap().info().to_string()
    );
}
