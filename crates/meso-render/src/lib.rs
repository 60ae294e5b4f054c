//! # meso-render
//!
//! A fast CPU renderer for *multiple surfaces* (Fournier 1992, §4): each surface point may
//! carry several normals, each adding a Phong term, so shading is a plain sum of ordinary
//! shading operations — `lobes × lights × pixels` is the inner loop, kept flat and
//! allocation-free.
//!
//! * [`camera`]: perspective / orthographic cameras with ray differentials (pixel footprint).
//! * [`geometry`]: spheres, quads, planes, OBJ meshes; consistent tangent frames; the
//!   [`ShadingPoint`] of a hit. A binned-SAH BVH accelerates intersection.
//! * [`shader`]: the [`Shader`] trait materials implement (BRDF in the local frame), and the
//!   built-in [`Lambert`] and [`PhongLobes`] shaders.
//! * [`light`]: point, directional, linear, spherical and rectangular area lights, and an
//!   importance-sampled [`EnvironmentMap`].
//! * [`scene`]: [`Scene`] / [`SceneBuilder`], and the TOML scene format
//!   (`docs/scene-format.md`) with a caller-supplied [`MaterialResolver`]; [`limits`]: the
//!   largest scene, mesh and environment-map files read.
//! * [`render()`]: tiles in parallel (rayon), Owen-scrambled Sobol sampling, progress callback.
//! * [`Image`]: linear EXR and tone-mapped sRGB PNG output.
//!
//! Conventions are those of `meso_core::frame` (local frame: normal `+z`, tangent `+x`).
//!
//! # Performance
//! Build a [`Scene`] once (BVH, cached frames), then call [`render()`] as often as needed;
//! nothing is allocated per sample (one scratch and one pixel buffer per tile). Measure with
//! `cargo bench -p meso-render --bench sphere -- --warm-up-time 1 --measurement-time 3`
//! (1024² sphere, 7-lobe [`PhongLobes`], 4 point lights, 1 spp; and a 384² preview) or, on
//! a loaded machine, `cargo run --release -p meso-render --example bench_sphere -- 1024 10`,
//! which also reports process CPU time per frame.
//!
//! ```
//! use meso_render::*;
//! use glam::DVec3;
//! use std::sync::Arc;
//!
//! let cam = Camera::new(Projection::Orthographic { width: 2.5 }, DVec3::new(0.0, 0.0, 5.0),
//!                       DVec3::ZERO, DVec3::Y).unwrap();
//! let mut b = SceneBuilder::new(cam, ImageSettings { width: 32, height: 32, spp: 1, background: [0.0; 3] });
//! let white = b.material(Arc::new(Lambert { albedo: [1.0; 3] }));
//! b.sphere(DVec3::ZERO, 1.0, DVec3::Y, white).unwrap();
//! b.light(Light::Directional { direction: DVec3::Z, irradiance: DVec3::ONE }).unwrap();
//! let scene = b.build().unwrap();
//! let img = render(&scene, &RenderOptions::default(), None);
//! // The centre pixel sees the sphere head-on: L = albedo/π · E.
//! let c = img.get(16, 16)[0];
//! assert!((c - 1.0 / std::f32::consts::PI).abs() < 1e-3);
//! ```
#![warn(missing_docs)]

mod bvh;
pub mod camera;
pub mod error;
pub mod geometry;
pub mod image;
pub mod light;
pub mod limits;
pub mod mapped;
pub mod material;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod shader;
pub mod textured;

pub use camera::{Camera, Projection, Ray, RayDifferential};
pub use error::{ImageError, SceneError};
pub use geometry::{MaterialId, Mesh, Plane, Quad, ShadingPoint, Sphere};
pub use image::Image;
pub use light::{EnvironmentMap, Light, LightSample};
pub use mapped::{
    default_box_detail, BumpMapped, NdfMapped, BROAD_BOX_DETAIL, DEFAULT_MAX_BOX_DETAIL,
    GLOSSY_BOX_DETAIL_FROM, MAX_BOX_DETAIL, MEMO_BYTES,
};
pub use material::MaterialShader;
pub use render::{render, render_pixel, shade, shade_with, RenderOptions, ShadeScratch};
pub use scene::{ImageSettings, MaterialResolver, ResolveError, Scene, SceneBuilder};
pub use shader::{Lambert, PhongLobes, Shader};
pub use textured::{load_textured, resolve_material_file};
