//! Scenes: built in code with [`SceneBuilder`] or loaded from a TOML file
//! (`docs/scene-format.md`) with [`Scene::from_toml_file`].
//!
//! Material references in scene files are paths relative to the scene file; they are turned
//! into shaders by a caller-supplied [`MaterialResolver`], so the renderer does not depend on
//! any material file format. Each distinct path is resolved once.
//!
//! The module is split by concern: the builder and its validation (`builder`), the
//! intersection queries the renderer asks of a built scene (`query`), and the TOML scene
//! format (`file`).

mod builder;
mod file;
mod query;

pub use builder::{validate_light, SceneBuilder};
pub use file::{MaterialResolver, ResolveError};
pub(crate) use query::{LeafSphere, Skip};

pub use crate::limits::{MAX_ENVIRONMENT_BYTES, MAX_OBJ_BYTES, MAX_SCENE_BYTES};

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::error::SceneError;
use crate::geometry::{MaterialId, Mesh, Plane, Quad, Sphere};
use crate::light::{EnvironmentMap, Light};
use crate::shader::Shader;
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

impl Scene {
    /// The registered shaders, indexed by [`MaterialId`].
    #[must_use]
    pub fn materials(&self) -> &[Arc<dyn Shader>] {
        &self.materials
    }

    /// Whether every material read sound data while shading ([`Shader::check_sources`]): the
    /// first material's error, naming its file, when a file it reads as it goes changed in
    /// place during the render. Check after rendering, before writing the image.
    ///
    /// # Errors
    /// The first failing material's message.
    pub fn check_sources(&self) -> Result<(), String> {
        self.materials.iter().try_for_each(|m| m.check_sources())
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
}
