//! The far-field sweep of docs/heightmaps.md: how far NDF-mapped shading at 1 sample per pixel
//! is from the bump-mapped truth at 64, on the steep facade of the tests
//! (`tests/data/facade_disp_256.png`, height 20, tiled), over scenes of a viewer, a distance
//! (cells of the map per pixel) and a light (elevation and azimuth), both with shadowing and
//! view weighting (the defaults of `NdfMapped` and `BumpMapped` here):
//!
//! ```text
//! cargo run --release -p meso-render --example facade_sweep -- \
//!     [MAX_LOBES] [ALPHA] [THETAS] [VIEWS] [CELLS] [AZIMUTHS] [DETAIL] [HEIGHTS HEIGHT_SCALE]
//! ```
//!
//! `MAX_LOBES`: the extraction's lobes per texel at most on any map (default `-`:
//! `ExtractParams`' default, 4, or 6 on a map of faces and walls such as the facade); `ALPHA`: GGX facets of this roughness (Fresnel 1, no diffuse part) instead of
//! Lambert (default 0: Lambert); then comma-separated lists, in degrees: `THETAS` the light's
//! angles from the normal (default 69), `VIEWS` the viewer's (default 24,45,60; the viewer on
//! −y), `CELLS` cells per pixel (default 1,2,4,16,64), `AZIMUTHS` the light's azimuths from +x
//! towards +y (default 0,45,90,135,180,270: 90° is opposite the viewer); `DETAIL` the box
//! filter's detail (`NdfMapped::with_box_detail`; default the facet's own,
//! `default_box_detail`: 2, or 3 for GGX α ≤ 0.158; `-` for that
//! default); `HEIGHTS` another height map in its place (any format `meso extract` reads; texel
//! size 1, tiled) and its `HEIGHT_SCALE` (the height of the full code range). A 48² image per
//! scene. Prints each scene's ratio of mean pixels (NDF-mapped over bump-mapped), then the mean
//! of |ln ratio| per cells per pixel and over all scenes, the figure the docs' tables give.
//! The bump map is a truth up to views of about 45°: from 60° on it drifts from the displaced
//! geometry itself (up to 5× at 75° with the light opposite; docs/heightmaps.md, "Broad facets
//! read two levels finer"), which `far_gonio` measures far views against.
//!
//! Environment: `FACADE_SWEEP_FOV=F` renders every scene through a pinhole of horizontal field
//! of view `F` degrees instead of the orthographic camera, placed to see the same width of the
//! plane at its centre (so `CELLS` is the cells per pixel there; the far rows see more, and
//! more obliquely).

use glam::DVec3;
use meso_core::material::Material;
use meso_maps::{extract, Border, ExtractParams, HeightMap, Source};
use meso_render::{BumpMapped, Image, NdfMapped, Shader};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

#[path = "../tests/common/mod.rs"]
mod common;

/// The mean of an image's first channel.
fn mean(img: &Image) -> f64 {
    let px = img.pixels();
    px.iter().map(|p| f64::from(p[0])).sum::<f64>() / px.len() as f64
}

/// Argument `i` as a comma-separated list of numbers, or `default`.
fn list(args: &[String], i: usize, default: &str) -> Vec<f64> {
    let s = args.get(i).map_or(default, String::as_str);
    s.split(',')
        .map(|x| {
            x.trim()
                .parse()
                .unwrap_or_else(|_| panic!("argument {}: not a list of numbers: {s}", i + 1))
        })
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // MAX_LOBES: `-` (or absent) for the extraction's default (4, or 6 on a map of faces and
    // walls such as the facade), a number for that many on any map.
    let max_lobes = match args.first().map(String::as_str) {
        None | Some("-") => None,
        Some(_) => Some(list(&args, 0, "4")[0] as usize),
    };
    let alpha = list(&args, 1, "0")[0];
    let thetas = list(&args, 2, "69");
    let views = list(&args, 3, "24,45,60");
    let cells = list(&args, 4, "1,2,4,16,64");
    let azimuths = list(&args, 5, "0,45,90,135,180,270");
    let (path, scale) = match args.get(7) {
        Some(p) => (
            Path::new(p).to_path_buf(),
            list(&args, 8, "")
                .first()
                .copied()
                .expect("HEIGHT_SCALE after HEIGHTS"),
        ),
        None => (common::facade_path(), 20.0),
    };
    let map = HeightMap::load(&path, 1.0, scale, Border::Wrap)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let surface =
        Material::from_toml_str(&common::facet_toml(alpha, 0.0)).expect("the facet material");
    let params = match max_lobes {
        Some(k) => ExtractParams::default().with_max_lobes(k),
        None => ExtractParams::default(),
    };
    let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).expect("extraction");
    let max_lobes = pyr.max_lobes;
    let tpu = map.width() as f64;
    let mut ndf = NdfMapped::new(&pyr, &surface, tpu, true).expect("NDF-mapped shader");
    if let Some(d) = args.get(6).filter(|d| d.as_str() != "-") {
        ndf = ndf.with_box_detail(
            d.parse()
                .unwrap_or_else(|_| panic!("argument 7: not a number: {d}")),
        );
    }
    let detail = ndf.box_detail();
    let mapped: Arc<dyn Shader> = Arc::new(ndf);
    let bump: Arc<dyn Shader> =
        Arc::new(BumpMapped::new(&map, &surface, tpu, true).expect("bump-mapped shader"));
    let size = 48u32;
    let fov: f64 = match std::env::var("FACADE_SWEEP_FOV") {
        Ok(f) => f
            .parse()
            .unwrap_or_else(|_| panic!("FACADE_SWEEP_FOV: not a number of degrees: {f}")),
        Err(_) => 0.0,
    };
    let facet = if alpha > 0.0 {
        format!("GGX α = {alpha}")
    } else {
        "Lambert".to_string()
    };
    println!(
        "{} (height {scale}), {facet} facets, at most {max_lobes} lobes a texel, box detail {detail:.2}, {}",
        path.display(),
        if fov > 0.0 {
            format!("pinhole {fov}°")
        } else {
            "orthographic".to_string()
        }
    );
    let (mut sum, mut n) = (0.0, 0.0);
    let mut by_cells: BTreeMap<u64, (f64, f64)> = BTreeMap::new();
    for &theta in &thetas {
        for &view in &views {
            let v = view.to_radians();
            let camera = DVec3::new(0.0, -v.sin(), v.cos());
            for &c in &cells {
                let width = c * f64::from(size) / tpu;
                for &az in &azimuths {
                    let (t, p) = (theta.to_radians(), az.to_radians());
                    let light = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                    let scene = |s: &Arc<dyn Shader>| {
                        common::plane_scene_through(s.clone(), width, fov, size, light, camera)
                    };
                    let truth = mean(&common::render_at(&scene(&bump), 64));
                    let r = mean(&common::render_at(&scene(&mapped), 1)) / truth;
                    println!(
                        "light {theta}° azimuth {az}°, view {view}°, {c} cells/px: ratio {r:.3}"
                    );
                    let e = r.ln().abs();
                    sum += e;
                    n += 1.0;
                    let b = by_cells.entry(c.to_bits()).or_default();
                    b.0 += e;
                    b.1 += 1.0;
                }
            }
        }
    }
    let per: Vec<String> = by_cells
        .iter()
        .map(|(c, (s, k))| format!("{}: {:.3}", f64::from_bits(*c), s / k))
        .collect();
    println!(
        "mean |ln ratio| over {n} scenes: {:.4}; by cells per pixel: {}",
        sum / n,
        per.join(", ")
    );
}
