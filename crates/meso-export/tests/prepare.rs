//! The up-front checks of `meso_export::prepare`: a lobe pyramid's levels against the export's
//! mip chain (sizes written out by hand from the two rounding rules), map files and output
//! paths, and map options given with a material file.

use meso_export::prepare;
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-prepare-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Level sizes by the two rules, against sizes written out by hand: a pyramid halves rounding up
/// (5 × 3 → 3 × 2 → 2 × 1 → 1 × 1), KTX2 rounding down (5 × 3 → 2 × 1 → 1 × 1); powers of two agree.
#[test]
fn level_sizes_by_both_rules() {
    assert_eq!(
        prepare::lobe_level_sizes(5, 3),
        vec![(5, 3), (3, 2), (2, 1), (1, 1)]
    );
    assert_eq!(prepare::mip_level_sizes(5, 3), vec![(5, 3), (2, 1), (1, 1)]);
    assert_eq!(
        prepare::lobe_level_sizes(63, 63),
        vec![(63, 63), (32, 32), (16, 16), (8, 8), (4, 4), (2, 2), (1, 1)]
    );
    let p2: Vec<(usize, usize)> = (0..7).map(|k| (64 >> k, 64 >> k)).collect();
    assert_eq!(prepare::lobe_level_sizes(64, 64), p2);
    assert_eq!(prepare::mip_level_sizes(64, 64), p2);
    // 8 × 2 agrees (8×2, 4×1, 2×1, 1×1 both ways); 6 × 6 does not (6, 3, 2, 1 against 6, 3, 1).
    assert_eq!(
        prepare::lobe_level_sizes(8, 2),
        prepare::mip_level_sizes(8, 2)
    );
    assert_ne!(
        prepare::lobe_level_sizes(6, 6),
        prepare::mip_level_sizes(6, 6)
    );
}

/// The grid check: a 5 × 3 pyramid, a clamped one (63 × 63 cells of a 64² map), one of another
/// map are refused naming the file and the sizes; a matching 64² one passes.
#[test]
fn lobe_grids_that_are_not_the_mip_chain_are_refused() {
    let p = Path::new("lobes.map");
    let e = prepare::check_lobe_grid(p, (5, 3, 5, 3), 5, 3)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("lobes.map")
            && e.contains("level 1 is 3 × 2 in the pyramid")
            && e.contains("2 × 1 in the mip chain")
            && e.contains("4 levels")
            && e.contains("3 levels"),
        "{e}"
    );
    let e = prepare::check_lobe_grid(p, (64, 64, 63, 63), 64, 64)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("63 × 63") && e.contains("64 × 64") && e.contains("without --clamp"),
        "{e}"
    );
    let e = prepare::check_lobe_grid(p, (32, 32, 32, 32), 64, 64)
        .unwrap_err()
        .to_string();
    assert!(e.contains("32 × 32") && e.contains("64 × 64"), "{e}");
    prepare::check_lobe_grid(p, (64, 64, 64, 64), 64, 64).unwrap();
}

/// The grid read from a map file's first bytes is the pyramid's own (width, height, level 0's
/// cols × rows), for a pyramid extracted here; a file that is no map file is refused.
#[test]
fn lobe_grid_is_read_from_the_header() {
    let d = scratch("grid");
    let map = meso_maps::HeightMap::from_heights(
        8,
        4,
        (0..32).map(|t| ((t * 7) % 5) as f64 * 0.1).collect(),
        1.0,
        meso_maps::Border::Clamp,
    )
    .unwrap();
    let mut params = meso_maps::ExtractParams::default();
    params = params.with_max_lobes(1);
    let pyr = meso_maps::extract(meso_maps::Source::Heights(&map), &params, &mut |_| {}).unwrap();
    let f = d.join("p.map");
    pyr.write(&f).unwrap();
    let l0 = &pyr.levels[0];
    assert_eq!(
        prepare::lobe_grid(&f).unwrap(),
        (pyr.width, pyr.height, l0.cols, l0.rows)
    );
    assert_eq!((l0.cols, l0.rows), (7, 3));
    assert!(meso_maps::format::is_map_file(&f));
    let e = prepare::refuse_map_file(&f).unwrap_err().to_string();
    assert!(
        e.contains("p.map is a meso map file (written by `meso extract`), not an image")
            && e.contains("--lobes"),
        "{e}"
    );
    let not = d.join("n.map");
    std::fs::write(&not, b"not a map file at all, but long enough").unwrap();
    assert!(prepare::lobe_grid(&not).is_err());
    assert!(!meso_maps::format::is_map_file(&not));
    prepare::refuse_map_file(&not).unwrap();
    // An output path that is a file.
    let e = prepare::check_out_dir(&not).unwrap_err().to_string();
    assert!(e.contains("n.map") && e.contains("must be a folder"), "{e}");
    prepare::check_out_dir(&d).unwrap();
    prepare::check_out_dir(&d.join("new")).unwrap();
    std::fs::remove_dir_all(&d).unwrap();
}

/// Every given map option is named when a material file refuses them.
#[test]
fn material_options_are_named() {
    let m = Path::new("ggx.toml");
    prepare::refuse_material_options(m, &[]).unwrap();
    let e = prepare::refuse_material_options(m, &["--convention"])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("ggx.toml") && e.contains("--convention does not apply"),
        "{e}"
    );
    let e = prepare::refuse_material_options(m, &["--alpha", "--metallic"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("--alpha, --metallic do not apply"), "{e}");
}

/// `prepare::lobe_bytes`: before the fit, what reading the map compactly checks
/// (`Pyramid::read_compact_bytes`) plus room for the packed textures and their files; during
/// it, room for the files. Both bounds hold the real packing of a 3-lobe pyramid of a 64² and of
/// a 63 × 40 height map (the mip chain of the export), with the header's lobe count.
#[test]
fn lobe_memory_covers_the_packed_textures_and_their_files() {
    use meso_maps::{extract, fixtures, ExtractParams, Pyramid, Source};
    let d = scratch("lobe-bytes");
    for (w, h) in [(64usize, 64usize), (63, 40)] {
        let map = fixtures::gaussian(w.max(h), 3.0, 0.1, 5, 0.05).unwrap();
        let map = meso_maps::HeightMap::from_heights(
            w,
            h,
            (0..h)
                .flat_map(|r| (0..w).map(move |c| (r, c)))
                .map(|(r, c)| map.heights()[r * w.max(h) + c])
                .collect(),
            0.05,
            meso_maps::Border::Wrap,
        )
        .unwrap();
        let mut params = ExtractParams::default();
        params = params.with_max_lobes(3);
        let p = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();
        let path = d.join(format!("m{w}x{h}.map"));
        p.write(&path).unwrap();
        let extra = prepare::lobe_bytes(&path, w as u64, h as u64).unwrap();
        let need = Pyramid::read_compact_bytes(&path).unwrap();
        let tex = meso_export::lobes::pack(&Pyramid::read_compact(&path).unwrap());
        let packed: u64 = tex
            .levels
            .iter()
            .flatten()
            .map(|s| 2 * s.len() as u64)
            .sum();
        let files: u64 = meso_export::lobes::files(&tex)
            .unwrap()
            .iter()
            .map(|f| f.1.len() as u64)
            .sum();
        assert!(
            packed <= extra.during && files <= extra.during,
            "{w}×{h}: packed {packed} B, files {files} B, counted {} B",
            extra.during
        );
        assert!(
            extra.before >= need.bytes + packed + files,
            "{w}×{h}: {} B before the fit, reading {} + packed {packed} + files {files}",
            extra.before,
            need.bytes
        );
    }
}
