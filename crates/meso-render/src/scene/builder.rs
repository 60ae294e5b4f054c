//! [`SceneBuilder`]: geometry, materials and lights collected and validated, then built into a
//! [`Scene`] with its BVH; the range checks shared with the scene file.

use super::{ImageSettings, LeafSphere, Scene};
use crate::bvh::{Bvh, Prim};
use crate::camera::Camera;
use crate::error::SceneError;
use crate::geometry::{MaterialId, Mesh, Plane, Quad, Sphere};
use crate::light::{EnvironmentMap, Light};
use crate::limits::MAX_LIGHT_VALUE;
use crate::sampling::MAX_SAMPLES_PER_PIXEL;
use crate::shader::Shader;
use glam::DVec3;
use meso_core::display::Num;
use std::sync::Arc;

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

pub(super) use crate::error::finite;

pub(super) fn positive(field: &str, x: f64) -> Result<(), SceneError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(SceneError::invalid(
            field,
            format!("must be a finite number > 0, got {}", Num(x)),
        ))
    }
}

/// A light's colour (or the background's): every channel in [0, [`MAX_LIGHT_VALUE`]].
fn nonneg_rgb(field: &str, v: DVec3) -> Result<(), SceneError> {
    if v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= MAX_LIGHT_VALUE {
        Ok(())
    } else {
        Err(SceneError::invalid(
            field,
            format!(
                "must be finite, non-negative and at most {} in every channel, got {}",
                Num(MAX_LIGHT_VALUE),
                crate::error::vec3_text(v)
            ),
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
