//! A map file whose level 0 is held by band (`Pyramid::read_lazy`, what `meso render` reads of
//! a map too big for the memory budget) changed in place while the material reads it: reported
//! by `Shader::check_sources`, which `meso render` checks before writing, never a panic.

use glam::{DVec2, DVec3};
use meso_core::material::Material;
use meso_maps::{extract, fixtures, ExtractParams, Lobes, Pyramid, Source};
use meso_render::material::local_point;
use meso_render::{NdfMapped, Shader};

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

/// Shade `n × n` points over the whole map (uv `[0, 1)²`) with a footprint of `fp` uv units;
/// every result's bits, in order.
fn shade(m: &NdfMapped, n: usize, fp: f64) -> Vec<u32> {
    let wi = [DVec3::new(0.3, 0.4, 0.866)];
    let wo = DVec3::new(0.0, -0.5, 0.866);
    let mut out = [[0.0f32; 3]];
    let mut bits = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let uv = DVec2::new((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            m.eval_many(&local_point(uv, fp), wo, &wi, &mut out);
            bits.extend(out[0].iter().map(|v| v.to_bits()));
        }
    }
    bits
}

/// The map file changed in place while the material reads it by band: shading goes on (the
/// band reads as zero-weight lobes, flat), no panic, and `check_sources` (what `meso render`
/// checks before it writes the image) names the file; before the change it is `Ok`.
#[test]
fn a_map_file_changed_while_rendering_is_reported() {
    use std::io::{Seek, SeekFrom, Write};
    let (dir, path) = written(7, "map-changed");
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
