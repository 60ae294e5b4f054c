//! Scenes: built in code with [`SceneBuilder`] or loaded from a TOML file
//! (`docs/scene-format.md`) with [`Scene::from_toml_file`].
//!
//! Material references in scene files are paths relative to the scene file; they are turned
//! into shaders by a caller-supplied [`MaterialResolver`], so the renderer does not depend on
//! any material file format. Each distinct path is resolved once.

/// Largest scene file read (bytes actually read): 16 MiB.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// Largest OBJ mesh file read (bytes actually read): 256 MiB.
pub const MAX_OBJ_BYTES: u64 = 256 << 20;
/// Largest environment-map image file read (bytes actually read): 256 MiB.
pub const MAX_ENVIRONMENT_BYTES: u64 = 256 << 20;

use crate::bvh::{Bvh, Prim};
use crate::camera::{Camera, Projection, Ray, RayDifferential};
use crate::error::SceneError;
use crate::geometry::{
    face_viewer, finish_shading_point, MaterialId, Mesh, Plane, Quad, ShadingPoint, Sphere,
};
use crate::light::{EnvironmentMap, Light};
use crate::sampling::MAX_SAMPLES_PER_PIXEL;
use crate::shader::Shader;
use glam::DVec3;
use meso_core::display::Num;
use meso_core::frame::Frame;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Image size, sampling rate and background.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageSettings {
    /// Width in pixels, 1..=16384.
    pub width: u32,
    /// Height in pixels, 1..=16384.
    pub height: u32,
    /// Samples per pixel, 1..=65536.
    pub spp: u32,
    /// Linear RGB radiance seen by camera rays that hit nothing (when no visible environment).
    pub background: [f32; 3],
}

impl Default for ImageSettings {
    fn default() -> Self {
        ImageSettings {
            width: 256,
            height: 256,
            spp: 16,
            background: [0.0; 3],
        }
    }
}

/// The boxed error a [`MaterialResolver`] returns.
pub type ResolveError = Box<dyn std::error::Error + Send + Sync>;

/// Turns a material reference of a scene file into a shader.
///
/// `path` is the reference joined to the scene file's directory. Implemented for closures
/// `Fn(&Path) -> Result<Arc<dyn Shader>, ResolveError>`.
pub trait MaterialResolver {
    /// The shader for the material file at `path`.
    fn resolve(&self, path: &Path) -> Result<Arc<dyn Shader>, ResolveError>;
}

impl<F> MaterialResolver for F
where
    F: Fn(&Path) -> Result<Arc<dyn Shader>, ResolveError>,
{
    fn resolve(&self, path: &Path) -> Result<Arc<dyn Shader>, ResolveError> {
        self(path)
    }
}

/// A renderable scene with its acceleration structure built.
///
/// Camera, image settings, lights and environment are public and can be changed between
/// renders at no cost; materials can be swapped with [`Scene::set_material`]. Geometry is fixed
/// once built (build a new scene to change it).
#[derive(Clone)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    /// Image size, spp and background.
    pub image: ImageSettings,
    /// Light sources.
    pub lights: Vec<Light>,
    /// Optional environment light.
    pub environment: Option<Arc<EnvironmentMap>>,
    /// Whether camera rays that miss see the environment (else the background colour).
    pub environment_visible: bool,
    materials: Vec<Arc<dyn Shader>>,
    spheres: Vec<Sphere>,
    sphere_frames: Vec<meso_core::frame::Frame>,
    quads: Vec<Quad>,
    planes: Vec<Plane>,
    meshes: Vec<(Arc<Mesh>, MaterialId)>,
    bvh: Bvh,
    /// See [`Scene::sphere_only`] (empty when the scene has other geometry).
    sphere_only: Vec<LeafSphere>,
}

/// Collects geometry, materials and lights, then builds a [`Scene`].
#[derive(Clone)]
pub struct SceneBuilder {
    camera: Camera,
    image: ImageSettings,
    lights: Vec<Light>,
    environment: Option<Arc<EnvironmentMap>>,
    environment_visible: bool,
    materials: Vec<Arc<dyn Shader>>,
    spheres: Vec<Sphere>,
    quads: Vec<Quad>,
    planes: Vec<Plane>,
    meshes: Vec<(Arc<Mesh>, MaterialId)>,
}

fn finite(field: &str, v: DVec3) -> Result<(), SceneError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(SceneError::invalid(
            field,
            format!("must be finite, got {v:?}"),
        ))
    }
}

fn positive(field: &str, x: f64) -> Result<(), SceneError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(SceneError::invalid(
            field,
            format!("must be a finite number > 0, got {}", Num(x)),
        ))
    }
}

fn nonneg_rgb(field: &str, v: DVec3) -> Result<(), SceneError> {
    if v.is_finite() && v.min_element() >= 0.0 {
        Ok(())
    } else {
        Err(SceneError::invalid(
            field,
            format!("must be finite and non-negative in every channel, got {v:?}"),
        ))
    }
}

fn nonzero(field: &str, v: DVec3) -> Result<(), SceneError> {
    finite(field, v)?;
    if v.length() > 1e-12 {
        Ok(())
    } else {
        Err(SceneError::invalid(field, "must be a non-zero vector"))
    }
}

fn not_parallel(field: &str, a: DVec3, b: DVec3) -> Result<(), SceneError> {
    if a.cross(b).length() > 1e-12 * a.length() * b.length() && a.length() > 0.0 {
        Ok(())
    } else {
        Err(SceneError::invalid(
            field,
            "edges must be non-zero and not parallel",
        ))
    }
}

impl ImageSettings {
    /// Check the ranges; errors name `image.width` etc.
    pub fn validate(&self) -> Result<(), SceneError> {
        for (f, v) in [("image.width", self.width), ("image.height", self.height)] {
            if !(1..=16384).contains(&v) {
                return Err(SceneError::invalid(
                    f,
                    format!("must be in 1..=16384 pixels, got {v}"),
                ));
            }
        }
        if !(1..=MAX_SAMPLES_PER_PIXEL).contains(&self.spp) {
            return Err(SceneError::invalid(
                "image.spp",
                format!("must be in 1..={MAX_SAMPLES_PER_PIXEL}, got {}", self.spp),
            ));
        }
        let bg = DVec3::from_array(self.background.map(f64::from));
        nonneg_rgb("image.background", bg)
    }
}

/// Validate a light; `field` is its name in messages (e.g. `light[2]`).
pub fn validate_light(field: &str, l: &Light) -> Result<(), SceneError> {
    match *l {
        Light::Point {
            position,
            intensity,
        } => {
            finite(&format!("{field}.position"), position)?;
            nonneg_rgb(&format!("{field}.intensity"), intensity)
        }
        Light::Directional {
            direction,
            irradiance,
        } => {
            nonzero(&format!("{field}.direction"), direction)?;
            nonneg_rgb(&format!("{field}.irradiance"), irradiance)
        }
        Light::Linear {
            start,
            end,
            intensity,
        } => {
            finite(&format!("{field}.start"), start)?;
            finite(&format!("{field}.end"), end)?;
            if (end - start).length() <= 0.0 {
                return Err(SceneError::invalid(
                    format!("{field}.end"),
                    "must differ from start",
                ));
            }
            nonneg_rgb(&format!("{field}.intensity"), intensity)
        }
        Light::Sphere {
            center,
            radius,
            radiance,
        } => {
            finite(&format!("{field}.center"), center)?;
            positive(&format!("{field}.radius"), radius)?;
            nonneg_rgb(&format!("{field}.radiance"), radiance)
        }
        Light::Rectangle {
            corner,
            edge_u,
            edge_v,
            radiance,
            ..
        } => {
            finite(&format!("{field}.corner"), corner)?;
            finite(&format!("{field}.edge_u"), edge_u)?;
            finite(&format!("{field}.edge_v"), edge_v)?;
            not_parallel(&format!("{field}.edge_v"), edge_u, edge_v)?;
            nonneg_rgb(&format!("{field}.radiance"), radiance)
        }
    }
}

impl SceneBuilder {
    /// An empty scene seen through `camera`.
    #[must_use]
    pub fn new(camera: Camera, image: ImageSettings) -> SceneBuilder {
        SceneBuilder {
            camera,
            image,
            lights: Vec::new(),
            environment: None,
            environment_visible: true,
            materials: Vec::new(),
            spheres: Vec::new(),
            quads: Vec::new(),
            planes: Vec::new(),
            meshes: Vec::new(),
        }
    }

    /// Register a shader; returns its id.
    pub fn material(&mut self, shader: Arc<dyn Shader>) -> MaterialId {
        self.materials.push(shader);
        MaterialId((self.materials.len() - 1) as u32)
    }

    /// Add a sphere (pole normalised here).
    pub fn sphere(
        &mut self,
        center: DVec3,
        radius: f64,
        pole: DVec3,
        material: MaterialId,
    ) -> Result<&mut Self, SceneError> {
        let f = format!("sphere[{}]", self.spheres.len());
        finite(&format!("{f}.center"), center)?;
        positive(&format!("{f}.radius"), radius)?;
        nonzero(&format!("{f}.pole"), pole)?;
        self.spheres.push(Sphere {
            center,
            radius,
            pole: pole.normalize(),
            material,
        });
        Ok(self)
    }

    /// Add a parallelogram `origin + u·edge_u + v·edge_v`.
    pub fn quad(
        &mut self,
        origin: DVec3,
        edge_u: DVec3,
        edge_v: DVec3,
        material: MaterialId,
    ) -> Result<&mut Self, SceneError> {
        let f = format!("quad[{}]", self.quads.len());
        finite(&format!("{f}.origin"), origin)?;
        finite(&format!("{f}.edge_u"), edge_u)?;
        finite(&format!("{f}.edge_v"), edge_v)?;
        not_parallel(&format!("{f}.edge_v"), edge_u, edge_v)?;
        self.quads.push(Quad {
            origin,
            edge_u,
            edge_v,
            material,
        });
        Ok(self)
    }

    /// Add an infinite plane (normal normalised; tangent made orthogonal to it).
    pub fn plane(
        &mut self,
        point: DVec3,
        normal: DVec3,
        tangent: DVec3,
        uv_scale: f64,
        material: MaterialId,
    ) -> Result<&mut Self, SceneError> {
        let f = format!("plane[{}]", self.planes.len());
        finite(&format!("{f}.point"), point)?;
        nonzero(&format!("{f}.normal"), normal)?;
        finite(&format!("{f}.tangent"), tangent)?;
        positive(&format!("{f}.uv_scale"), uv_scale)?;
        self.planes.push(Plane {
            point,
            normal: normal.normalize(),
            tangent,
            uv_scale,
            material,
        });
        Ok(self)
    }

    /// Add a triangle mesh.
    pub fn mesh(&mut self, mesh: Arc<Mesh>, material: MaterialId) -> &mut Self {
        self.meshes.push((mesh, material));
        self
    }

    /// Add a light (validated).
    pub fn light(&mut self, light: Light) -> Result<&mut Self, SceneError> {
        validate_light(&format!("light[{}]", self.lights.len()), &light)?;
        let light = match light {
            Light::Directional {
                direction,
                irradiance,
            } => Light::Directional {
                direction: direction.normalize(),
                irradiance,
            },
            l => l,
        };
        self.lights.push(light);
        Ok(self)
    }

    /// Set the environment light; `visible` makes camera misses show it.
    pub fn environment(&mut self, env: Arc<EnvironmentMap>, visible: bool) -> &mut Self {
        self.environment = Some(env);
        self.environment_visible = visible;
        self
    }

    /// Check material ids and image settings, and build the BVH.
    pub fn build(self) -> Result<Scene, SceneError> {
        self.image.validate()?;
        let nm = self.materials.len() as u32;
        let check = |field: String, m: MaterialId| {
            if m.0 < nm {
                Ok(())
            } else {
                Err(SceneError::invalid(
                    field,
                    format!("material id {} does not exist ({nm} registered)", m.0),
                ))
            }
        };
        for (i, s) in self.spheres.iter().enumerate() {
            check(format!("sphere[{i}].material"), s.material)?;
        }
        for (i, q) in self.quads.iter().enumerate() {
            check(format!("quad[{i}].material"), q.material)?;
        }
        for (i, p) in self.planes.iter().enumerate() {
            check(format!("plane[{i}].material"), p.material)?;
        }
        for (i, (_, m)) in self.meshes.iter().enumerate() {
            check(format!("mesh[{i}].material"), *m)?;
        }
        let mut prims = Vec::new();
        for (i, s) in self.spheres.iter().enumerate() {
            prims.push(Prim::Sphere {
                center: s.center,
                radius: s.radius,
                index: i as u32,
            });
        }
        for (i, q) in self.quads.iter().enumerate() {
            prims.push(Prim::quad(q.origin, q.edge_u, q.edge_v, i as u32));
        }
        for (mi, (m, _)) in self.meshes.iter().enumerate() {
            let pos = m.positions();
            for (ti, t) in m.indices().iter().enumerate() {
                let p0 = pos[t[0] as usize];
                let e1 = pos[t[1] as usize] - p0;
                let e2 = pos[t[2] as usize] - p0;
                if e1.cross(e2).length_squared() > 0.0 {
                    prims.push(Prim::Tri {
                        p0,
                        e1,
                        e2,
                        mesh: mi as u32,
                        tri: ti as u32,
                    });
                }
            }
        }
        let bvh = Bvh::build(prims);
        let sphere_only = match bvh.root_leaf() {
            Some(leaf) if self.planes.is_empty() => leaf
                .iter()
                .enumerate()
                .map(|(k, p)| match *p {
                    Prim::Sphere { index, .. } => {
                        let s = &self.spheres[index as usize];
                        Some(LeafSphere {
                            prim: k as u32,
                            index,
                            center: s.center,
                            radius: s.radius,
                            pole: s.pole,
                            material: s.material,
                        })
                    }
                    _ => None,
                })
                .collect::<Option<Vec<_>>>()
                .unwrap_or_default(),
            _ => Vec::new(),
        };
        Ok(Scene {
            camera: self.camera,
            image: self.image,
            lights: self.lights,
            environment: self.environment,
            environment_visible: self.environment_visible,
            materials: self.materials,
            sphere_frames: self.spheres.iter().map(Sphere::pole_frame).collect(),
            spheres: self.spheres,
            quads: self.quads,
            planes: self.planes,
            meshes: self.meshes,
            bvh,
            sphere_only,
        })
    }
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("camera", &self.camera)
            .field("image", &self.image)
            .field("lights", &self.lights)
            .field("environment", &self.environment.as_ref().map(|e| e.size()))
            .field("materials", &self.materials.len())
            .field("spheres", &self.spheres.len())
            .field("quads", &self.quads.len())
            .field("planes", &self.planes.len())
            .field("meshes", &self.meshes.len())
            .finish()
    }
}

/// The surface a shadow ray starts on, when the ray provably cannot hit it again (so the
/// any-hit test can leave it out): a BVH primitive (leaf order) or an infinite plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Skip {
    /// Test everything.
    None,
    /// Leave out this BVH primitive.
    Prim(u32),
    /// Leave out this plane.
    Plane(usize),
}

/// A camera hit as the stream path needs it ([`Scene::primary_frame`]); the fields mean
/// what the [`ShadingPoint`] fields of the same names mean.
#[derive(Clone, Copy, Debug)]
pub(crate) struct HitFrame {
    pub position: DVec3,
    pub geometric_normal: DVec3,
    pub frame: Frame,
    pub material: MaterialId,
    pub skip: Skip,
}

/// A sphere of a sphere-only scene ([`Scene::sphere_only`]) with what the stream path's
/// vectorised camera rays need.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LeafSphere {
    /// Its position in the BVH's leaf order (for [`Skip::Prim`]).
    pub prim: u32,
    /// Its index among the scene's spheres.
    pub index: u32,
    /// Centre (world).
    pub center: DVec3,
    /// Radius, > 0.
    pub radius: f64,
    /// Unit polar axis of the tangent field.
    pub pole: DVec3,
    /// Material.
    pub material: MaterialId,
}

/// A closest hit: distance, the primitive's hit parameters and which surface.
#[derive(Clone, Copy)]
pub(crate) struct ClosestHit {
    t: f64,
    a: f64,
    b: f64,
    what: HitWhat,
}

/// Closest-hit bookkeeping.
#[derive(Clone, Copy)]
enum HitWhat {
    Prim(u32),
    Plane(usize),
}

impl Scene {
    /// The registered shaders, indexed by [`MaterialId`].
    #[must_use]
    pub fn materials(&self) -> &[Arc<dyn Shader>] {
        &self.materials
    }

    /// The shader of a material id (`None` if out of range).
    #[inline]
    #[must_use]
    pub fn shader(&self, id: MaterialId) -> Option<&dyn Shader> {
        self.materials.get(id.0 as usize).map(|s| s.as_ref())
    }

    /// Replace the shader of an existing material (no rebuild). Errors if `id` is unknown.
    pub fn set_material(
        &mut self,
        id: MaterialId,
        shader: Arc<dyn Shader>,
    ) -> Result<(), SceneError> {
        let n = self.materials.len();
        match self.materials.get_mut(id.0 as usize) {
            Some(s) => {
                *s = shader;
                Ok(())
            }
            None => Err(SceneError::invalid(
                "material",
                format!("material id {} does not exist ({n} registered)", id.0),
            )),
        }
    }

    /// Number of primitives in the BVH plus infinite planes.
    #[must_use]
    pub fn primitive_count(&self) -> usize {
        self.spheres.len()
            + self.quads.len()
            + self.planes.len()
            + self
                .meshes
                .iter()
                .map(|(m, _)| m.indices().len())
                .sum::<usize>()
    }

    #[inline(always)]
    fn closest(&self, ray: &Ray) -> Option<(f64, f64, f64, HitWhat)> {
        let mut tmax = f64::INFINITY;
        let mut best = None;
        if let Some(h) = self.bvh.intersect(ray, 0.0, tmax) {
            tmax = h.t;
            best = Some((h.t, h.a, h.b, HitWhat::Prim(h.prim)));
        }
        for (i, p) in self.planes.iter().enumerate() {
            if let Some(t) = p.intersect(ray, tmax) {
                tmax = t;
                best = Some((t, 0.0, 0.0, HitWhat::Plane(i)));
            }
        }
        best
    }

    fn shading_point(
        &self,
        ray: &Ray,
        rd: Option<&RayDifferential>,
    ) -> Option<(f64, ShadingPoint)> {
        let (t, a, b, what) = self.closest(ray)?;
        Some((t, self.surface_at(ray, t, a, b, what, rd, true).0))
    }

    /// The renderer's primary-ray path: the first hit along `ray` as a shading point (with
    /// the footprint when `rd` is given; `uv` left zero on spheres unless `with_uv`), and
    /// which surface its shadow rays may skip.
    #[inline]
    pub(crate) fn primary_hit(
        &self,
        ray: &Ray,
        rd: Option<&RayDifferential>,
        with_uv: bool,
    ) -> Option<(ShadingPoint, Skip)> {
        let (t, a, b, what) = self.closest(ray)?;
        Some(self.surface_at(ray, t, a, b, what, rd, with_uv))
    }

    /// The closest hit along `ray` (stage one of the stream path's primary rays; finish it
    /// with [`Scene::hit_frame`]).
    #[inline]
    pub(crate) fn closest_hit(&self, ray: &Ray) -> Option<ClosestHit> {
        self.closest(ray)
            .map(|(t, a, b, what)| ClosestHit { t, a, b, what })
    }

    /// The renderer's stream path: a closest hit reduced to what a direction-only shader and
    /// the shadow rays need (no texture coordinates, no footprint). Spheres take a short
    /// path; other shapes go through the full shading point.
    #[inline]
    pub(crate) fn hit_frame(&self, ray: &Ray, h: &ClosestHit) -> HitFrame {
        if let HitWhat::Prim(k) = h.what {
            if let Prim::Sphere { index, .. } = *self.bvh.prim(k) {
                return self.sphere_frame(ray, h.t, index as usize, k);
            }
        }
        let (sp, skip) = self.surface_at(ray, h.t, h.a, h.b, h.what, None, false);
        HitFrame {
            position: sp.position,
            geometric_normal: sp.geometric_normal,
            frame: sp.frame,
            material: sp.material,
            skip,
        }
    }

    /// The hit frame at distance `t` along `ray` on sphere `index`, BVH primitive `k`.
    #[inline]
    fn sphere_frame(&self, ray: &Ray, t: f64, index: usize, k: u32) -> HitFrame {
        let sph = &self.spheres[index];
        // The hit lies on the sphere to rounding: scaling by 1/r normalises without
        // the square root and division that `normalize` would add to the chain.
        let n = (ray.at(t) - sph.center) * (1.0 / sph.radius);
        let (mut frame, _) = sph.frame_at(n);
        let mut ng = n;
        let outside = ng.dot(ray.d) < 0.0;
        face_viewer(&mut ng, &mut frame, ray.d);
        HitFrame {
            position: sph.center + n * sph.radius,
            geometric_normal: ng,
            frame,
            material: sph.material,
            skip: if outside { Skip::Prim(k) } else { Skip::None },
        }
    }

    /// [`Scene::hit_frame`] for a hit at distance `t` on sphere `which` of
    /// [`Scene::sphere_only`].
    pub(crate) fn sphere_hit_frame(&self, ray: &Ray, t: f64, which: usize) -> HitFrame {
        let s = &self.sphere_only[which];
        self.sphere_frame(ray, t, s.index as usize, s.prim)
    }

    /// When the scene is nothing but the spheres of one BVH leaf (no planes, quads or
    /// meshes; at most a leaf's worth of spheres), those spheres in leaf order: the stream
    /// path then intersects camera rays with them in flat vectorised loops.
    #[inline]
    pub(crate) fn sphere_only(&self) -> Option<&[LeafSphere]> {
        (!self.sphere_only.is_empty()).then_some(&self.sphere_only[..])
    }

    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn surface_at(
        &self,
        ray: &Ray,
        t: f64,
        a: f64,
        b: f64,
        what: HitWhat,
        rd: Option<&RayDifferential>,
        with_uv: bool,
    ) -> (ShadingPoint, Skip) {
        // Shadow rays leave on the geometric normal's side (`n_g · wi > 0`): they cannot hit
        // the planar primitive they start on again, nor a sphere seen from outside (convex).
        let (g, skip) = match what {
            HitWhat::Plane(i) => (self.planes[i].surface(ray.at(t)), Skip::Plane(i)),
            HitWhat::Prim(k) => match *self.bvh.prim(k) {
                Prim::Sphere { index, .. } => {
                    let i = index as usize;
                    let g = self.spheres[i].surface(&self.sphere_frames[i], ray.at(t), with_uv);
                    let outside = g.ng.dot(ray.d) < 0.0;
                    (g, if outside { Skip::Prim(k) } else { Skip::None })
                }
                Prim::Quad { index, .. } => {
                    (self.quads[index as usize].surface(a, b), Skip::Prim(k))
                }
                Prim::Tri { mesh, tri, .. } => {
                    let (m, mat) = &self.meshes[mesh as usize];
                    (m.surface(tri as usize, a, b, *mat), Skip::Prim(k))
                }
            },
        };
        (finish_shading_point(g, rd, ray), skip)
    }

    /// The first surface along a camera ray, with the pixel footprint from its differentials.
    #[inline]
    #[must_use]
    pub fn intersect(&self, rd: &RayDifferential) -> Option<ShadingPoint> {
        self.shading_point(&rd.ray, Some(rd)).map(|x| x.1)
    }

    /// The first surface along a ray and its distance (no footprint).
    #[must_use]
    pub fn intersect_ray(&self, ray: &Ray) -> Option<(f64, ShadingPoint)> {
        self.shading_point(ray, None)
    }

    /// Is there any surface along `ray` with `0 < t < tmax`?
    #[inline]
    #[must_use]
    pub fn occluded(&self, ray: &Ray, tmax: f64) -> bool {
        self.occluded_skip(ray, tmax, Skip::None)
    }

    /// True when the scene holds exactly one surface (one BVH primitive or one plane): a
    /// shadow ray leaving it with a [`Skip`] other than `None` cannot be blocked.
    #[inline]
    pub(crate) fn single_convex_prim(&self) -> bool {
        self.bvh.len() + self.planes.len() == 1
    }

    /// [`Scene::occluded`] without testing the surface `skip` (see [`Skip`]).
    #[inline]
    pub(crate) fn occluded_skip(&self, ray: &Ray, tmax: f64, skip: Skip) -> bool {
        let prim = match skip {
            Skip::Prim(k) => k,
            _ => u32::MAX,
        };
        if self.bvh.occluded(ray, 0.0, tmax, prim) {
            return true;
        }
        self.planes
            .iter()
            .enumerate()
            .any(|(i, p)| skip != Skip::Plane(i) && p.intersect(ray, tmax).is_some())
    }

    /// Load a scene file (format: `docs/scene-format.md`). Material paths and mesh /
    /// environment files are relative to the scene file's directory.
    pub fn from_toml_file(
        path: &Path,
        resolver: &dyn MaterialResolver,
    ) -> Result<Scene, SceneError> {
        let bytes = meso_core::io::read_limited(path, MAX_SCENE_BYTES).map_err(|source| {
            SceneError::Read {
                file: path.to_path_buf(),
                source,
            }
        })?;
        let text = String::from_utf8(bytes).map_err(|_| SceneError::Read {
            file: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidData, "not UTF-8 text"),
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene::from_toml_str_in(&text, path, &base, resolver)
    }

    /// Parse a scene from TOML text; relative paths resolve against `base_dir`.
    pub fn from_toml_str(
        text: &str,
        base_dir: &Path,
        resolver: &dyn MaterialResolver,
    ) -> Result<Scene, SceneError> {
        Scene::from_toml_str_in(text, Path::new("<scene>"), base_dir, resolver)
    }

    fn from_toml_str_in(
        text: &str,
        file: &Path,
        base: &Path,
        resolver: &dyn MaterialResolver,
    ) -> Result<Scene, SceneError> {
        let parsed: SceneFile = toml::from_str(text).map_err(|e| SceneError::Parse {
            file: file.to_path_buf(),
            message: toml_error_line(text, &e),
        })?;
        parsed.build(base, resolver).map_err(|e| e.in_file(file))
    }
}

/// Longest excerpt of the offending line quoted in a TOML error.
const TOML_EXCERPT_CHARS: usize = 40;

/// A TOML error on one short line: `line L, column C: MESSAGE (at `EXCERPT…`)`, the excerpt at
/// most [`TOML_EXCERPT_CHARS`] characters from the error's position, so a 20 MB line is not
/// echoed.
fn toml_error_line(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim().replace('\n', "; ");
    let Some(span) = e.span() else {
        return message;
    };
    let start = span.start.min(text.len());
    let start = (0..=start)
        .rev()
        .find(|&i| text.is_char_boundary(i))
        .unwrap_or(0);
    let line_start = text[..start].rfind('\n').map_or(0, |i| i + 1);
    let line = text[..start].matches('\n').count() + 1;
    let column = text[line_start..start].chars().count() + 1;
    let rest = text[start..].lines().next().unwrap_or("");
    let mut excerpt: String = rest.chars().take(TOML_EXCERPT_CHARS).collect();
    if rest.chars().nth(TOML_EXCERPT_CHARS).is_some() {
        excerpt.push('…');
    }
    if excerpt.trim().is_empty() {
        format!("line {line}, column {column}: {message}")
    } else {
        format!("line {line}, column {column}: {message} (at `{excerpt}`)")
    }
}

// ---------------------------------------------------------------------------------------------
// The file schema.

type V3 = [f64; 3];

fn default_up() -> V3 {
    [0.0, 1.0, 0.0]
}
fn default_spp() -> u32 {
    16
}
fn one() -> f64 {
    1.0
}
fn one_f32() -> f32 {
    1.0
}
fn yes() -> bool {
    true
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    camera: CameraFile,
    image: ImageFile,
    #[serde(default)]
    object: Vec<ObjectFile>,
    #[serde(default)]
    light: Vec<LightFile>,
    environment: Option<EnvironmentFile>,
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
enum CameraFile {
    Perspective {
        position: V3,
        look_at: V3,
        #[serde(default = "default_up")]
        up: V3,
        fov_deg: f64,
    },
    Orthographic {
        position: V3,
        look_at: V3,
        #[serde(default = "default_up")]
        up: V3,
        width: f64,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ImageFile {
    width: u32,
    height: u32,
    #[serde(default = "default_spp")]
    spp: u32,
    #[serde(default)]
    background: [f32; 3],
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
enum ObjectFile {
    Sphere {
        center: V3,
        radius: f64,
        material: String,
        #[serde(default = "default_up")]
        pole: V3,
    },
    Quad {
        origin: V3,
        edge_u: V3,
        edge_v: V3,
        material: String,
    },
    Plane {
        point: V3,
        normal: V3,
        tangent: Option<V3>,
        #[serde(default = "one")]
        uv_scale: f64,
        material: String,
    },
    Mesh {
        file: String,
        material: String,
        #[serde(default)]
        translate: V3,
        #[serde(default = "one")]
        scale: f64,
    },
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
enum LightFile {
    Point {
        position: V3,
        intensity: V3,
    },
    Directional {
        direction: V3,
        irradiance: V3,
    },
    Linear {
        start: V3,
        end: V3,
        intensity: V3,
    },
    Sphere {
        center: V3,
        radius: f64,
        radiance: V3,
    },
    Rectangle {
        corner: V3,
        edge_u: V3,
        edge_v: V3,
        radiance: V3,
        #[serde(default)]
        two_sided: bool,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvironmentFile {
    file: String,
    #[serde(default = "one_f32")]
    scale: f32,
    #[serde(default)]
    rotation_deg: f64,
    #[serde(default = "yes")]
    visible: bool,
}

fn v(a: V3) -> DVec3 {
    DVec3::from_array(a)
}

/// Rename `sphere[0].x` (the builder's name) to the file's `object[i].x`.
fn rename(e: SceneError, prefix: &str) -> SceneError {
    match e {
        SceneError::Invalid {
            file,
            field,
            problem,
        } => {
            let rest = field.split_once('.').map_or("", |(_, r)| r);
            SceneError::Invalid {
                file,
                field: if rest.is_empty() {
                    prefix.to_string()
                } else {
                    format!("{prefix}.{rest}")
                },
                problem,
            }
        }
        e => e,
    }
}

impl SceneFile {
    fn build(self, base: &Path, resolver: &dyn MaterialResolver) -> Result<Scene, SceneError> {
        let camera = match self.camera {
            CameraFile::Perspective {
                position,
                look_at,
                up,
                fov_deg,
            } => Camera::new(
                Projection::Perspective { fov_deg },
                v(position),
                v(look_at),
                v(up),
            )?,
            CameraFile::Orthographic {
                position,
                look_at,
                up,
                width,
            } => Camera::new(
                Projection::Orthographic { width },
                v(position),
                v(look_at),
                v(up),
            )?,
        };
        let image = ImageSettings {
            width: self.image.width,
            height: self.image.height,
            spp: self.image.spp,
            background: self.image.background,
        };
        image.validate()?;
        let mut b = SceneBuilder::new(camera, image);
        let mut cache: HashMap<PathBuf, MaterialId> = HashMap::new();
        let mut resolve =
            |b: &mut SceneBuilder, field: String, m: &str| -> Result<MaterialId, SceneError> {
                if m.trim().is_empty() {
                    return Err(SceneError::invalid(field, "must name a material file"));
                }
                let p = base.join(m);
                if let Some(id) = cache.get(&p) {
                    return Ok(*id);
                }
                let shader = resolver.resolve(&p).map_err(|e| SceneError::Material {
                    file: None,
                    field,
                    resolved: p.clone(),
                    message: e.to_string(),
                })?;
                let id = b.material(shader);
                cache.insert(p, id);
                Ok(id)
            };
        for (i, o) in self.object.into_iter().enumerate() {
            let pre = format!("object[{i}]");
            match o {
                ObjectFile::Sphere {
                    center,
                    radius,
                    material,
                    pole,
                } => {
                    let m = resolve(&mut b, format!("{pre}.material"), &material)?;
                    b.sphere(v(center), radius, v(pole), m)
                        .map_err(|e| rename(e, &pre))?;
                }
                ObjectFile::Quad {
                    origin,
                    edge_u,
                    edge_v,
                    material,
                } => {
                    let m = resolve(&mut b, format!("{pre}.material"), &material)?;
                    b.quad(v(origin), v(edge_u), v(edge_v), m)
                        .map_err(|e| rename(e, &pre))?;
                }
                ObjectFile::Plane {
                    point,
                    normal,
                    tangent,
                    uv_scale,
                    material,
                } => {
                    let m = resolve(&mut b, format!("{pre}.material"), &material)?;
                    let n = v(normal);
                    let t = match tangent {
                        Some(t) => v(t),
                        None => meso_core::frame::Frame::from_normal(n.normalize_or_zero()).t,
                    };
                    b.plane(v(point), n, t, uv_scale, m)
                        .map_err(|e| rename(e, &pre))?;
                }
                ObjectFile::Mesh {
                    file,
                    material,
                    translate,
                    scale,
                } => {
                    positive(&format!("{pre}.scale"), scale)?;
                    finite(&format!("{pre}.translate"), v(translate))?;
                    let m = resolve(&mut b, format!("{pre}.material"), &material)?;
                    let mut mesh = Mesh::from_obj(&base.join(&file))?;
                    mesh.transform(scale, v(translate));
                    b.mesh(Arc::new(mesh), m);
                }
            }
        }
        for (i, l) in self.light.into_iter().enumerate() {
            let light = match l {
                LightFile::Point {
                    position,
                    intensity,
                } => Light::Point {
                    position: v(position),
                    intensity: v(intensity),
                },
                LightFile::Directional {
                    direction,
                    irradiance,
                } => Light::Directional {
                    direction: v(direction),
                    irradiance: v(irradiance),
                },
                LightFile::Linear {
                    start,
                    end,
                    intensity,
                } => Light::Linear {
                    start: v(start),
                    end: v(end),
                    intensity: v(intensity),
                },
                LightFile::Sphere {
                    center,
                    radius,
                    radiance,
                } => Light::Sphere {
                    center: v(center),
                    radius,
                    radiance: v(radiance),
                },
                LightFile::Rectangle {
                    corner,
                    edge_u,
                    edge_v,
                    radiance,
                    two_sided,
                } => Light::Rectangle {
                    corner: v(corner),
                    edge_u: v(edge_u),
                    edge_v: v(edge_v),
                    radiance: v(radiance),
                    two_sided,
                },
            };
            validate_light(&format!("light[{i}]"), &light)?;
            b.light(light)?;
        }
        if let Some(env) = self.environment {
            if !(env.scale.is_finite() && env.scale >= 0.0) {
                return Err(SceneError::invalid(
                    "environment.scale",
                    format!("must be finite and >= 0, got {}", Num(f64::from(env.scale))),
                ));
            }
            if !env.rotation_deg.is_finite() {
                return Err(SceneError::invalid(
                    "environment.rotation_deg",
                    "must be finite",
                ));
            }
            let map = EnvironmentMap::from_file(
                &base.join(&env.file),
                env.scale,
                env.rotation_deg.to_radians(),
            )?;
            b.environment(Arc::new(map), env.visible);
        }
        b.build()
    }
}
