//! A map file whose level 0 is held by band (`Pyramid::read_lazy`, what `meso render` reads of
//! a map too big for the memory budget): the coarse levels' tiles, whose lobe statistics sweep
//! the level-0 rows under them, are built a tile row at a time, so that each full-width band is
//! decoded once a row rather than once for every tile across it. The shading is the same, bit
//! for bit, as from the coded pyramid (every tile built on its own), and the bands decoded are
//! counted. A band changed in the file while it is mapped is reported by
//! `Shader::check_sources`, which `meso render` checks before writing, never a panic.

use glam::{DVec2, DVec3};
use meso_core::material::Material;
use meso_maps::{extract, fixtures, ExtractParams, Lobes, Pyramid, Source};
use meso_render::material::local_point;
use meso_render::{NdfMapped, Shader};

/// Shade `n × n` points over the whole map (uv `[0, 1)²`, u the outer loop) with a footprint
/// of `fp` uv units; every result's bits, in order.
fn shade(m: &NdfMapped, n: usize, fp: f64) -> Vec<u32> {
    shade_from(m, n, fp, 0)
}

/// A Gaussian height map of 256² samples (`seed`) extracted and written to a fresh folder
/// named after `name`: the folder and the map file.
fn written(seed: u64, name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let map = fixtures::gaussian(256, 4.0, 0.1, seed, 0.01).unwrap();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let dir = std::env::temp_dir().join(format!("meso-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("g256.map");
    pyr.write(&path).unwrap();
    (dir, path)
}

#[test]
fn coarse_tiles_of_a_map_held_by_band_are_built_a_row_at_a_time() {
    // 256² texels: level 0 in 4 bands of 64 rows; level 1 (128²) in 2 × 2 tiles of 64²
    // texels, each over 128 level-0 rows (2 bands) and half the map's width.
    let (dir, path) = written(5, "tile-rows");
    let surface =
        Material::from_toml_str("[transfer]\nkind = \"phong\"\nexponent = 20.0\n").unwrap();
    let coded = Pyramid::read_coded(&path).unwrap();
    // Level 1 alone: the box filter over a footprint of 8 level-0 cells reads the level of a
    // quarter of it.
    let material = |p: Pyramid| {
        NdfMapped::from_pyramid(p, &surface, 256.0, true)
            .unwrap()
            .with_box_filter(true)
    };
    let fp = 8.0 / 256.0;
    let want = shade(&material(coded), 96, fp);

    for (cache, grouped) in [(1, true), (4, false)] {
        let lazy = Pyramid::read_lazy(&path).unwrap();
        let Lobes::Lazy(l0) = &lazy.levels[0].lobes else {
            panic!("level 0 is held by band");
        };
        let l0 = std::sync::Arc::clone(l0);
        assert_eq!(l0.bands(), 4);
        // One band kept: a level-1 tile sweeps 128 rows, more than half of the 64 kept, so
        // level 1 is built by row. Four kept (256 rows): tile by tile.
        l0.set_cache_bands(cache);
        assert_eq!(l0.cached_rows(), 64 * cache);
        let m = material(lazy);
        let got = shade(&m, 96, fp);
        assert!(
            got == want,
            "cache {cache}: not the coded pyramid's shading"
        );
        assert_eq!(m.tiles_built(), 4, "the four tiles of level 1");
        let decoded = l0.decoded_bands();
        eprintln!("cache of {cache} bands: {decoded} bands decoded");
        if grouped {
            // Each of the two tile rows sweeps its two bands once, and the next band's first
            // row for its last cells' far corners: at most 3 a row. (Built tile by tile, the
            // two tiles across each row swept them again: 11.)
            assert!(decoded <= 6, "{decoded} bands decoded");
        } else {
            // Every band kept: decoded once, whichever way the tiles are built.
            assert_eq!(decoded, 4);
        }
    }

    // Four threads shading at once (each all the points, from a different row), the rows
    // built under their locks as the threads reach them: the same shading, bit for bit.
    let lazy = Pyramid::read_lazy(&path).unwrap();
    let Lobes::Lazy(l0) = &lazy.levels[0].lobes else {
        panic!("level 0 is held by band");
    };
    l0.set_cache_bands(1);
    let m = material(lazy.clone());
    let parts: Vec<Vec<u32>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..4)
            .map(|k| {
                let m = &m;
                s.spawn(move || shade_from(m, 96, fp, k))
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (k, got) in parts.iter().enumerate() {
        assert!(
            *got == shade_from_bits(&want, 96, k),
            "thread {k}: not the same shading"
        );
    }
    assert_eq!(m.tiles_built(), 4);
    // Under a cap of three of the four tiles, tiles are dropped and their rows built again:
    // the same shading.
    let (_, all, _) = m.table_cache_stats();
    // (24² points: each column of points crosses both tile rows, each crossing a build.)
    let coded = Pyramid::read_coded(&path).unwrap();
    let want = shade(&material(coded), 24, fp);
    let m = material(lazy).with_table_cap(all * 3 / 4);
    assert!(shade(&m, 24, fp) == want, "capped: not the same shading");
    let (_, _, dropped) = m.table_cache_stats();
    eprintln!("cap {}: {dropped} tiles dropped", all * 3 / 4);
    assert!(dropped > 0, "the cap drops tiles");
    std::fs::remove_dir_all(&dir).ok();
}

/// Shade `n × n` points over the whole map (uv `[0, 1)²`, u the outer loop) with a footprint
/// of `fp` uv units, starting from row `k · n / 4` of the points and wrapping (another
/// thread's order); every result's bits, in order.
fn shade_from(m: &NdfMapped, n: usize, fp: f64, k: usize) -> Vec<u32> {
    let wi = [DVec3::new(0.3, 0.4, 0.866)];
    let wo = DVec3::new(0.0, -0.5, 0.866);
    let mut out = [[0.0f32; 3]];
    let mut bits = Vec::with_capacity(n * n);
    for i0 in 0..n {
        let i = (i0 + k * n / 4) % n;
        for j in 0..n {
            let uv = DVec2::new((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            m.eval_many(&local_point(uv, fp), wo, &wi, &mut out);
            bits.extend(out[0].iter().map(|v| v.to_bits()));
        }
    }
    bits
}

/// `want` (the bits of [`shade`]) in the order of [`shade_from`] with `k`.
fn shade_from_bits(want: &[u32], n: usize, k: usize) -> Vec<u32> {
    let per_row = 3 * n;
    (0..n)
        .flat_map(|i0| {
            let i = (i0 + k * n / 4) % n;
            want[i * per_row..(i + 1) * per_row].iter().copied()
        })
        .collect()
}

/// The map file changed in place while the material reads it by band: shading goes on (the
/// band reads as zero-weight lobes, flat), no panic, and `check_sources` (what `meso render`
/// checks before it writes the image) names the file; before the change it is `Ok`.
#[test]
fn a_map_file_changed_while_rendering_is_reported() {
    use meso_render::Shader;
    use std::io::{Seek, SeekFrom, Write};
    let (dir, path) = written(7, "tile-rows-changed");
    let bytes = std::fs::read(&path).unwrap();
    // Level 0's third band (rows 128..192): its first stream's deflate data.
    let at = bytes
        .windows(4)
        .enumerate()
        .filter(|(_, w)| *w == b"BAND")
        .map(|(i, _)| i)
        .nth(2)
        .unwrap();
    let lazy = Pyramid::read_lazy(&path).unwrap();
    let Lobes::Lazy(l0) = &lazy.levels[0].lobes else {
        panic!("level 0 is held by band");
    };
    l0.set_cache_bands(1);
    let surface =
        Material::from_toml_str("[transfer]\nkind = \"phong\"\nexponent = 20.0\n").unwrap();
    let m = NdfMapped::from_pyramid(lazy, &surface, 256.0, true).unwrap();
    m.check_sources().unwrap();
    let mut f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.seek(SeekFrom::Start((at + 40) as u64)).unwrap();
    f.write_all(&[0xFF]).unwrap();
    f.sync_all().unwrap();
    drop(f);
    // Every texel of the map, zoomed in: the changed band is read.
    let got = shade(&m, 64, 0.5 / 256.0);
    assert!(got.iter().all(|b| f32::from_bits(*b).is_finite()));
    let err = m.check_sources().unwrap_err();
    assert!(err.contains(&path.display().to_string()), "{err}");
    assert!(err.contains("band 2"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
