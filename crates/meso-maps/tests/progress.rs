//! Issue #12, item 13: the progress of an extraction tells the truth: a total known from the
//! first call (never a placeholder such as `u64::MAX`), monotone, ending at its total, and
//! weighted by work, so that the coarse levels (few texels, each fitted on many points) are not
//! a last few percent that take most of the time. The same for reading a map file
//! (`Pyramid::read_compact_reporting`, what `meso render` and `meso map info` read with).

use meso_maps::{extract, fixtures, ExtractParams, Progress, ProgressTask, Pyramid, Source};

fn progress_of(n: usize) -> Vec<Progress> {
    let map = fixtures::gaussian(n, 3.0, 0.15, 7, 0.1).unwrap();
    let mut calls = Vec::new();
    extract(Source::Heights(&map), &ExtractParams::default(), &mut |p| {
        calls.push(p)
    })
    .unwrap();
    calls
}

#[test]
fn item13_extract_progress_is_monotone_and_ends_at_its_total() {
    let calls = progress_of(64);
    let first = calls[0];
    assert_eq!(
        (first.work_done, first.texels_done, first.levels_done),
        (0, 0, 0)
    );
    assert!(
        first.work_total > 0 && first.work_total < u64::MAX / 2,
        "{first:?}"
    );
    assert!(first.texels_total > 0 && first.texels_total < u64::MAX / 2);
    for w in calls.windows(2) {
        assert_eq!(w[0].work_total, w[1].work_total, "the total never changes");
        assert!(
            w[1].work_done >= w[0].work_done,
            "{:?} then {:?}",
            w[0],
            w[1]
        );
        assert!(w[1].texels_done >= w[0].texels_done);
    }
    let last = calls.last().unwrap();
    assert_eq!(last.work_done, last.work_total);
    assert_eq!(last.texels_done, last.texels_total);
    assert_eq!(last.levels_done, last.levels);
    // One call before the work, one after the normals and horizons, one per level.
    assert_eq!(calls.len(), last.levels + 2);
}

#[test]
fn item13_extract_progress_is_weighted_by_work_not_texels() {
    let calls = progress_of(128);
    let total = calls[0].work_total as f64;
    // After the two finest levels (94% of the texels) much of the work is still to come.
    let after2 = calls.iter().find(|p| p.levels_done == 2).unwrap();
    let texel_share = after2.texels_done as f64 / after2.texels_total as f64;
    let work_share = after2.work_done as f64 / total;
    assert!(texel_share > 0.9, "{texel_share}");
    assert!(
        work_share < 0.8,
        "two finest levels {:.0}% of the work",
        100.0 * work_share
    );
}

/// Reading a map file reports task `Read` from 0 before the first band to its total after the
/// last level: one total throughout, monotone, every level counted, every texel; the pyramid
/// read is the same as without reports.
#[test]
fn reading_a_map_file_reports_every_band_up_to_its_total() {
    let map = fixtures::gaussian(256, 3.0, 0.15, 7, 0.1).unwrap();
    let pyr = extract(Source::Heights(&map), &ExtractParams::default(), &mut |p| {
        assert_eq!(p.task, ProgressTask::Extract)
    })
    .unwrap();
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("progress_read.map");
    pyr.write(&path).unwrap();
    let mut calls = Vec::new();
    let read = Pyramid::read_compact_reporting(&path, &mut |p| calls.push(p)).unwrap();
    assert!(read.to_bytes() == Pyramid::read_compact(&path).unwrap().to_bytes());
    let (first, last) = (calls[0], *calls.last().unwrap());
    assert_eq!(
        (first.work_done, first.levels_done, first.texels_done),
        (0, 0, 0)
    );
    assert!(calls.iter().all(|p| p.task == ProgressTask::Read));
    for w in calls.windows(2) {
        assert_eq!(w[0].work_total, w[1].work_total, "one total");
        assert!(w[0].work_done <= w[1].work_done && w[0].texels_done <= w[1].texels_done);
        assert!(w[0].levels_done <= w[1].levels_done);
    }
    assert_eq!(last.work_done, last.work_total);
    assert_eq!(last.levels_done, pyr.levels.len());
    let texels: u64 = pyr.levels.iter().map(|l| l.texels() as u64).sum();
    assert_eq!((last.texels_done, last.texels_total), (texels, texels));
    // More than one report a level on level 0 (its 256 rows are four bands of 64).
    assert!(
        calls.iter().filter(|p| p.levels_done == 0).count() >= 4,
        "{calls:?}"
    );
}

/// The renderer's tables (`lobe_stats_by_cell_reporting`, what `meso render` shows as
/// "tables"): reported from several threads, yet monotone, starting at 0 with the total set,
/// ending at it with every level done, weighted so that the levels whose every cell gives a
/// joint distribution count double; and the very values of `lobe_stats_by_cell`.
#[test]
fn tables_progress_is_monotone_and_ends_at_its_total() {
    let map = fixtures::gaussian(64, 3.0, 0.15, 7, 0.1).unwrap();
    let pyramid = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let calls = std::sync::Mutex::new(Vec::new());
    let stats = meso_maps::lobe_stats_by_cell_reporting(&pyramid, true, &|p| {
        calls.lock().unwrap().push(p);
    });
    assert_eq!(stats, meso_maps::lobe_stats_by_cell(&pyramid, true));
    let calls = calls.into_inner().unwrap();
    assert!(calls.iter().all(|p| p.task == ProgressTask::Tables));
    let first = calls[0];
    assert_eq!((first.work_done, first.levels_done), (0, 0));
    // 64² cells: level 0's pass, then levels 1–6 visiting every cell, levels 2 and 3 (texels of
    // 4 and 8 cells a side) counted twice.
    let levels = pyramid.levels.len();
    assert_eq!(levels, 7);
    assert_eq!(first.work_total, 64 * 64 * (1 + 6 + 2));
    for w in calls.windows(2) {
        assert_eq!(w[0].work_total, w[1].work_total, "the total never changes");
        assert!(
            w[1].work_done >= w[0].work_done,
            "{:?} then {:?}",
            w[0],
            w[1]
        );
        assert!(w[1].work_done <= w[1].work_total);
    }
    let last = calls.last().unwrap();
    assert_eq!(
        (last.work_done, last.levels_done),
        (last.work_total, levels)
    );
    // Reports along the way, not only the first and the last: one per coarse row (63 in levels
    // 1–6), less those a faster thread's larger figure made moot.
    let rows: usize = pyramid.levels[1..].iter().map(|l| l.rows).sum();
    assert_eq!(rows, 63);
    assert!(calls.len() > 8, "{}", calls.len());
}
