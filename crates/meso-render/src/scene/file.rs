//! The TOML scene format (`docs/scene-format.md`): [`Scene::from_toml_file`] /
//! [`Scene::from_toml_str`], with material references turned into shaders by a caller-supplied
//! [`MaterialResolver`].

use super::builder::{finite, positive};
use super::{validate_light, ImageSettings, Scene, SceneBuilder, MAX_SCENE_BYTES};
use crate::camera::{Camera, Projection};
use crate::error::SceneError;
use crate::geometry::{MaterialId, Mesh};
use crate::light::{EnvironmentMap, Light};
use crate::shader::Shader;
use glam::DVec3;
use meso_core::display::Num;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

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

impl Scene {
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
