//! Shapes, triangle meshes and the shading point a hit produces.
//!
//! **Texture coordinates follow glTF**: `uv = (0, 0)` is the texture image's top-left corner,
//! `u` grows to the right and `v` grows **down** the image (docs/conventions.md). OBJ files store
//! OpenGL's `v` (growing up the image); [`Mesh::from_obj`] turns it into `1 − v` on load, as
//! glTF exporters do, so an OBJ from Blender shows its textures the right way up.
//!
//! Every hit carries a **consistent tangent frame** (the paper's §4 requirement: lobe normals
//! are defined in the local frame, so the tangent must be defined everywhere):
//!
//! * [`Sphere`]: `u = φ/2π`, `v = θ/π` with θ measured from the sphere's `pole` (default
//!   `+y`) and φ around it (an equirectangular image: its top row at the pole); the tangent is
//!   `∂p/∂φ` (along the parallels, i.e. around the polar axis), the bitangent points towards
//!   the pole (up the image, along `−∂p/∂v`). At the two poles the tangent is undefined and an
//!   arbitrary orthonormal one is used.
//! * [`Quad`]: `p = origin + s·edge_u + t·edge_v`, `(s, t) ∈ [0,1]²`, `uv = (s, 1 − t)`:
//!   `origin` is the image's bottom-left corner, `edge_u` runs along its bottom edge and
//!   `edge_v` up its left edge; normal `edge_u × edge_v`; tangent along `edge_u`.
//! * [`Plane`]: infinite; tangent = the given tangent made orthogonal to the normal, bitangent
//!   `b = n × t`; `uv = ((p − point)·t, −(p − point)·b) / uv_scale` (the image's up along `b`).
//! * [`Mesh`]: per-vertex tangents from UV derivatives (MikkTSpace-style: per-triangle
//!   `∂p/∂u`, accumulated at each corner weighted by the corner angle, then Gram–Schmidt against
//!   the vertex normal). Without UVs the tangent is world `+x` projected onto the tangent plane
//!   (world `+y` where the normal is near `±x`).
//!
//! In every case the shading frame is right-handed (`t × b = n`, [`Frame`]), the tangent is
//! along `∂p/∂u`, and the bitangent points **up the texture image**: it has a positive
//! component along `−∂p/∂v` (except on meshes with mirrored UVs, where `b = n × t` points along
//! `∂p/∂v`). A map's +y (green = up in a `gl` normal map) is therefore the frame's `b`. When
//! the viewer is behind the surface, `n` and `b` are flipped (`t` kept) so that the frame faces
//! the viewer.

use crate::camera::{Ray, RayDifferential};
use crate::error::SceneError;
use glam::{DVec2, DVec3};
use meso_core::frame::Frame;
use std::f64::consts::PI;
use std::path::Path;

/// Index of a material in a scene (returned by `SceneBuilder::material`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MaterialId(pub u32);

/// A sphere (world units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: DVec3,
    /// Radius, > 0.
    pub radius: f64,
    /// Unit polar axis of the `(θ, φ)` parameterisation and of the tangent field (default `+y`).
    pub pole: DVec3,
    /// Material.
    pub material: MaterialId,
}

/// A parallelogram `origin + s·edge_u + t·edge_v`, `(s, t) ∈ [0,1]²`, two-sided, textured
/// the right way up: `uv = (s, 1 − t)` (glTF's `v` grows down the image).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quad {
    /// The texture image's bottom-left corner, `uv = (0, 1)`.
    pub origin: DVec3,
    /// Edge to the image's bottom-right corner, `uv = (1, 1)`; the tangent direction.
    pub edge_u: DVec3,
    /// Edge to the image's top-left corner, `uv = (0, 0)`.
    pub edge_v: DVec3,
    /// Material.
    pub material: MaterialId,
}

/// An infinite plane, two-sided.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// A point of the plane (`uv = 0` there: a corner of the texture image's top-left copy).
    pub point: DVec3,
    /// Unit normal.
    pub normal: DVec3,
    /// Tangent direction (made orthogonal to the normal).
    pub tangent: DVec3,
    /// World units per unit of `uv`, > 0.
    pub uv_scale: f64,
    /// Material.
    pub material: MaterialId,
}

/// A triangle mesh with per-vertex normals (optional), UVs (optional) and tangents (always
/// present: generated when not supplied). Triangles are counter-clockwise seen from the front.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    positions: Vec<DVec3>,
    normals: Option<Vec<DVec3>>,
    uvs: Option<Vec<DVec2>>,
    tangents: Vec<DVec3>,
    indices: Vec<[u32; 3]>,
}

/// Refuse OBJ element indices that cannot refer to anything: in `f`, `l` and `p` lines, an
/// index of 0, a relative (negative) index reaching before the first position, texture
/// coordinate or normal declared so far, an index larger than the file's line count, or one
/// that is not a number that fits. The OBJ reader computes offsets from such indices with
/// unchecked arithmetic (found by the `obj` fuzz target: `f 1/-1111111111111111` and
/// `f 1/-11/1` after three `vt` overflowed tobj 4.0.5's `vt * 2 + 1`).
fn check_obj_indices(bytes: &[u8]) -> Result<(), String> {
    let lines = bytes.split(|&b| b == b'\n').count() as u64;
    // Positions, texture coordinates and normals declared so far.
    let mut declared = [0u64; 3];
    for (n, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => declared[0] += 1,
            Some("vt") => declared[1] += 1,
            Some("vn") => declared[2] += 1,
            Some("f" | "l" | "p") => {
                for word in words.take_while(|w| !w.starts_with('#')) {
                    for (kind, part) in word.split('/').enumerate().take(3) {
                        if part.is_empty() {
                            continue;
                        }
                        let ok = part.parse::<i64>().is_ok_and(|i| {
                            i != 0
                                && if i < 0 {
                                    i.unsigned_abs() <= declared[kind]
                                } else {
                                    i.unsigned_abs() <= lines
                                }
                        });
                        if !ok {
                            return Err(format!(
                                "line {}: index `{}` refers to no element",
                                n + 1,
                                part.chars().take(24).collect::<String>()
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Everything a shader may need about a surface point seen along a camera ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingPoint {
    /// Position (world).
    pub position: DVec3,
    /// Unit geometric normal, facing the viewer.
    pub geometric_normal: DVec3,
    /// Shading frame (world vectors): tangent `t` (+x local), bitangent `b` (+y), normal `n`
    /// (+z), facing the viewer.
    pub frame: Frame,
    /// Texture coordinates, glTF's orientation: `(0, 0)` at the texture image's top-left
    /// corner, `v` growing down the image (module docs).
    pub uv: DVec2,
    /// `∂p/∂u` (world units per unit u).
    pub dpdu: DVec3,
    /// `∂p/∂v` (world units per unit v).
    pub dpdv: DVec3,
    /// Change of position per pixel step in x (zero if no differentials).
    pub dpdx: DVec3,
    /// Change of position per pixel step in y.
    pub dpdy: DVec3,
    /// Change of `uv` per pixel step in x.
    pub duvdx: DVec2,
    /// Change of `uv` per pixel step in y.
    pub duvdy: DVec2,
    /// Where a filtering material centres its footprint, in `uv` (usually `uv`). With several
    /// samples per pixel the renderer moves it to the centre of the sample's stratum of the
    /// pixel and shrinks the differentials (`dpdx` … `duvdy`) to the stratum, so that the
    /// samples' footprints tile the pixel (`meso_render::render` module docs).
    pub filter_uv: DVec2,
    /// The material of the surface.
    pub material: MaterialId,
}

impl ShadingPoint {
    /// The pixel footprint in `uv` units: the longer of the two per-pixel `uv` steps.
    /// A level-of-detail selector uses `log2(footprint · texture_resolution)`.
    #[must_use]
    pub fn uv_footprint(&self) -> f64 {
        self.duvdx.length().max(self.duvdy.length())
    }

    /// The pixel footprint in world units: the longer of the two per-pixel position steps.
    #[must_use]
    pub fn world_footprint(&self) -> f64 {
        self.dpdx.length().max(self.dpdy.length())
    }
}

impl Sphere {
    /// The shading frame at the unit outward normal `n` (tangent along the parallels, see
    /// the module docs) and `sin θ` from the pole.
    #[inline(always)]
    pub(crate) fn frame_at(&self, n: DVec3) -> (Frame, f64) {
        let along = self.pole.cross(n); // ∂p/∂φ direction, length sin θ
        let sin_t = along.length();
        let t = if sin_t > 1e-12 {
            along * (1.0 / sin_t)
        } else {
            Frame::from_normal(n).t
        };
        (
            Frame {
                t,
                b: n.cross(t),
                n,
            },
            sin_t,
        )
    }

    /// The local frame of the parameterisation: its `n` is the pole; φ = 0 along its `t`.
    #[must_use]
    pub fn pole_frame(&self) -> Frame {
        let reference = if self.pole.x.abs() < 0.9 {
            DVec3::X
        } else {
            DVec3::Z
        };
        Frame::from_normal_tangent(self.pole, reference)
    }
}

/// Peak memory of loading an OBJ file of `file_bytes` bytes ([`Mesh::from_obj`]) and building
/// its BVH, estimated from the file's size: 48 bytes per byte of OBJ (a file of nothing but
/// `f 1 2 3` lines measured 42: 334 MB of peak RSS for 8 MB, docs/limits.md).
#[must_use]
pub fn obj_bytes(file_bytes: u64) -> u64 {
    file_bytes.saturating_mul(48)
}

impl Mesh {
    /// A mesh from raw arrays. `normals`, `uvs` and `tangents`, when given, are per vertex;
    /// `uvs` follow glTF (`v` grows down the texture image, see the module docs).
    /// Missing tangents are generated (see the module docs). Inconsistent arrays give a
    /// [`SceneError::Invalid`] on the field `mesh` naming the problem.
    pub fn new(
        positions: Vec<DVec3>,
        normals: Option<Vec<DVec3>>,
        uvs: Option<Vec<DVec2>>,
        tangents: Option<Vec<DVec3>>,
        indices: Vec<[u32; 3]>,
    ) -> Result<Mesh, SceneError> {
        let e = |m: String| SceneError::invalid("mesh", m);
        let n = positions.len();
        if indices.is_empty() {
            return Err(e("contains no triangles".into()));
        }
        if let Some(bad) = positions.iter().position(|p| !p.is_finite()) {
            return Err(e(format!("vertex {bad} has a non-finite position")));
        }
        if let Some(bad) = normals
            .as_ref()
            .and_then(|ns| ns.iter().position(|v| !v.is_finite()))
        {
            return Err(e(format!("vertex {bad} has a non-finite normal")));
        }
        if let Some(bad) = uvs
            .as_ref()
            .and_then(|uv| uv.iter().position(|v| !v.is_finite()))
        {
            return Err(e(format!(
                "vertex {bad} has a non-finite texture coordinate"
            )));
        }
        for (name, len) in [
            ("normals", normals.as_ref().map(Vec::len)),
            ("uvs", uvs.as_ref().map(Vec::len)),
            ("tangents", tangents.as_ref().map(Vec::len)),
        ] {
            if let Some(l) = len {
                if l != n {
                    return Err(e(format!("{name} has {l} entries for {n} vertices")));
                }
            }
        }
        if let Some((t, _)) = indices
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
        {
            return Err(e(format!(
                "triangle {t} refers to a vertex beyond the {n} vertices"
            )));
        }
        let normals = normals.map(|ns| {
            ns.into_iter()
                .map(|v| {
                    if v.length() > 0.0 && v.is_finite() {
                        v.normalize()
                    } else {
                        DVec3::ZERO
                    }
                })
                .collect::<Vec<_>>()
        });
        let mut mesh = Mesh {
            positions,
            normals,
            uvs,
            tangents: Vec::new(),
            indices,
        };
        mesh.tangents = match tangents {
            Some(t) => t,
            None => mesh.generate_tangents(),
        };
        Ok(mesh)
    }

    /// Load an OBJ file (all its objects merged, polygons triangulated). Errors name the file.
    pub fn from_obj(path: &Path) -> Result<Mesh, SceneError> {
        let err = |message: String| SceneError::Mesh {
            file: path.to_path_buf(),
            message,
        };
        if let Some(problem) = crate::error::input_path_problem(path) {
            return Err(err(problem));
        }
        // (A file over the size limit gets that error from the reader below.)
        if let Some(len) = std::fs::metadata(path)
            .ok()
            .map(|m| m.len())
            .filter(|&n| n <= crate::limits::MAX_OBJ_BYTES)
        {
            meso_core::budget::check(path, "loading the OBJ mesh", obj_bytes(len))
                .map_err(|e| SceneError::Budget(e.to_string()))?;
        }
        // Some LoadOptions fields exist only with tobj features: keep the struct update.
        #[allow(clippy::needless_update)]
        let opts = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ignore_points: true,
            ignore_lines: true,
            ..Default::default()
        };
        let bytes = meso_core::io::read_limited(path, crate::limits::MAX_OBJ_BYTES)
            .map_err(|e| err(format!("cannot read: {e}")))?;
        check_obj_indices(&bytes).map_err(|e| err(format!("broken OBJ: {e}")))?;
        // `mtllib` files are never opened: materials come from the scene, not the OBJ.
        let (models, _materials) = tobj::load_obj_buf(&mut bytes.as_slice(), &opts, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| err(format!("broken OBJ: {e}")))?;
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        let mut uvs = Vec::new();
        let mut indices = Vec::new();
        let mut all_normals = true;
        let mut all_uvs = true;
        for m in &models {
            let mm = &m.mesh;
            let base = positions.len() as u32;
            let nv = mm.positions.len() / 3;
            positions.extend(
                mm.positions
                    .chunks_exact(3)
                    .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))),
            );
            if mm.normals.len() == 3 * nv {
                normals.extend(
                    mm.normals
                        .chunks_exact(3)
                        .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))),
                );
            } else {
                all_normals = false;
            }
            if mm.texcoords.len() == 2 * nv {
                uvs.extend(
                    mm.texcoords
                        .chunks_exact(2)
                        // OBJ's v grows up the image; meso's (glTF's) grows down it.
                        .map(|p| DVec2::new(f64::from(p[0]), 1.0 - f64::from(p[1]))),
                );
            } else {
                all_uvs = false;
            }
            if mm.indices.len() % 3 != 0 {
                return Err(err(format!(
                    "object `{}` has an index count not divisible by 3",
                    m.name
                )));
            }
            indices.extend(
                mm.indices
                    .chunks_exact(3)
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
        }
        Mesh::new(
            positions,
            all_normals.then_some(normals),
            all_uvs.then_some(uvs),
            None,
            indices,
        )
        .map_err(|e| match e {
            SceneError::Invalid { problem, .. } => err(problem),
            e => e,
        })
    }

    /// Vertex positions.
    #[must_use]
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }
    /// Per-vertex unit normals, if the mesh has them.
    #[must_use]
    pub fn normals(&self) -> Option<&[DVec3]> {
        self.normals.as_deref()
    }
    /// Per-vertex UVs (glTF's orientation: `v` down the image), if the mesh has them.
    #[must_use]
    pub fn uvs(&self) -> Option<&[DVec2]> {
        self.uvs.as_deref()
    }
    /// Per-vertex unit tangents (given or generated).
    #[must_use]
    pub fn tangents(&self) -> &[DVec3] {
        &self.tangents
    }
    /// Triangles as vertex indices.
    #[must_use]
    pub fn indices(&self) -> &[[u32; 3]] {
        &self.indices
    }

    /// Apply `p ↦ scale·p + translate` (uniform scale > 0 keeps normals and tangents).
    pub fn transform(&mut self, scale: f64, translate: DVec3) {
        for p in &mut self.positions {
            *p = *p * scale + translate;
        }
    }

    fn face_normal_raw(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.indices[t];
        let (pa, pb, pc) = (
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        );
        (pb - pa).cross(pc - pa)
    }

    /// The unit normal at each vertex: the given one, or the area-weighted face normals.
    fn vertex_normals(&self) -> Vec<DVec3> {
        if let Some(n) = &self.normals {
            return n.clone();
        }
        let mut acc = vec![DVec3::ZERO; self.positions.len()];
        for t in 0..self.indices.len() {
            let fnrm = self.face_normal_raw(t);
            for &i in &self.indices[t] {
                acc[i as usize] += fnrm;
            }
        }
        acc.into_iter().map(|v| v.normalize_or_zero()).collect()
    }

    fn generate_tangents(&self) -> Vec<DVec3> {
        let normals = self.vertex_normals();
        let mut acc = vec![DVec3::ZERO; self.positions.len()];
        if let Some(uvs) = &self.uvs {
            for tri in &self.indices {
                let p = tri.map(|i| self.positions[i as usize]);
                let uv = tri.map(|i| uvs[i as usize]);
                let (dp1, dp2) = (p[1] - p[0], p[2] - p[0]);
                let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
                let det = d1.x * d2.y - d2.x * d1.y;
                if det.abs() < 1e-20 {
                    continue;
                }
                let t = ((dp1 * d2.y - dp2 * d1.y) / det).normalize_or_zero();
                for k in 0..3 {
                    let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
                    let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
                    let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
                    acc[tri[k] as usize] += t * angle;
                }
            }
        }
        acc.iter()
            .zip(&normals)
            .map(|(&t, &n)| {
                let t = if t.length_squared() > 1e-30 {
                    t
                } else if n.x.abs() < 0.9 {
                    DVec3::X
                } else {
                    DVec3::Y
                };
                if n == DVec3::ZERO {
                    t.normalize_or_zero()
                } else {
                    Frame::from_normal_tangent(n, t).t
                }
            })
            .collect()
    }
}

/// Solve `dp ≈ du·dpdu + dv·dpdv` in the least-squares sense.
#[inline]
fn solve_uv(dpdu: DVec3, dpdv: DVec3, dp: DVec3) -> DVec2 {
    let a = dpdu.dot(dpdu);
    let b = dpdu.dot(dpdv);
    let c = dpdv.dot(dpdv);
    let det = a * c - b * b;
    if det.abs() < 1e-300 || !det.is_finite() {
        return DVec2::ZERO;
    }
    let r0 = dpdu.dot(dp);
    let r1 = dpdv.dot(dp);
    DVec2::new((c * r0 - b * r1) / det, (a * r1 - b * r0) / det)
}

/// The raw data a shape's intersection routine reports, turned into a [`ShadingPoint`] by
/// [`finish_shading_point`].
pub(crate) struct SurfaceGeom {
    pub position: DVec3,
    pub ng: DVec3,
    pub ns: DVec3,
    pub tangent: DVec3,
    pub uv: DVec2,
    pub dpdu: DVec3,
    pub dpdv: DVec3,
    pub material: MaterialId,
    /// The shading frame when the shape already has it orthonormal (`t = tangent`,
    /// `n = ns`); otherwise it is built from `ns` and `tangent` by Gram–Schmidt.
    pub frame: Option<Frame>,
}

/// Turn the geometric normal and the shading frame towards the viewer looking along `d`:
/// when `ng · d > 0`, `ng`, `n` and `b` are negated and the tangent kept (the frame stays
/// right-handed).
#[inline(always)]
pub(crate) fn face_viewer(ng: &mut DVec3, frame: &mut Frame, d: DVec3) {
    if ng.dot(d) > 0.0 {
        *ng = -*ng;
        frame.n = -frame.n;
        frame.b = -frame.b;
    }
}

/// Orient the frame towards the viewer and add the ray-differential footprint.
#[inline]
pub(crate) fn finish_shading_point(
    g: SurfaceGeom,
    rd: Option<&RayDifferential>,
    ray: &Ray,
) -> ShadingPoint {
    let mut ng = g.ng;
    let mut frame = match g.frame {
        Some(f) => f,
        None => Frame::from_normal_tangent(g.ns, g.tangent),
    };
    face_viewer(&mut ng, &mut frame, ray.d);
    let (mut dpdx, mut dpdy) = (DVec3::ZERO, DVec3::ZERO);
    let (mut duvdx, mut duvdy) = (DVec2::ZERO, DVec2::ZERO);
    if let Some(rd) = rd {
        let d_plane = ng.dot(g.position);
        let transfer = |o: DVec3, d: DVec3| -> Option<DVec3> {
            let den = ng.dot(d);
            if den.abs() < 1e-300 {
                return None;
            }
            let t = (d_plane - ng.dot(o)) / den;
            Some(o + d * t)
        };
        if let (Some(px), Some(py)) = (
            transfer(rd.ray.o + rd.dodx, rd.ray.d + rd.dddx),
            transfer(rd.ray.o + rd.dody, rd.ray.d + rd.dddy),
        ) {
            dpdx = px - g.position;
            dpdy = py - g.position;
            duvdx = solve_uv(g.dpdu, g.dpdv, dpdx);
            duvdy = solve_uv(g.dpdu, g.dpdv, dpdy);
        }
    }
    ShadingPoint {
        position: g.position,
        geometric_normal: ng,
        frame,
        uv: g.uv,
        dpdu: g.dpdu,
        dpdv: g.dpdv,
        dpdx,
        dpdy,
        duvdx,
        duvdy,
        filter_uv: g.uv,
        material: g.material,
    }
}

impl Sphere {
    /// The surface at `p`; `pf` is [`Sphere::pole_frame`] (cached by the scene). With
    /// `with_uv == false` the texture coordinates (an `acos` and an `atan2`) are not computed
    /// and `uv` is left zero (for shaders that do not read them).
    #[inline]
    pub(crate) fn surface(&self, pf: &Frame, p: DVec3, with_uv: bool) -> SurfaceGeom {
        let n = (p - self.center).normalize();
        let uv = if with_uv {
            let l = pf.to_local(n);
            let theta = l.z.clamp(-1.0, 1.0).acos();
            let mut phi = l.y.atan2(l.x);
            if phi < 0.0 {
                phi += 2.0 * PI;
            }
            DVec2::new(phi / (2.0 * PI), theta / PI)
        } else {
            DVec2::ZERO
        };
        let (frame, sin_t) = self.frame_at(n);
        let (t, b) = (frame.t, frame.b);
        SurfaceGeom {
            frame: Some(frame),
            position: self.center + n * self.radius,
            ng: n,
            ns: n,
            tangent: t,
            uv,
            dpdu: t * (2.0 * PI * self.radius * sin_t),
            dpdv: b * (-PI * self.radius),
            material: self.material,
        }
    }
}

impl Quad {
    /// The surface at the quad's parameters `(s, t)`: `origin + s·edge_u + t·edge_v`.
    pub(crate) fn surface(&self, u: f64, v: f64) -> SurfaceGeom {
        let n = self.edge_u.cross(self.edge_v).normalize();
        SurfaceGeom {
            position: self.origin + self.edge_u * u + self.edge_v * v,
            ng: n,
            ns: n,
            tangent: self.edge_u,
            uv: DVec2::new(u, 1.0 - v),
            dpdu: self.edge_u,
            dpdv: -self.edge_v,
            material: self.material,

            frame: None,
        }
    }
}

impl Plane {
    pub(crate) fn intersect(&self, ray: &Ray, tmax: f64) -> Option<f64> {
        let den = self.normal.dot(ray.d);
        if den.abs() < 1e-300 {
            return None;
        }
        let t = self.normal.dot(self.point - ray.o) / den;
        (t > 0.0 && t < tmax).then_some(t)
    }

    pub(crate) fn surface(&self, p: DVec3) -> SurfaceGeom {
        let f = Frame::from_normal_tangent(self.normal, self.tangent);
        let d = p - self.point;
        SurfaceGeom {
            position: p,
            ng: self.normal,
            ns: self.normal,
            tangent: f.t,
            uv: DVec2::new(d.dot(f.t), -d.dot(f.b)) / self.uv_scale,
            dpdu: f.t * self.uv_scale,
            dpdv: f.b * -self.uv_scale,
            material: self.material,

            frame: None,
        }
    }
}

impl Mesh {
    pub(crate) fn surface(
        &self,
        tri: usize,
        b1: f64,
        b2: f64,
        material: MaterialId,
    ) -> SurfaceGeom {
        let [i0, i1, i2] = self.indices[tri].map(|i| i as usize);
        let b0 = 1.0 - b1 - b2;
        let (p0, p1, p2) = (self.positions[i0], self.positions[i1], self.positions[i2]);
        let ng = (p1 - p0).cross(p2 - p0).normalize();
        let mut ns = match &self.normals {
            Some(n) => (n[i0] * b0 + n[i1] * b1 + n[i2] * b2).normalize_or_zero(),
            None => ng,
        };
        if ns == DVec3::ZERO {
            ns = ng;
        }
        let (uv, dpdu, dpdv) = match &self.uvs {
            Some(uvs) => {
                let (t0, t1, t2) = (uvs[i0], uvs[i1], uvs[i2]);
                let uv = t0 * b0 + t1 * b1 + t2 * b2;
                let (d1, d2) = (t1 - t0, t2 - t0);
                let det = d1.x * d2.y - d2.x * d1.y;
                if det.abs() > 1e-20 {
                    let (dp1, dp2) = (p1 - p0, p2 - p0);
                    (
                        uv,
                        (dp1 * d2.y - dp2 * d1.y) / det,
                        (dp2 * d1.x - dp1 * d2.x) / det,
                    )
                } else {
                    (uv, p1 - p0, p2 - p0)
                }
            }
            None => (DVec2::new(b1, b2), p1 - p0, p2 - p0),
        };
        let tangent = self.tangents[i0] * b0 + self.tangents[i1] * b1 + self.tangents[i2] * b2;
        SurfaceGeom {
            position: p0 * b0 + p1 * b1 + p2 * b2,
            ng,
            ns,
            tangent: if tangent.length_squared() > 1e-30 {
                tangent
            } else {
                dpdu
            },
            uv,
            dpdu,
            dpdv,
            material,

            frame: None,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests_support {
    use super::*;
    /// A shading point at the origin with the identity frame.
    pub(crate) fn dummy_point() -> ShadingPoint {
        ShadingPoint {
            position: DVec3::ZERO,
            geometric_normal: DVec3::Z,
            frame: Frame::IDENTITY,
            uv: DVec2::ZERO,
            dpdu: DVec3::X,
            dpdv: DVec3::Y,
            dpdx: DVec3::ZERO,
            dpdy: DVec3::ZERO,
            duvdx: DVec2::ZERO,
            duvdy: DVec2::ZERO,
            filter_uv: DVec2::ZERO,
            material: MaterialId(0),
        }
    }
}
