//! Far views of a height map against its displaced geometry: the mean radiance of an
//! orthographic image of the tiled map (NDF-mapped at 1 sample per pixel, and the ray-shadowed
//! bump map at 64) over the irradiance `2·cos θᵢ`, against the map's effective BRDF measured
//! by `meso_maps::Gonio` (rays traced on the displaced mesh, masking and shadowing included;
//! 384² rays a pair), which neither renderer reads. Lights 69° from the normal at azimuths 0,
//! 45, 90, 135, 180 and 270° (270°: the viewer's side), the viewer on −y:
//!
//! ```text
//! cargo run --release -p meso-render --example far_gonio -- \
//!     ALPHA VIEWS [CELLS [DETAIL [HEIGHTS HEIGHT_SCALE]]]
//! ```
//!
//! `ALPHA`: GGX facets of this roughness (Fresnel 1, no diffuse part), 0 for Lambert; `VIEWS`:
//! comma-separated viewing angles from the normal in degrees; `CELLS`: map cells per pixel
//! (default 64; the 32² image then spans 8 tiles of a 256² map, the far field); `DETAIL`: the
//! box filter's detail (`NdfMapped::with_box_detail`; default `-`, the facet's own,
//! `default_box_detail`); `HEIGHTS`, `HEIGHT_SCALE`: another height map (texel size 1, tiled;
//! the height of the full code range in cells) instead of the steep facade of the tests
//! (`tests/data/facade_disp_256.png`, 20). Prints each scene's truth and both ratios, then per
//! view and over all scenes (truth > 0) the mean |ln ratio| of each renderer against the
//! geometry. Environment: `FAR_GONIO_BRIEF=1` prints only the per-view and overall lines.

use glam::DVec3;
use meso_core::material::Material;
use meso_maps::{extract, Border, ExtractParams, Gonio, GonioParams, HeightMap, Source};
use meso_render::{BumpMapped, Image, NdfMapped, Shader};
use std::path::PathBuf;
use std::sync::Arc;

#[path = "../tests/common/mod.rs"]
mod common;

/// The mean of an image's first channel.
fn mean(img: &Image) -> f64 {
    let px = img.pixels();
    px.iter().map(|p| f64::from(p[0])).sum::<f64>() / px.len() as f64
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let number = |i: usize, what: &str| -> f64 {
        args[i]
            .parse()
            .unwrap_or_else(|_| panic!("{what}: not a number: {}", args[i]))
    };
    assert!(
        args.len() >= 2,
        "usage: ALPHA VIEWS [CELLS [DETAIL [HEIGHTS HEIGHT_SCALE]]]"
    );
    let alpha = number(0, "ALPHA");
    let views: Vec<f64> = args[1]
        .split(',')
        .map(|v| v.trim().parse().expect("VIEWS: comma-separated degrees"))
        .collect();
    let cells = if args.len() > 2 {
        number(2, "CELLS")
    } else {
        64.0
    };
    let detail = args
        .get(3)
        .filter(|d| d.as_str() != "-")
        .map(|_| number(3, "DETAIL"));
    let (path, scale) = match args.get(4) {
        Some(p) => (PathBuf::from(p), number(5, "HEIGHT_SCALE")),
        None => (common::facade_path(), 20.0),
    };
    let brief = std::env::var_os("FAR_GONIO_BRIEF").is_some();
    let map = HeightMap::load(&path, 1.0, scale, Border::Wrap)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let surface =
        Material::from_toml_str(&common::facet_toml(alpha, 0.0)).expect("the facet material");
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .expect("extraction");
    let tpu = map.width() as f64;
    let mut ndf = NdfMapped::new(&pyr, &surface, tpu, true).expect("NDF-mapped shader");
    if let Some(d) = detail {
        ndf = ndf.with_box_detail(d);
    }
    println!(
        "{} (height {scale}), {}, box detail {:.2}, {cells} cells per pixel",
        path.display(),
        if alpha > 0.0 {
            format!("GGX α = {alpha}")
        } else {
            "Lambert".to_string()
        },
        ndf.box_detail()
    );
    let ndf: Arc<dyn Shader> = Arc::new(ndf);
    let bump: Arc<dyn Shader> =
        Arc::new(BumpMapped::new(&map, &surface, tpu, true).expect("bump-mapped shader"));
    let gonio = Gonio::new(&map).expect("the displaced mesh");
    let params = GonioParams {
        rays_per_side: 384,
        ..GonioParams::default()
    };
    let size = 32u32;
    let width = cells * f64::from(size) / tpu;
    let (mut all_b, mut all_n, mut all) = (0.0, 0.0, 0.0);
    for &view in &views {
        let v = view.to_radians();
        let camera = DVec3::new(0.0, -v.sin(), v.cos());
        let (mut sb, mut sn, mut k) = (0.0, 0.0, 0.0);
        for az in [0.0f64, 45.0, 90.0, 135.0, 180.0, 270.0] {
            let (t, p) = (69f64.to_radians(), az.to_radians());
            let light = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
            let truth = gonio.measure(&surface.transfer, light, camera, &params)[0];
            let e = 2.0 * light.z;
            let far = |s: &Arc<dyn Shader>, spp: u32| {
                let scene = common::plane_scene_from(s.clone(), width, size, light, camera);
                mean(&common::render_at(&scene, spp)) / e
            };
            let (b, n) = (far(&bump, 64), far(&ndf, 1));
            if !brief {
                println!(
                    "view {view}°, light azimuth {az}°: geometry {truth:.5}, bump map {:.3}×, \
                     NDF-mapped {:.3}×",
                    b / truth,
                    n / truth
                );
            }
            if truth > 0.0 {
                sb += (b / truth).ln().abs();
                sn += (n / truth).ln().abs();
                k += 1.0;
            }
        }
        println!(
            "view {view}°: mean |ln ratio| bump map {:.3}, NDF-mapped {:.3}",
            sb / k,
            sn / k
        );
        (all_b, all_n, all) = (all_b + sb, all_n + sn, all + k);
    }
    println!(
        "over {all} scenes: mean |ln ratio| bump map {:.4}, NDF-mapped {:.4}",
        all_b / all,
        all_n / all
    );
}
