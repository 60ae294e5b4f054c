//! The live preview: a material on a sphere, a plane or a draped cloth under directional lights,
//! rendered by `meso_render`.
//!
//! World frame: `+y` up, the camera on the `+z` side. A light is given by its azimuth (degrees
//! from the camera direction `+z` towards `+x`, i.e. 90° lights from the right) and its
//! elevation above the horizontal plane (for the plane and the cloth that plane is the surface,
//! so a 5° elevation grazes it). The sphere's pole is `+y`, so its tangent runs along the
//! parallels (horizontal); the plane's and the cloth's tangent is `+x` (left to right).
//!
//! The material is compiled once per request ([`preview_brdf`]) into meso-core's plan under its
//! preview policy ([`FastBrdf::with_policy`], [`Policy::Preview`]; the preview chooses nothing
//! itself): Phong peaks under Phong (N·H) facets in the multiple-surface form use the von
//! Mises–Fisher closed form (a cost per lobe; a few per cent from the exact convolution), other
//! materials the interactive plan. When that has no fast path (the quadrature: Phong peaks under
//! a Lambert, microfacet or reflect-Phong facet), the plan replaces the continuous NDF by
//! [`PREVIEW_NORMALS`] normals drawn from it by stratified sampling (a multiple surface with the
//! same facet), evaluated exactly by the sum of Eq. 4. Mirror facets (on a continuous NDF, in
//! either form) always have `FastBrdf`'s collapsed path, so they never reach the sampled normals
//! (a delta NDF under a mirror facet has no pointwise value). A GGX or Beckmann NDF under a mirror
//! facet in the microfacet form with Smith shadowing is the classic microfacet BRDF, which
//! `FastBrdf` evaluates in closed form ([`ANALYTIC_PATH`]). The response names the path in
//! `x-brdf-path`.

use crate::error::ApiError;
use glam::{DVec2, DVec3};
use meso_core::material::Material;
use meso_core::shading::{FastBrdf, Policy};
use meso_render::{
    render, Camera, ImageSettings, Light, Mesh, Projection, RenderOptions, SceneBuilder, Shader,
    ShadingPoint,
};
use serde::Deserialize;
use std::sync::{Arc, OnceLock};

/// Normals drawn from a continuous NDF when the preview needs a multiple surface (the plan's).
pub use meso_core::shading::PREVIEW_NORMALS;
/// Largest preview side in pixels.
pub const MAX_SIDE: u32 = 1024;
/// Smallest preview side in pixels.
pub const MIN_SIDE: u32 = 8;
/// Most samples per pixel.
pub const MAX_SPP: u32 = 64;
/// Linear radiance behind the object (sRGB #232426 at exposure 0).
pub const BACKGROUND: [f32; 3] = [0.0168, 0.0176, 0.0194];
/// Most lights per request.
pub const MAX_LIGHTS: usize = 8;

/// What the preview shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Object {
    /// A unit sphere, pole up, seen slightly from above (orthographic).
    #[default]
    Sphere,
    /// A flat square seen at 30° above its plane (perspective).
    Plane,
    /// A round cloth draped over a round form, with folds (perspective).
    Cloth,
}

/// Camera and image parameters of a preview.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct View {
    /// The object.
    pub object: Object,
    /// Image width in pixels ([`MIN_SIDE`]..=[`MAX_SIDE`]).
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel (1..=[`MAX_SPP`]).
    pub spp: u32,
    /// Exposure in stops (−20..=20).
    pub exposure: f64,
    /// Rotation of the material's tangent about the normal, degrees.
    pub tangent_deg: f64,
    /// Seed of the pixel sampling.
    pub seed: u32,
}

impl Default for View {
    fn default() -> Self {
        View {
            object: Object::Sphere,
            width: 384,
            height: 384,
            spp: 1,
            exposure: 0.0,
            tangent_deg: 0.0,
            seed: 0,
        }
    }
}

/// A directional light of the preview.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LightSpec {
    /// Degrees from the camera direction towards the right (+x).
    pub azimuth_deg: f64,
    /// Degrees above the horizontal plane (−90..=90).
    pub elevation_deg: f64,
    /// Irradiance perpendicular to the light, W/m² (0..=1000).
    pub intensity: f64,
    /// Linear RGB colour (each 0..=1).
    pub color: [f64; 3],
}

impl Default for LightSpec {
    fn default() -> Self {
        LightSpec {
            azimuth_deg: -35.0,
            elevation_deg: 40.0,
            intensity: 3.0,
            color: [1.0; 3],
        }
    }
}

/// The default lights: a key light from the upper left and a warm grazing light from the right.
#[must_use]
pub fn default_lights() -> Vec<LightSpec> {
    vec![
        LightSpec::default(),
        LightSpec {
            azimuth_deg: 80.0,
            elevation_deg: 6.0,
            intensity: 4.0,
            color: [1.0, 0.92, 0.8],
        },
    ]
}

/// The body of `POST /api/render`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderRequest {
    /// The material (JSON form).
    pub material: serde_json::Value,
    /// Camera and image.
    #[serde(default)]
    pub view: View,
    /// Directional lights (default [`default_lights`]).
    #[serde(default = "default_lights")]
    pub lights: Vec<LightSpec>,
}

fn range(name: &str, v: f64, lo: f64, hi: f64) -> Result<(), ApiError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(ApiError::bad_request(format!(
            "{name}: must be in [{lo}, {hi}], got {v}"
        )))
    }
}

impl RenderRequest {
    /// Check every number against its range.
    ///
    /// # Errors
    /// 400 naming the field.
    pub fn check(&self) -> Result<(), ApiError> {
        let v = &self.view;
        for (n, x) in [("view.width", v.width), ("view.height", v.height)] {
            range(n, f64::from(x), f64::from(MIN_SIDE), f64::from(MAX_SIDE))?;
        }
        range("view.spp", f64::from(v.spp), 1.0, f64::from(MAX_SPP))?;
        range("view.exposure", v.exposure, -20.0, 20.0)?;
        range("view.tangent_deg", v.tangent_deg, -3600.0, 3600.0)?;
        if self.lights.len() > MAX_LIGHTS {
            return Err(ApiError::bad_request(format!(
                "lights: {} lights is above the limit of {MAX_LIGHTS}",
                self.lights.len()
            )));
        }
        for (k, l) in self.lights.iter().enumerate() {
            range(
                &format!("lights[{k}].azimuth_deg"),
                l.azimuth_deg,
                -3600.0,
                3600.0,
            )?;
            range(
                &format!("lights[{k}].elevation_deg"),
                l.elevation_deg,
                -90.0,
                90.0,
            )?;
            range(&format!("lights[{k}].intensity"), l.intensity, 0.0, 1000.0)?;
            for c in l.color {
                range(&format!("lights[{k}].color"), c, 0.0, 1.0)?;
            }
        }
        Ok(())
    }
}

/// How the preview evaluates a material: meso-core's compiled plan (see the module docs).
pub type PreviewBrdf = FastBrdf;

/// The path name of meso-core's closed-form microfacet evaluation (in `x-brdf-path`): a GGX or
/// Beckmann NDF under mirror facets in the microfacet form with Smith shadowing.
pub const ANALYTIC_PATH: &str = meso_core::shading::CLOSED_MICROFACET_PATH;

/// The evaluation the plots use: meso-core's [`FastBrdf`] (never the preview's vMF closed
/// form or sampled normals).
#[must_use]
pub fn plot_brdf(material: &Material) -> PreviewBrdf {
    FastBrdf::new(material)
}

/// A [`PreviewBrdf`] as a renderer shader, with the tangent rotated by a fixed angle.
pub struct BrdfShader {
    brdf: PreviewBrdf,
    cos: f64,
    sin: f64,
}

impl BrdfShader {
    /// Wrap a compiled material; `tangent_deg` rotates its frame about the normal.
    #[must_use]
    pub fn new(brdf: PreviewBrdf, tangent_deg: f64) -> BrdfShader {
        let a = tangent_deg.to_radians();
        BrdfShader {
            brdf,
            cos: a.cos(),
            sin: a.sin(),
        }
    }

    #[inline]
    fn rotate(&self, v: DVec3) -> DVec3 {
        // Local directions of a frame whose tangent is rotated by +a: rotate by −a.
        DVec3::new(
            self.cos * v.x + self.sin * v.y,
            -self.sin * v.x + self.cos * v.y,
            v.z,
        )
    }
}

impl Shader for BrdfShader {
    #[inline]
    fn eval(&self, _sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        let f = self.brdf.eval(self.rotate(wi), self.rotate(wo));
        [f[0] as f32, f[1] as f32, f[2] as f32]
    }
}

/// Compile a material for the preview ([`Policy::Preview`]); returns the evaluation and a
/// description of its path.
#[must_use]
pub fn preview_brdf(material: &Material) -> (PreviewBrdf, String) {
    let f = FastBrdf::with_policy(material, Policy::Preview);
    let path = f.description();
    (f, path)
}

/// World direction of a light.
#[must_use]
pub fn light_direction(azimuth_deg: f64, elevation_deg: f64) -> DVec3 {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    DVec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
}

/// Height of the draped cloth above the floor at `(x, z)`: a round cloth over a round form
/// (a flat top of radius ~0.55), falling to the floor in folds whose depth grows with the drop.
fn cloth_height(x: f64, z: f64) -> f64 {
    let r = (x * x + z * z).sqrt();
    let a = z.atan2(x);
    let t = ((r - 0.5) / 0.8).clamp(0.0, 1.0);
    let drop = 1.0 - t * t * (3.0 - 2.0 * t);
    let top = 0.62 * drop - 0.08 * (r.min(0.5) / 0.5).powi(2);
    let fold = 0.09 * t.sqrt() * (1.0 - 0.4 * t) * (9.0 * a + 0.7 * (3.0 * a).sin()).sin();
    top + fold
}

/// Radius of the round cloth.
const CLOTH_RADIUS: f64 = 1.5;

/// The draped cloth mesh (built once): a round height field with radial folds, UVs along x/z
/// (so the tangent is +x; the texture image's top towards −z, glTF's v growing towards +z).
fn cloth_mesh() -> Result<Arc<Mesh>, String> {
    static MESH: OnceLock<Result<Arc<Mesh>, String>> = OnceLock::new();
    MESH.get_or_init(|| {
        let n = 110usize;
        let half = CLOTH_RADIUS;
        let mut pos = Vec::with_capacity((n + 1) * (n + 1));
        let mut nor = Vec::with_capacity((n + 1) * (n + 1));
        let mut uv = Vec::with_capacity((n + 1) * (n + 1));
        let e = 1e-4;
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let x = -half + 2.0 * half * u;
                let z = half - 2.0 * half * v;
                let y = cloth_height(x, z);
                let dx = (cloth_height(x + e, z) - cloth_height(x - e, z)) / (2.0 * e);
                let dz = (cloth_height(x, z + e) - cloth_height(x, z - e)) / (2.0 * e);
                pos.push(DVec3::new(x, y, z));
                nor.push(DVec3::new(-dx, 1.0, -dz).normalize());
                uv.push(DVec2::new(u, 1.0 - v));
            }
        }
        let mut idx = Vec::with_capacity(n * n * 2);
        let at = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        let inside = |i: usize, j: usize| {
            let p = pos[j * (n + 1) + i];
            p.x * p.x + p.z * p.z <= half * half
        };
        for j in 0..n {
            for i in 0..n {
                // Counter-clockwise seen from +y: (i,j) → (i+1,j) → (i+1,j+1) runs +x then −z.
                if inside(i, j) && inside(i + 1, j) && inside(i + 1, j + 1) {
                    idx.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                }
                if inside(i, j) && inside(i + 1, j + 1) && inside(i, j + 1) {
                    idx.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
        Mesh::new(pos, Some(nor), Some(uv), None, idx)
            .map(Arc::new)
            .map_err(|e| e.to_string())
    })
    .clone()
}

/// The timing and path of a finished preview.
#[derive(Clone, Debug, PartialEq)]
pub struct Rendered {
    /// The PNG bytes.
    pub png: Vec<u8>,
    /// Milliseconds spent compiling the material and rendering.
    pub render_ms: f64,
    /// The evaluation path of the material (see [`preview_brdf`]).
    pub path: String,
}

impl Rendered {
    /// The PNG of `img` at `exposure` stops, with its render time and path description.
    fn encode(
        img: &meso_render::Image,
        exposure: f64,
        render_ms: f64,
        path: String,
    ) -> Result<Rendered, ApiError> {
        let png = img
            .encode_png(exposure as f32)
            .map_err(|e| ApiError::internal(format!("png: {e}")))?;
        Ok(Rendered {
            png,
            render_ms,
            path,
        })
    }
}

/// Render a preview (blocking; call from `spawn_blocking`).
///
/// # Errors
/// 400 for an invalid request, 500 if the scene cannot be built or encoded.
pub fn render_preview(req: &RenderRequest, material: &Material) -> Result<Rendered, ApiError> {
    let (img, render_ms, path) = render_image(req, material)?;
    Rendered::encode(&img, req.view.exposure, render_ms, path)
}

/// Render a preview to a linear image (before exposure and PNG encoding); returns the image, the
/// milliseconds spent compiling the material and rendering, and the evaluation path.
///
/// # Errors
/// 400 for an invalid request, 500 if the scene cannot be built.
pub fn render_image(
    req: &RenderRequest,
    material: &Material,
) -> Result<(meso_render::Image, f64, String), ApiError> {
    req.check()?;
    let t0 = std::time::Instant::now();
    let (brdf, path) = preview_brdf(material);
    let shader = Arc::new(BrdfShader::new(brdf, req.view.tangent_deg));
    let img = render_shader(req, shader)?;
    let render_ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok((img, render_ms, path))
}

/// Most copies of a texture per unit of the object's texture coordinates
/// ([`TexturedRequest::repeat`]).
pub const MAX_REPEAT: f64 = 64.0;

/// The body of `POST /api/texture/render`: a [`RenderRequest`] with the open texture whose
/// pyramid shades the object (`meso_render::NdfMapped`, as `meso render` shades a `[texture]`
/// material with `kind = "ndf-mapped"`), the facet transfer and diffuse term from `material`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TexturedRequest {
    /// The texture's id (`POST /api/texture`).
    pub texture: String,
    /// Copies of the texture per unit of texture coordinate (default 1: once around the
    /// sphere, once across the plane); in (0, [`MAX_REPEAT`]].
    #[serde(default = "one")]
    pub repeat: f64,
    /// Horizon shadowing of the light from the pyramid's statistics (default: when the texture
    /// has them, i.e. height maps).
    #[serde(default)]
    pub shadowing: Option<bool>,
    /// The material (JSON form): its transfer, diffuse term and form shade the facets; its NDF
    /// is not used.
    pub material: serde_json::Value,
    /// Camera and image (`tangent_deg` does not apply: the texture fixes the tangent).
    #[serde(default)]
    pub view: View,
    /// Directional lights (default [`default_lights`]).
    #[serde(default = "default_lights")]
    pub lights: Vec<LightSpec>,
}

fn one() -> f64 {
    1.0
}

impl TexturedRequest {
    /// The request without the texture, for the checks and the scene.
    #[must_use]
    pub fn render_request(&self) -> RenderRequest {
        RenderRequest {
            material: serde_json::Value::Null,
            view: self.view,
            lights: self.lights.clone(),
        }
    }
}

/// Render the preview of an open texture (blocking): the object shaded through the texture's NDF
/// pyramid with the facets of `material` (module docs of [`TexturedRequest`]); the shader comes
/// from `store`'s cache when the last textured preview used the same texture and facets.
///
/// # Errors
/// 400 for an invalid request (ranges, shadowing asked of a normal map), 500 if the scene
/// cannot be built or encoded.
pub fn render_textured(
    req: &TexturedRequest,
    store: &crate::textures::TextureStore,
    texture: &crate::textures::Texture,
    material: &Material,
) -> Result<Rendered, ApiError> {
    let rr = req.render_request();
    rr.check()?;
    if !(req.repeat.is_finite() && req.repeat > 0.0 && req.repeat <= MAX_REPEAT) {
        return Err(ApiError::bad_request(format!(
            "repeat: must be in (0, {MAX_REPEAT}], got {}",
            req.repeat
        )));
    }
    let t0 = std::time::Instant::now();
    let pyr = &texture.pyramid;
    let has_horizon = pyr.levels.iter().all(|l| l.horizon.is_some());
    let shadowing = req.shadowing.unwrap_or(has_horizon);
    if shadowing && !has_horizon {
        return Err(ApiError::bad_request(format!(
            "shadowing: texture {:?} has no horizon statistics (a normal map has no heights)",
            texture.name
        )));
    }
    let texels_per_uv = pyr.levels[0].cols as f64 * req.repeat;
    let (shader, cached) = store
        .shader(texture, material, texels_per_uv, shadowing)
        .map_err(ApiError::bad_request)?;
    let path = format!(
        "{:?}: {}{}",
        texture.name,
        shader.describe().unwrap_or_default(),
        if cached { "" } else { " (shader built)" }
    );
    let img = render_shader(&rr, shader)?;
    let render_ms = t0.elapsed().as_secs_f64() * 1e3;
    Rendered::encode(&img, req.view.exposure, render_ms, path)
}

/// The preview scene of `req` (object, camera, lights) with `shader` on the object, rendered.
fn render_shader(
    req: &RenderRequest,
    shader: Arc<dyn Shader>,
) -> Result<meso_render::Image, ApiError> {
    let v = req.view;
    let scene_err = |e: meso_render::SceneError| ApiError::internal(format!("scene: {e}"));
    let camera = match v.object {
        Object::Sphere => {
            let el: f64 = 15f64.to_radians();
            Camera::new(
                Projection::Orthographic { width: 2.3 },
                DVec3::new(0.0, 5.0 * el.sin(), 5.0 * el.cos()),
                DVec3::ZERO,
                DVec3::Y,
            )
        }
        Object::Plane | Object::Cloth => Camera::new(
            Projection::Perspective { fov_deg: 38.0 },
            DVec3::new(0.0, 2.6, 3.9),
            DVec3::new(0.0, 0.1, 0.0),
            DVec3::Y,
        ),
    }
    .map_err(scene_err)?;
    let mut b = SceneBuilder::new(
        camera,
        ImageSettings {
            width: v.width,
            height: v.height,
            spp: v.spp,
            background: BACKGROUND,
        },
    );
    let mat = b.material(shader);
    match v.object {
        Object::Sphere => {
            b.sphere(DVec3::ZERO, 1.0, DVec3::Y, mat)
                .map_err(scene_err)?;
        }
        Object::Plane => {
            b.quad(
                DVec3::new(-1.6, 0.0, 1.6),
                DVec3::new(3.2, 0.0, 0.0),
                DVec3::new(0.0, 0.0, -3.2),
                mat,
            )
            .map_err(scene_err)?;
        }
        Object::Cloth => {
            let mesh = cloth_mesh().map_err(|e| ApiError::internal(format!("cloth: {e}")))?;
            b.mesh(mesh, mat);
        }
    }
    for l in &req.lights {
        if l.intensity > 0.0 {
            let k = l.intensity;
            b.light(Light::Directional {
                direction: light_direction(l.azimuth_deg, l.elevation_deg),
                irradiance: DVec3::new(l.color[0] * k, l.color[1] * k, l.color[2] * k),
            })
            .map_err(scene_err)?;
        }
    }
    let scene = b.build().map_err(scene_err)?;
    let opts = RenderOptions {
        width: Some(v.width),
        height: Some(v.height),
        spp: Some(v.spp),
        seed: v.seed,
        tile_size: 16,
        ..RenderOptions::default()
    };
    Ok(render(&scene, &opts, None))
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::transfer::Transfer;

    #[test]
    fn light_directions() {
        assert!((light_direction(0.0, 0.0) - DVec3::Z).length() < 1e-12);
        assert!((light_direction(90.0, 0.0) - DVec3::X).length() < 1e-12);
        assert!((light_direction(0.0, 90.0) - DVec3::Y).length() < 1e-12);
    }

    #[test]
    fn rotation_moves_the_tangent() {
        let m = Material::from_toml_str("[transfer]\nkind = \"lambert\"\n").unwrap();
        let s = BrdfShader::new(FastBrdf::new(&m), 90.0);
        // A frame rotated by 90°: the world tangent +x is the rotated frame's −y.
        assert!((s.rotate(DVec3::X) - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn cloth_builds() {
        let m = cloth_mesh().unwrap();
        let n = m.indices().len();
        assert!(n > 110 * 110 && n < 110 * 110 * 2, "{n} triangles");
    }

    /// A mirror facet on a continuous NDF (GGX in the microfacet form, Phong peaks in the
    /// multiple-surface form) takes meso-core's collapsed mirror path, never the sampled normals
    /// (a delta NDF under a mirror facet has no pointwise value), and agrees with the core's BRDF.
    #[test]
    fn mirror_facets_follow_the_core_brdf() {
        for text in [
            "form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha = 0.3\n\
             [transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.9, 0.9]\n\
             specular = [1.0, 0.25, 0.0]\n",
            "[ndf]\nkind = \"phong-peaks\"\nlobes = [{ axis = [0, 0], weight = 1, exponent = 60 }]\n\
             [transfer]\nkind = \"mirror\"\nspecular = [0.2, 0.9, 0.5]\n",
            // Anisotropic GGX and Beckmann (the editor's α_x, α_y), closed form.
            "form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha_x = 0.4\nalpha_y = 0.1\n\
             [transfer]\nkind = \"mirror\"\nfresnel = \"dielectric\"\neta = 1.5\n\
             specular = [0.3, 0.6, 0.9]\n",
            "form = \"microfacet\"\n[ndf]\nkind = \"beckmann\"\nalpha_x = 0.15\nalpha_y = 0.45\n\
             [transfer]\nkind = \"mirror\"\nspecular = [0.9, 0.6, 0.3]\n",
        ] {
            let m = Material::from_toml_str(text).unwrap();
            let (brdf, path) = preview_brdf(&m);
            assert!(path.starts_with("mirror facets"), "{path}");
            let dir = |t: f64, p: f64| {
                let (t, p) = (t.to_radians(), p.to_radians());
                DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
            };
            let mut peak = [0.0f64; 3];
            for (ti, pi, to, po) in [
                (30.0, 0.0, 30.0, 180.0),
                (45.0, 0.0, 20.0, 150.0),
                (10.0, 0.0, 60.0, 200.0),
                (40.0, 90.0, 35.0, 250.0),
                (25.0, 45.0, 50.0, 200.0),
            ] {
                let (i, o) = (dir(ti, pi), dir(to, po));
                let a = brdf.eval(i, o);
                let b = m.brdf(i, o);
                for c in 0..3 {
                    assert!(
                        (a[c] - b[c]).abs() <= 2e-2 * b[c].abs().max(1e-3),
                        "{text}: channel {c} at ({ti}, {to}, {po}): preview {} core {}",
                        a[c],
                        b[c]
                    );
                    peak[c] = peak[c].max(a[c]);
                }
            }
            assert!(peak.iter().all(|x| x.is_finite()) && peak.iter().any(|&x| x > 0.0));
            // The channels follow `specular`.
            let Transfer::Mirror { specular, .. } = m.transfer else {
                unreachable!()
            };
            for c in 1..3 {
                let want = specular[c] / specular[0];
                assert!((peak[c] / peak[0] - want).abs() < 1e-6, "{peak:?} vs {specular:?}");
            }
        }
    }

    #[test]
    fn slow_materials_get_sampled_normals() {
        let m = Material::from_toml_str(
            "[ndf]\nkind = \"phong-peaks\"\nlobes = [{ axis = [0, 0], weight = 1, exponent = 20 }]\n\
             [transfer]\nkind = \"lambert\"\n",
        )
        .unwrap();
        let (_, path) = preview_brdf(&m);
        assert!(path.starts_with("48 normals"), "{path}");
    }
}
