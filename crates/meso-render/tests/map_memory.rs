//! The memory of rendering a map file's material (what `meso render` does for
//! `[texture] map = "…"`: `Pyramid::read_coded`, then `NdfMapped::from_pyramid`, whose tables
//! are built tile by tile as shading reads them, under a cap) against what is really
//! allocated: this test binary counts every heap byte (a counting global allocator,
//! `meso_testkit::alloc`, as `meso-maps`' `extract_memory.rs`). On a 256² Gaussian height
//! map's file (two lobes a level-0 texel, level 0 compact: coded) the model of
//! docs/map-format.md ("Rendering a map file"):
//!
//! * reading: the coded pyramid (11 B a lobe, 4 + 28 B a texel on compact levels; 40 B a lobe,
//!   4 + 136 B a texel on the others: eight horizon azimuths) and one band being decoded;
//! * building and shading: the pyramid, the tables of the tiles held (the cache's own count)
//!   and one tile being built (its lobe statistics), whatever the view; under a cap, at most
//!   the cap, the tile being built and the tiles a shading call holds;
//! * level 0 held by band (`Pyramid::read_lazy`, what `meso render` reads when the coded
//!   pyramid would take more than half the budget): reading holds the coded pyramid less
//!   level 0's codes, and one band; it shades bit for bit as the coded one.
//!
//! One test per binary: the counter sees only this test's allocations.

use glam::{DVec2, DVec3};
use meso_core::material::Material;
use meso_maps::{extract, fixtures, ExtractParams, Pyramid, Source, COMPACT_TEXELS};
use meso_render::material::local_point;
use meso_render::{NdfMapped, Shader};
use meso_testkit::alloc::peak_since;

#[global_allocator]
static A: meso_testkit::alloc::Counting = meso_testkit::alloc::Counting;

/// Shade a `n × n` grid of points over `span` uv units from `(0.3, 0.6)` with a footprint of
/// `fp` uv units.
fn shade(m: &NdfMapped, n: usize, span: f64, fp: f64) -> f64 {
    let wi = [DVec3::new(0.3, 0.4, 0.866)];
    let wo = DVec3::new(0.0, -0.5, 0.866);
    let mut out = [[0.0f32; 3]];
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let uv = DVec2::new(
                0.3 + span * i as f64 / n as f64,
                0.6 + span * j as f64 / n as f64,
            );
            m.eval_many(&local_point(uv, fp), wo, &wi, &mut out);
            sum += f64::from(out[0][0]);
        }
    }
    sum
}

#[test]
fn rendering_a_map_file_peaks_at_its_model() {
    let map = fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    drop(map);
    let dir = std::env::temp_dir().join(format!("meso-map-memory-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("g256.map");
    pyr.write(&path).unwrap();
    let lobes: usize = pyr.levels.iter().map(|l| l.lobes.len()).sum();
    assert!(pyr.levels[0].lobes.len() > pyr.levels[0].texels() * 3 / 2);
    let model_pyramid: usize = pyr
        .levels
        .iter()
        .map(|l| {
            if l.texels() >= COMPACT_TEXELS {
                11 * l.lobes.len() + 32 * l.texels() + 4
            } else {
                40 * l.lobes.len() + 140 * l.texels() + 4
            }
        })
        .sum();
    drop(pyr);

    // Reading: the coded pyramid and one band (64 rows of level 0: its streams inflated and
    // decoded, its lobes and horizons built in `f64`, ≈ 250 B a texel and lobe).
    let mut reset = 0;
    peak_since(&mut reset);
    let read = Pyramid::read_coded(&path).unwrap();
    let read_peak = peak_since(&mut reset);
    let p_bytes = NdfMapped::pyramid_bytes(&read) as usize;
    let band = 64 * 256 * 250;
    eprintln!(
        "{lobes} lobes: coded pyramid {:.2} MB (model {:.2} MB), reading peak {:.2} MB",
        p_bytes as f64 / 1e6,
        model_pyramid as f64 / 1e6,
        read_peak as f64 / 1e6
    );
    assert_eq!(p_bytes, model_pyramid);
    assert!(
        read_peak >= p_bytes && read_peak <= p_bytes + band,
        "{read_peak}"
    );

    let surface =
        Material::from_toml_str("[transfer]\nkind = \"phong\"\nexponent = 20.0\n").unwrap();
    // One tile being built, at most: 64² texels of up to 4 lobes (a coarse level's, in
    // `f64`), each lobe's share, horizon statistics and table entry (8 + 72 + 40 B, vectors
    // grown up to twice), each texel's horizon statistics and lobe start (72 + 4 B).
    let tile = 64 * 64 * (4 * (8 + 72 + 40) * 2 + 76);
    // A far view (8 cells a point: levels 0 and 1 at Phong 20's default box detail 2), a zoomed one (half a cell: level 0, over
    // 128² cells, 4 to 9 tiles), and the zoomed one under a cap of about two tiles.
    let views = [
        ("far", 64, 1.0, 8.0 / 256.0, usize::MAX),
        ("zoom", 128, 0.5, 0.5 / 256.0, usize::MAX),
        ("zoom", 128, 0.5, 0.5 / 256.0, 3 << 19),
    ];
    let mut sums = Vec::new();
    for (view, n, span, fp, cap) in views {
        {
            peak_since(&mut reset);
            let m = NdfMapped::from_pyramid(read.clone(), &surface, 256.0, true)
                .unwrap()
                .with_table_cap(cap);
            let sum = shade(&m, n, span, fp);
            // The pyramid's copy (allocated after the reset) is part of the peak.
            let peak = peak_since(&mut reset);
            let (held, cache_peak, dropped) = m.table_cache_stats();
            eprintln!(
                "{view}, cap {cap}: {} tiles held ({:.2} MB, peak {:.2} MB, {dropped} dropped), \
                 heap peak beyond the pyramid {:.2} MB (shaded sum {sum:.3})",
                m.tiles_built(),
                held as f64 / 1e6,
                cache_peak as f64 / 1e6,
                (peak - p_bytes) as f64 / 1e6
            );
            assert!(m.tiles_built() > 0);
            assert!(
                peak >= p_bytes + cache_peak,
                "{peak} against {p_bytes} + {cache_peak}"
            );
            // The texel responses this thread keeps between shading calls of the same
            // directions (`MEMO_BYTES` at most, less under a cap; the far view reads levels
            // 0–1 at the default box detail and fills it).
            let memo = meso_render::MEMO_BYTES.min(cap / 2);
            assert!(
                peak <= p_bytes + cache_peak + tile + memo,
                "{peak} against the model"
            );
            if cap < usize::MAX {
                assert!(dropped > 0);
                // The cap, passed by at most the tile just built before others are dropped.
                assert!(cache_peak <= cap + tile, "{cache_peak} over the cap {cap}");
            }
            sums.push(sum);
        }
    }

    // Level 0 held by band (`Pyramid::read_lazy`, what `meso render` reads of a large map):
    // reading holds the other levels coded, level 0's lobe starts and one band being decoded;
    // the same shading, bit for bit, every view.
    peak_since(&mut reset);
    let lazy = Pyramid::read_lazy(&path).unwrap();
    let lazy_peak = peak_since(&mut reset);
    let l0 = &read.levels[0];
    let lazy_model = p_bytes - 11 * l0.lobes.len() - 16 * l0.texels();
    eprintln!(
        "level 0 by band: reading peak {:.2} MB (model {:.2} MB + one band)",
        lazy_peak as f64 / 1e6,
        lazy_model as f64 / 1e6
    );
    assert!(
        lazy_peak >= lazy_model && lazy_peak <= lazy_model + band,
        "{lazy_peak}"
    );
    for ((_, n, span, fp, cap), want) in views.into_iter().zip(sums) {
        let m = NdfMapped::from_pyramid(lazy.clone(), &surface, 256.0, true)
            .unwrap()
            .with_table_cap(cap);
        assert_eq!(shade(&m, n, span, fp).to_bits(), want.to_bits());
    }
    std::fs::remove_dir_all(&dir).ok();
}
