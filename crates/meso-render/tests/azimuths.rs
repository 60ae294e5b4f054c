//! Shadows of a real, steep height map, on and between the grid's axes: the NDF-mapped
//! material's per-lobe shadowing against the bump map shadowed by rays on the displaced
//! surface (the truth of the same view, which the NDF-mapped material never reads). The map is
//! a facade with recessed windows (`tests/data/facade_disp_256.png`, 8-bit), at two height
//! scales (5: gentle walls; 20: walls of the window recesses near vertical); Lambert facets;
//! a light 69° from the normal at azimuths on the axes, on the diagonals and between them;
//! 4 and 16 map cells per pixel (pyramid levels ≈ 1.5 and 3.5).
//!
//! Each lobe's visibility is read from the distribution of the horizon angles of the cells it
//! stands for along eight azimuths (`meso_maps::HorizonCdf`). Measured (2026-12-07): 0.90–1.02
//! of the truth. Before, with four azimuths and a ramp of each lobe's pooled mean and variance,
//! the same renders were 0.29–1.19 (the steep map at 16 cells a pixel under the light along +y:
//! 0.29; at 4 cells a pixel on the diagonals: 1.19); docs/heightmaps.md, "Horizon
//! distributions per lobe".
//!
//! A second test takes the light to the viewer's side, the view 60° from the normal: a
//! lobe's visibility of the light and of the viewer are then one event along one azimuth
//! (`meso_maps::HorizonCdf::joint_visibility_along`). Measured (2026-12-07): 0.97–1.09 of the
//! truth; with their product, as before, 0.71–1.02 (16 cells a pixel, light 30° beside the
//! view's azimuth: 0.71).
//!
//! A third puts the light 90°–180° away from that viewer, where a lobe's joint horizon
//! distribution (`meso_maps::HorizonJoint`) says how the two go together: on the facade the
//! wall tops see both, the recess floors neither. Measured (2026-12-07): 0.94–0.95 of the
//! truth, bound 10 %; with the grid read bilinearly between its nodes, as before, 0.74–0.93;
//! with the product 0.14–0.47.
//!
//! Another puts the light 90° from that viewer's azimuth (at 0° and 180°), where the walls
//! turned towards the light are the ones lit: from level 2 on each lobe node reads the light
//! by its own normal (`meso_maps::HorizonToward`). Measured (2026-12-07): 0.92–0.94 of the
//! truth, bound 15 %; with each lobe's visibility read alike by all its normals, 0.54–0.59.
//!
//! A fourth reads level 0 alone, where each cell's light and viewer are read together per
//! sub-cell (`meso_maps::CellHorizon`), and a fifth footprints the viewer barely sees, which
//! read as the plain average rather than as the ratio of two numbers near 0
//! (docs/heightmaps.md, "One cell, light and viewer together; footprints barely seen").

use glam::DVec3;
use meso_core::material::Material;
use meso_maps::{extract, Border, ExtractParams, HeightMap, Source};
use meso_render::*;
use std::sync::Arc;

mod common;
use common::{plane_scene_from, render_at, render_plane};

/// The mean red radiance of an image.
fn mean(img: &Image) -> f64 {
    let px = img.pixels();
    px.iter().map(|p| f64::from(p[0])).sum::<f64>() / px.len() as f64
}

/// The facade (`tests/data/facade_disp_256.png`, texel 1, height scale `height`) with Lambert
/// facets: the NDF-mapped material of its pyramid and the bump map shadowed by rays, both with
/// shadowing (and so view weighting), and its texels per unit of texture coordinate.
fn facade(height: f64) -> (Arc<dyn Shader>, Arc<dyn Shader>, f64) {
    facade_to_level(height, usize::MAX)
}

/// [`facade`] with the NDF-mapped material reading levels up to `max_level` only.
fn facade_to_level(height: f64, max_level: usize) -> (Arc<dyn Shader>, Arc<dyn Shader>, f64) {
    let path = common::facade_path();
    let surface = Material::from_toml_str("[transfer]\nkind = \"lambert\"\n").unwrap();
    let map = HeightMap::load(&path, 1.0, height, Border::Wrap).unwrap();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let tpu = map.width() as f64;
    let ndf: Arc<dyn Shader> = Arc::new(
        NdfMapped::new(&pyr, &surface, tpu, true)
            .unwrap()
            .with_max_level(max_level),
    );
    let bump: Arc<dyn Shader> = Arc::new(BumpMapped::new(&map, &surface, tpu, true).unwrap());
    (ndf, bump, tpu)
}

#[test]
fn lights_on_and_between_the_axes_shadow_like_the_geometry() {
    let size = 48;
    let mut worst: (f64, String) = (0.0, String::new());
    for height in [5.0, 20.0] {
        let (ndf, bump, tpu) = facade(height);
        for cells_per_pixel in [4.0, 16.0] {
            let width = cells_per_pixel * f64::from(size) / tpu;
            for az in [0.0f64, 22.5, 45.0, 90.0, 135.0] {
                let (t, p) = (69f64.to_radians(), az.to_radians());
                let l = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                let n = mean(&render_plane(ndf.clone(), width, size, l, 1));
                let b = mean(&render_plane(bump.clone(), width, size, l, 64));
                let what = format!(
                    "height {height}, {cells_per_pixel} cells a pixel, light azimuth {az}°: \
                     NDF-mapped / bump map {:.3}",
                    n / b
                );
                eprintln!("{what}");
                let off = (n / b - 1.0).abs();
                if off > worst.0 {
                    worst = (off, what);
                }
            }
        }
    }
    assert!(worst.0 < 0.15, "worst: {}", worst.1);
}

/// The facade (256², height 20, Lambert), NDF-mapped and bump-mapped (shadowed by rays),
/// seen from `view_deg` from the normal at azimuth 270° at `cells_per_pixel`, under a light 69°
/// from the normal at each of `azimuths`: per azimuth, NDF-mapped at 1 spp over the bump map
/// at 64 spp.
fn grazing_view_ratios(
    view_deg: f64,
    cells_per_pixel: &[f64],
    azimuths: &[f64],
) -> Vec<(f64, f64, f64)> {
    grazing_view_ratios_to_level(view_deg, usize::MAX, cells_per_pixel, azimuths)
}

/// [`grazing_view_ratios`] with the NDF-mapped material reading levels up to `max_level`.
fn grazing_view_ratios_to_level(
    view_deg: f64,
    max_level: usize,
    cells_per_pixel: &[f64],
    azimuths: &[f64],
) -> Vec<(f64, f64, f64)> {
    let size = 48;
    let (ndf, bump, tpu) = facade_to_level(20.0, max_level);
    let v = view_deg.to_radians();
    let camera = DVec3::new(0.0, -v.sin(), v.cos());
    let mut out = Vec::new();
    for &cells in cells_per_pixel {
        let width = cells * f64::from(size) / tpu;
        for &az in azimuths {
            let (t, p) = (69f64.to_radians(), az.to_radians());
            let l = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
            let n = mean(&render_at(
                &plane_scene_from(ndf.clone(), width, size, l, camera),
                1,
            ));
            let b = mean(&render_at(
                &plane_scene_from(bump.clone(), width, size, l, camera),
                64,
            ));
            eprintln!(
                "view {view_deg}° from the normal, {cells} cells a pixel, light azimuth {az}°: \
                 NDF-mapped / bump map {:.3}",
                n / b
            );
            out.push((cells, az, n / b));
        }
    }
    out
}

/// The worst ratio of `ratios` (the farthest from 1): (cells per pixel, light azimuth, ratio).
fn worst(ratios: &[(f64, f64, f64)]) -> (f64, f64, f64) {
    *ratios
        .iter()
        .max_by(|a, b| (a.2 - 1.0).abs().total_cmp(&(b.2 - 1.0).abs()))
        .unwrap()
}

#[test]
fn a_light_opposite_a_grazing_viewer_lights_the_tops_the_viewer_sees() {
    let w = worst(&grazing_view_ratios(60.0, &[16.0], &[45.0, 90.0, 135.0]));
    assert!(
        (w.2 - 1.0).abs() < 0.1,
        "light azimuth {}°: {:.3}",
        w.1,
        w.2
    );
}

#[test]
fn a_light_across_a_grazing_viewer_lights_the_normals_turned_to_it() {
    let w = worst(&grazing_view_ratios(60.0, &[16.0], &[0.0, 180.0]));
    assert!(
        (w.2 - 1.0).abs() < 0.15,
        "light azimuth {}°: {:.3}",
        w.1,
        w.2
    );
}

#[test]
fn a_light_beside_a_grazing_viewer_lights_what_the_viewer_sees() {
    let w = worst(&grazing_view_ratios(
        60.0,
        &[4.0, 16.0],
        &[240.0, 255.0, 270.0],
    ));
    assert!(
        (w.2 - 1.0).abs() < 0.12,
        "{} cells a pixel, light azimuth {}°: {:.3}",
        w.0,
        w.1,
        w.2
    );
}

/// Level 0 alone, the viewer 45° from the normal, 4 cells a pixel (a footprint of 4 × 6 cells):
/// a pixel's ratio of seen-and-lit to seen hangs on which points of each cell see both, which
/// level 0 reads per sub-cell (`meso_maps::CellHorizon`). Measured (2026-12-07): 0.92–0.98;
/// with each cell's two fractions multiplied, as before, 0.72–0.82.
#[test]
fn level_zero_sees_light_and_viewer_together_point_by_point() {
    let w = worst(&grazing_view_ratios_to_level(
        45.0,
        0,
        &[4.0],
        &[0.0, 45.0, 135.0],
    ));
    assert!(
        (w.2 - 1.0).abs() < 0.12,
        "light azimuth {}°: {:.3}",
        w.1,
        w.2
    );
}

/// The viewer 60° from the normal, the light on the other side, 2 cells a pixel: rows of pixels
/// whose footprints the viewer cannot see, but whose box filter grazes a lit row of cells,
/// read as the plain average there (as the bump map's pixel with no sample seen), not as that
/// row's radiance. Measured (2026-12-07): 0.91–0.97; with the bare weighted mean 3.0–6.8.
#[test]
fn a_footprint_barely_seen_is_not_lit_by_the_edge_of_its_filter() {
    let w = worst(&grazing_view_ratios(60.0, &[2.0], &[45.0, 90.0, 135.0]));
    assert!(
        (w.2 - 1.0).abs() < 0.15,
        "light azimuth {}°: {:.3}",
        w.1,
        w.2
    );
}
