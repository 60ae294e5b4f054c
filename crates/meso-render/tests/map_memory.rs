//! The memory of building the NDF-mapped material of a map file's pyramid
//! (`NdfMapped::from_pyramid`, what `meso render` does for `[texture] map = "…"`) against what
//! is really allocated: this test binary counts every heap byte (a counting global allocator,
//! `meso_testkit::alloc`, as `meso-maps`' `extract_memory.rs`). On a 256² Gaussian height map's pyramid (two lobes a
//! level-0 texel, level 0 compact) the peak of building it, the pyramid included, is the model
//! of docs/map-format.md ("Rendering a map file") to within −25 %/+10 %: the pyramid, the lobe
//! statistics (8 B a lobe for the shares; horizons 36 or 72 B a level-0 texel and a coarser lobe)
//! and level 0's table (40 B a lobe, 4 B a texel) — which the layout before 2026-12-04 (88-byte
//! lobes, horizons copied to `f64`, level 0's lobe horizons per lobe) exceeded by far — and it
//! stays under `NdfMapped::new`'s peak with the pyramid kept. One test per binary: the counter
//! sees only this test's allocations.

use meso_core::material::Material;
use meso_maps::{extract, fixtures, ExtractParams, Pyramid, Source};
use meso_render::NdfMapped;
use meso_testkit::alloc::peak_since;

#[global_allocator]
static A: meso_testkit::alloc::Counting = meso_testkit::alloc::Counting;

/// Heap bytes of a pyramid's levels (lobes, horizon statistics, lobe starts).
fn pyramid_bytes(p: &Pyramid) -> usize {
    p.levels
        .iter()
        .map(|l| {
            l.lobes.bytes() + l.horizon.as_ref().map_or(0, |h| h.bytes()) + 4 * l.lobe_start.len()
        })
        .sum()
}

#[test]
fn building_from_a_map_pyramid_peaks_at_its_model() {
    let map = fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    drop(map);
    let read = pyramid_to_file_and_back(&pyr);
    let lobes: usize = pyr.levels.iter().map(|l| l.lobes.len()).sum();
    assert!(pyr.levels[0].lobes.is_compact());
    assert!(pyr.levels[0].lobes.len() > pyr.levels[0].texels() * 3 / 2);
    let surface =
        Material::from_toml_str("[transfer]\nkind = \"phong\"\nexponent = 20.0\n").unwrap();
    let p_bytes = pyramid_bytes(&read);

    let mut reset = 0;
    peak_since(&mut reset);
    let kept = NdfMapped::new(&read, &surface, 256.0, true).unwrap();
    let new_peak = peak_since(&mut reset) + p_bytes;
    drop(kept);
    peak_since(&mut reset);
    // The pyramid (allocated before the reset) is part of `from_pyramid`'s peak.
    let built = NdfMapped::from_pyramid(read, &surface, 256.0, true).unwrap();
    let from_peak = peak_since(&mut reset) + p_bytes;
    let per_lobe = from_peak as f64 / lobes as f64;
    eprintln!(
        "{lobes} lobes, pyramid {:.1} MB: from_pyramid peak {:.1} MB ({per_lobe:.1} B a lobe), \
         new with the pyramid kept {:.1} MB ({:.1} B a lobe)",
        p_bytes as f64 / 1e6,
        from_peak as f64 / 1e6,
        new_peak as f64 / 1e6,
        new_peak as f64 / lobes as f64
    );
    assert!(built.levels() == pyr.levels.len());
    // The model: the pyramid, the lobe statistics, level 0's table.
    let hz = |c: bool| if c { 36 } else { 72 };
    let l0 = &pyr.levels[0];
    let stats: usize = pyr
        .levels
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let c = l.lobes.is_compact();
            8 * l.lobes.len()
                + if k == 0 {
                    hz(c) * l.texels()
                } else {
                    hz(c) * l.lobes.len()
                }
        })
        .sum();
    let model = p_bytes + stats + 40 * l0.lobes.len() + 4 * l0.texels();
    eprintln!("model {:.1} MB", model as f64 / 1e6);
    assert!(
        from_peak as f64 <= 1.1 * model as f64 && from_peak as f64 >= 0.75 * model as f64,
        "peak {from_peak} B against the model's {model} B"
    );
    assert!(from_peak < new_peak, "{from_peak} against {new_peak}");
}

/// The pyramid as `meso render` gets it from a map file: written and read back.
fn pyramid_to_file_and_back(p: &Pyramid) -> Pyramid {
    Pyramid::from_bytes(std::path::Path::new("g256.map"), &p.to_bytes()).unwrap()
}
