//! The benchmark scene, shared by `benches/sphere.rs` and `examples/bench_sphere.rs`.

use glam::DVec3;
use meso_render::*;
use std::sync::Arc;

/// Fig. 2d's seven normals (`meso_core::catalogue::seven_normals`: the filtered bump map of a
/// cylinder) as Phong lobes of the catalogue's exponent, weights normalised to sum 1.
pub fn seven_lobes() -> PhongLobes {
    let m = meso_core::catalogue::seven_normals();
    let total: f64 = m.normals.iter().map(|n| n.weight).sum();
    let lobes: Vec<(DVec3, f64, f64)> = m
        .normals
        .iter()
        .map(|n| {
            let axis = meso_core::frame::spherical_direction_deg(n.theta_deg, n.phi_deg);
            (axis, n.weight / total, m.exponent)
        })
        .collect();
    PhongLobes::new(&lobes, m.specular.map(|c| c as f32)).expect("seven valid lobes")
}

/// A `size × size` sphere with the 7-lobe shader under 4 point lights, 1 spp.
pub fn scene(size: u32) -> Scene {
    scene_with(size, Arc::new(seven_lobes()))
}

/// The benchmark scene with another material.
#[allow(dead_code)] // used by the example, not by every bench
pub fn scene_with(size: u32, shader: Arc<dyn Shader>) -> Scene {
    let cam = Camera::new(
        Projection::Perspective { fov_deg: 40.0 },
        DVec3::new(0.0, 0.0, 3.2),
        DVec3::ZERO,
        DVec3::Y,
    )
    .expect("valid camera");
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            width: size,
            height: size,
            spp: 1,
            background: [0.0; 3],
        },
    );
    let m = b.material(shader);
    b.sphere(DVec3::ZERO, 1.0, DVec3::Y, m)
        .expect("valid sphere");
    for p in [
        DVec3::new(3.0, 3.0, 4.0),
        DVec3::new(-3.0, 2.0, 4.0),
        DVec3::new(0.0, -3.0, 3.0),
        DVec3::new(2.0, 0.5, -1.0),
    ] {
        b.light(Light::Point {
            position: p,
            intensity: DVec3::splat(10.0),
        })
        .expect("valid light");
    }
    b.build().expect("valid scene")
}
