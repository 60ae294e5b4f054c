//! The plane scene of the textured-material tests (`materials.rs`, `steep.rs`,
//! `visibility.rs`) and of `examples/bench_mapped.rs` (which includes this file by path), and
//! the renders of it that those tests compare (a truth at many samples per pixel against a
//! filtered shader at few).

use glam::DVec3;
use meso_render::*;
use std::sync::Arc;

/// The steep facade height map of the tests and examples (`tests/data/facade_disp_256.png`:
/// 256², 8-bit, flat faces and walls; read with texel size 1 and a height scale of 20 cells
/// unless said otherwise).
#[allow(dead_code)] // Not every including file reads the facade.
pub fn facade_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/facade_disp_256.png")
}

/// A unit-tiled plane `z = 0` (one map tile per world unit, u along +x) seen orthographically
/// from ≈ 24° off its normal (the camera at `(0, −0.4, 0.9)`, up +y), `size²` pixels covering
/// `width` world units, 1 spp, black background, under a directional light of irradiance 2 W/m²
/// from `light` (towards the light; the builder normalises it).
pub fn plane_scene(shader: Arc<dyn Shader>, width: f64, size: u32, light: DVec3) -> Scene {
    plane_scene_from(shader, width, size, light, DVec3::new(0.0, -0.4, 0.9))
}

/// [`plane_scene`] seen from the direction `camera` (towards the camera, normalised here; not
/// along ±y, the camera's up).
pub fn plane_scene_from(
    shader: Arc<dyn Shader>,
    width: f64,
    size: u32,
    light: DVec3,
    camera: DVec3,
) -> Scene {
    plane_scene_through(shader, width, 0.0, size, light, camera)
}

/// [`plane_scene_from`] through a pinhole camera of horizontal field of view `fov_deg`
/// (orthographic for 0), placed along `camera` so that the image spans `width` world units
/// across the plane's centre.
#[allow(dead_code)] // Not every including file renders through a pinhole.
pub fn plane_scene_through(
    shader: Arc<dyn Shader>,
    width: f64,
    fov_deg: f64,
    size: u32,
    light: DVec3,
    camera: DVec3,
) -> Scene {
    let (projection, distance) = if fov_deg > 0.0 {
        (
            Projection::Perspective { fov_deg },
            0.5 * width / (0.5 * fov_deg.to_radians()).tan(),
        )
    } else {
        (Projection::Orthographic { width }, 50.0)
    };
    let cam = Camera::new(
        projection,
        camera.normalize() * distance,
        DVec3::ZERO,
        DVec3::Y,
    )
    .unwrap();
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
    b.plane(DVec3::ZERO, DVec3::Z, DVec3::X, 1.0, m).unwrap();
    b.light(Light::Directional {
        direction: light,
        irradiance: DVec3::splat(2.0),
    })
    .unwrap();
    b.build().unwrap()
}

/// `scene` rendered with `spp` samples per pixel and otherwise default options.
#[allow(dead_code)] // Not every including file renders.
pub fn render_at(scene: &Scene, spp: u32) -> Image {
    render(
        scene,
        &RenderOptions {
            spp: Some(spp),
            ..RenderOptions::default()
        },
        None,
    )
}

/// [`plane_scene`] rendered with `spp` samples per pixel ([`render_at`]).
#[allow(dead_code)] // Not every including file renders.
pub fn render_plane(
    shader: Arc<dyn Shader>,
    width: f64,
    size: u32,
    light: DVec3,
    spp: u32,
) -> Image {
    render_at(&plane_scene(shader, width, size, light), spp)
}

/// The TOML of the facet material the glossy far-field tests and examples share: GGX facets of
/// roughness `alpha` when `alpha > 0`, with a grey Lambert diffuse term of albedo `diffuse`
/// when `diffuse > 0` (`tests/steep.rs` uses 0.1); otherwise Lambert facets of the default
/// albedo.
#[allow(dead_code)] // Not every including file shades glossy facets.
pub fn facet_toml(alpha: f64, diffuse: f64) -> String {
    if alpha <= 0.0 {
        return "[transfer]\nkind = \"lambert\"\n".to_string();
    }
    let mut t =
        format!("[transfer]\nkind = \"microfacet\"\ndistribution = \"ggx\"\nalpha = {alpha}\n");
    if diffuse > 0.0 {
        t += &format!("[diffuse]\nalbedo = [{diffuse}, {diffuse}, {diffuse}]\n");
    }
    t
}
