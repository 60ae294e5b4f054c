//! Materials that vary over the surface with a height map: the bump-mapped ground truth
//! ([`BumpMapped`]) and its filtered counterpart reading an NDF pyramid ([`NdfMapped`]).
//!
//! # Placement
//! Both map the surface's texture coordinates onto the height map's grid of cells:
//! `x = u · texels_per_uv`, `y = v · texels_per_uv` (in cells), wrapped periodically, so the
//! map's columns (its x, `meso_maps` convention) run along the shading tangent (local `+x`)
//! and its rows along the bitangent (local `+y`); heights are along the local normal.
//!
//! # Shading (both materials)
//! A point of the bump map with facet normal `m` (local frame) is shaded as engines shade a
//! bump map, with its own cosine: radiance `f_μ(i, o; m) · E · max(0, m·i)`, where `f_μ` is the
//! material's facet transfer function (evaluated in the facet's frame, tangent = the surface
//! tangent made orthogonal to `m`). Returned to the renderer (which multiplies by `cos θi`)
//! as the BRDF `f_μ(i, o; m) · max(0, m·i) / cos θi`, plus the material's `diffuse/π`.
//! A pixel averages this over its footprint in `uv`, i.e. weights each facet by its
//! **projected** area.
//!
//! * [`BumpMapped`]: texel by texel: the facet normal of the triangulated height map under the
//!   point (two triangles per cell split along the `(i, j)–(i+1, j+1)` diagonal, exactly the
//!   surface `meso_maps` extracts its normals from). Optional shadowing: the light is blocked
//!   when it is below the horizon of the nearest height sample (`meso_maps::HorizonMap`, four
//!   azimuths interpolated as `HorizonStats::visibility`). Supersample it to get the ground
//!   truth of a pixel.
//! * [`NdfMapped`]: the pyramid of fitted Phong lobes. The level comes from the pixel footprint
//!   (`ShadingPoint::uv_footprint` from ray differentials): `lod = log2(footprint in cells) −
//!   ½` (the −½ matches the bilinear tent's spread to the pixel's box), clamped to the pyramid;
//!   the two nearest levels are blended linearly, and within each level the four nearest texels
//!   bilinearly (trilinear filtering), so zooming is continuous. Each fitted lobe (Eq. 1, area
//!   weights) is replaced at construction by 7 weighted nodes (its axis and a ring of 6 matched
//!   to the lobe's mean cosine through the von Mises–Fisher correspondence `κ = η/4`), and the
//!   node weights are converted to projected-area weights (`× max(0, m_z)`, renormalised per
//!   texel) so that the filtered shading is the average of the bump-mapped shading. Optional
//!   shadowing multiplies by the blended `HorizonStats::visibility(i)` of the texels (the
//!   filtered horizon angles of the map).
//!
//! Nothing allocates per shading call.

use crate::geometry::ShadingPoint;
use crate::render::LIGHT_BATCH;
use crate::shader::{fast_pow, Shader};
use glam::DVec3;
use meso_core::frame::Frame;
use meso_core::material::Material;
use meso_core::transfer::{PhongVariant, Transfer};
use meso_maps::{FacetNormals, HeightMap, HorizonMap, HorizonStats, NormalMode, Pyramid};
use std::f64::consts::FRAC_1_PI;

/// The facet transfer function, with fast paths for Phong (half vector) and Lambert.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Facet {
    Phong { exponent: f32, specular: [f32; 3] },
    Lambert { albedo_pi: [f32; 3] },
    General(Transfer),
}

impl Facet {
    fn new(t: &Transfer) -> Facet {
        match *t {
            Transfer::Phong {
                exponent,
                specular,
                variant: PhongVariant::Half,
            } => Facet::Phong {
                exponent: exponent as f32,
                specular: specular.map(|s| s as f32),
            },
            Transfer::Lambert { albedo } => Facet::Lambert {
                albedo_pi: albedo.map(|a| (a * FRAC_1_PI) as f32),
            },
            other => Facet::General(other),
        }
    }

    /// `f_μ(i, o; m) · max(0, m·i)` for the unit facet normal `m`; `h` is the unit half vector.
    #[inline]
    fn lit(&self, m: DVec3, i: DVec3, o: DVec3, h: DVec3) -> [f32; 3] {
        let mi = m.dot(i);
        if mi <= 0.0 {
            return [0.0; 3];
        }
        let mi32 = mi as f32;
        match *self {
            Facet::Phong { exponent, specular } => {
                let c = fast_pow(m.dot(h).max(0.0) as f32, exponent) * mi32;
                [specular[0] * c, specular[1] * c, specular[2] * c]
            }
            Facet::Lambert { albedo_pi } => {
                if m.dot(o) <= 0.0 {
                    return [0.0; 3];
                }
                [
                    albedo_pi[0] * mi32,
                    albedo_pi[1] * mi32,
                    albedo_pi[2] * mi32,
                ]
            }
            Facet::General(t) => {
                let f = Frame::from_normal_tangent(m, DVec3::X);
                let v = t.eval(f.to_local(i), f.to_local(o));
                [(v[0] * mi) as f32, (v[1] * mi) as f32, (v[2] * mi) as f32]
            }
        }
    }
}

fn check_scale(texels_per_uv: f64) -> Result<(), String> {
    if texels_per_uv.is_finite() && texels_per_uv > 0.0 {
        Ok(())
    } else {
        Err(format!(
            "texels_per_uv must be a finite number > 0, got {texels_per_uv}"
        ))
    }
}

/// A bump-mapped material shaded texel by texel from a height map (see the module docs):
/// the ground truth that [`NdfMapped`] filters.
#[derive(Clone, Debug)]
pub struct BumpMapped {
    cols: usize,
    rows: usize,
    /// Two facet normals per cell (triangles A and B), row-major.
    normals: Vec<[DVec3; 2]>,
    /// Per-sample horizon angles when shadowing is on.
    horizon: Option<HorizonMap>,
    facet: Facet,
    diffuse: [f32; 3],
    texels_per_uv: f64,
}

impl BumpMapped {
    /// A bump map of `map` with the facet transfer function and diffuse term of `surface` (its
    /// NDF is ignored), `texels_per_uv` height-map cells per unit of texture coordinate, and
    /// horizon shadowing of the light when `shadowing` is true.
    ///
    /// # Errors
    /// A message when `texels_per_uv` is not a finite positive number.
    pub fn new(
        map: &HeightMap,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<BumpMapped, String> {
        check_scale(texels_per_uv)?;
        let f = FacetNormals::from_heightmap(map, NormalMode::Triangles);
        let normals = f.normals.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
        Ok(BumpMapped {
            cols: f.cols,
            rows: f.rows,
            normals,
            horizon: shadowing.then(|| HorizonMap::compute(map)),
            facet: Facet::new(&surface.transfer),
            diffuse: surface.diffuse.map(|a| (a * FRAC_1_PI) as f32),
            texels_per_uv,
        })
    }

    /// The facet normal (local frame) of the triangulated height map at texture coordinates
    /// `(u, v)`.
    #[must_use]
    pub fn normal_at(&self, u: f64, v: f64) -> DVec3 {
        let (x, y) = (u * self.texels_per_uv, v * self.texels_per_uv);
        let (fx, fy) = (x.floor(), y.floor());
        let j = (fx as i64).rem_euclid(self.cols as i64) as usize;
        let i = (fy as i64).rem_euclid(self.rows as i64) as usize;
        // Triangle A is the half with y − y_i < x − x_j.
        let tri = usize::from(y - fy >= x - fx);
        self.normals[i * self.cols + j][tri]
    }

    fn shadow(&self, u: f64, v: f64, wi: DVec3) -> f32 {
        let Some(h) = &self.horizon else {
            return 1.0;
        };
        let (x, y) = (u * self.texels_per_uv, v * self.texels_per_uv);
        let j = (x.round() as i64).rem_euclid(h.width as i64) as usize;
        let i = (y.round() as i64).rem_euclid(h.height as i64) as usize;
        h.sample_stats(i, j).visibility(wi) as f32
    }
}

impl Shader for BumpMapped {
    fn eval(&self, sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let h = wi + wo;
        let l = h.length();
        if l < 1e-12 {
            return [0.0; 3];
        }
        let m = self.normal_at(sp.uv.x, sp.uv.y);
        let v = self.facet.lit(m, wi, wo, h / l);
        let s = self.shadow(sp.uv.x, sp.uv.y, wi) / wi.z as f32;
        [
            v[0] * s + self.diffuse[0],
            v[1] * s + self.diffuse[1],
            v[2] * s + self.diffuse[2],
        ]
    }
}

/// One node of a texel's filtered NDF: a unit normal with its projected-area weight.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    n: DVec3,
    w: f64,
}

/// One level of the filtered pyramid.
#[derive(Clone, Debug)]
struct NodeLevel {
    cols: usize,
    rows: usize,
    span: f64,
    start: Vec<u32>,
    nodes: Vec<Node>,
    horizon: Option<Vec<HorizonStats>>,
}

/// Nodes per fitted lobe: the axis and a ring of 6.
const RING: usize = 6;
/// Weight of the axis node.
const AXIS_WEIGHT: f64 = 0.25;

/// Replace a Phong peak by 7 weighted nodes (area weights) with the lobe's mean cosine.
fn lobe_nodes(axis: DVec3, weight: f64, exponent: f64, out: &mut Vec<Node>) {
    let kappa = exponent / 4.0;
    // Mean cosine to the axis of a vMF with concentration κ: coth κ − 1/κ.
    let mean = if kappa > 1e3 {
        1.0 - 1.0 / kappa
    } else if kappa < 1e-6 {
        0.0
    } else {
        1.0 / kappa.tanh() - 1.0 / kappa
    };
    let c = ((mean - AXIS_WEIGHT) / (1.0 - AXIS_WEIGHT)).clamp(-1.0, 1.0);
    if c > 1.0 - 1e-9 {
        out.push(Node { n: axis, w: weight });
        return;
    }
    let s = (1.0 - c * c).max(0.0).sqrt();
    let f = Frame::from_normal_tangent(axis, DVec3::X);
    out.push(Node {
        n: axis,
        w: weight * AXIS_WEIGHT,
    });
    for k in 0..RING {
        let a = std::f64::consts::TAU * k as f64 / RING as f64;
        out.push(Node {
            n: f.to_world(DVec3::new(s * a.cos(), s * a.sin(), c))
                .normalize(),
            w: weight * (1.0 - AXIS_WEIGHT) / RING as f64,
        });
    }
}

/// A material reading an NDF pyramid (see the module docs): the filtered bump map.
#[derive(Clone, Debug)]
pub struct NdfMapped {
    levels: Vec<NodeLevel>,
    facet: Facet,
    diffuse: [f32; 3],
    texels_per_uv: f64,
    shadowing: bool,
}

/// Up to 8 `(level, texel, weight)` taps of the trilinear filter.
type Taps = ([(usize, usize, f64); 8], usize);

impl NdfMapped {
    /// The filtered material of `pyramid` with the facet transfer and diffuse term of
    /// `surface` (its NDF is ignored), `texels_per_uv` level-0 cells per unit of texture
    /// coordinate, and horizon shadowing of the light when `shadowing` is true (needs a
    /// pyramid extracted from a height map).
    ///
    /// # Errors
    /// A message for a bad `texels_per_uv`, or shadowing asked of a pyramid without horizon
    /// statistics (normal maps).
    pub fn new(
        pyramid: &Pyramid,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<NdfMapped, String> {
        check_scale(texels_per_uv)?;
        let mut levels = Vec::with_capacity(pyramid.levels.len());
        for (k, l) in pyramid.levels.iter().enumerate() {
            if shadowing && l.horizon.is_none() {
                return Err(format!(
                    "level {k} of the pyramid has no horizon statistics (a normal map?): \
                     shadowing needs a height map"
                ));
            }
            let mut start = Vec::with_capacity(l.texels() + 1);
            let mut nodes = Vec::new();
            let mut tmp = Vec::new();
            start.push(0u32);
            for t in 0..l.texels() {
                tmp.clear();
                let (a, b) = (l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize);
                for lobe in &l.lobes[a..b] {
                    lobe_nodes(lobe.axis, lobe.weight, lobe.exponent, &mut tmp);
                }
                for n in &mut tmp {
                    n.w *= n.n.z.max(0.0);
                }
                let total: f64 = tmp.iter().map(|n| n.w).sum();
                if total > 0.0 {
                    nodes.extend(tmp.iter().filter(|n| n.w > 0.0).map(|n| Node {
                        n: n.n,
                        w: n.w / total,
                    }));
                } else {
                    // No lobe faces up: shade as the flat surface.
                    nodes.push(Node {
                        n: DVec3::Z,
                        w: 1.0,
                    });
                }
                start.push(nodes.len() as u32);
            }
            levels.push(NodeLevel {
                cols: l.cols,
                rows: l.rows,
                span: l.span as f64,
                start,
                nodes,
                horizon: if shadowing { l.horizon.clone() } else { None },
            });
        }
        if levels.is_empty() {
            return Err("the pyramid has no levels".into());
        }
        Ok(NdfMapped {
            levels,
            facet: Facet::new(&surface.transfer),
            diffuse: surface.diffuse.map(|a| (a * FRAC_1_PI) as f32),
            texels_per_uv,
            shadowing,
        })
    }

    /// Number of pyramid levels in use.
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Use only levels `0..=max_level` (coarser footprints read `max_level`). For a tileable
    /// map any level whose texels cover whole periods describes the far field; capping skips
    /// coarse levels whose lobe fit is worse (compare their residuals in `meso map info`).
    #[must_use]
    pub fn with_max_level(mut self, max_level: usize) -> NdfMapped {
        self.levels.truncate(max_level.saturating_add(1).max(1));
        self
    }

    /// The continuous level of detail used at `sp`: `log2(footprint in cells) − ½`, clamped to
    /// `[0, levels − 1]`.
    #[must_use]
    pub fn lod(&self, sp: &ShadingPoint) -> f64 {
        let fp = sp.uv_footprint() * self.texels_per_uv;
        let top = (self.levels.len() - 1) as f64;
        if fp > 0.0 && fp.is_finite() {
            (fp.log2() - 0.5).clamp(0.0, top)
        } else if fp.is_finite() {
            0.0
        } else {
            top
        }
    }

    /// The trilinear taps at `sp`.
    fn taps(&self, sp: &ShadingPoint) -> Taps {
        let lod = self.lod(sp);
        let l0 = lod.floor() as usize;
        let l1 = (l0 + 1).min(self.levels.len() - 1);
        let t = lod - l0 as f64;
        let (x, y) = (sp.uv.x * self.texels_per_uv, sp.uv.y * self.texels_per_uv);
        let mut taps = [(0usize, 0usize, 0.0f64); 8];
        let mut n = 0;
        for (lev, lw) in [(l0, 1.0 - t), (l1, t)] {
            if lw <= 0.0 {
                continue;
            }
            let l = &self.levels[lev];
            let tx = x / l.span - 0.5;
            let ty = y / l.span - 0.5;
            let (fx, fy) = (tx.floor(), ty.floor());
            let (ax, ay) = (tx - fx, ty - fy);
            for (dy, wy) in [(0i64, 1.0 - ay), (1, ay)] {
                for (dx, wx) in [(0i64, 1.0 - ax), (1, ax)] {
                    let w = lw * wx * wy;
                    if w <= 0.0 {
                        continue;
                    }
                    let c = (fx as i64 + dx).rem_euclid(l.cols as i64) as usize;
                    let r = (fy as i64 + dy).rem_euclid(l.rows as i64) as usize;
                    taps[n] = (lev, r * l.cols + c, w);
                    n += 1;
                }
            }
        }
        (taps, n)
    }
}

impl Shader for NdfMapped {
    fn eval(&self, sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        let mut out = [[0.0f32; 3]; 1];
        self.eval_many(sp, wo, &[wi], &mut out);
        out[0]
    }

    fn eval_many(&self, sp: &ShadingPoint, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
        for o in out.iter_mut() {
            *o = [0.0; 3];
        }
        if wo.z <= 0.0 {
            return;
        }
        let (taps, ntaps) = self.taps(sp);
        for chunk in 0..wi.len().div_ceil(LIGHT_BATCH) {
            let lo = chunk * LIGHT_BATCH;
            let hi = (lo + LIGHT_BATCH).min(wi.len());
            let mut h = [DVec3::ZERO; LIGHT_BATCH];
            let mut acc = [[0.0f64; 3]; LIGHT_BATCH];
            let mut vis = [0.0f64; LIGHT_BATCH];
            let mut ok = [false; LIGHT_BATCH];
            for k in lo..hi {
                let s = wi[k] + wo;
                let l = s.length();
                if wi[k].z > 0.0 && l > 1e-12 {
                    ok[k - lo] = true;
                    h[k - lo] = s / l;
                }
            }
            for &(lev, t, w) in &taps[..ntaps] {
                let l = &self.levels[lev];
                let nodes = &l.nodes[l.start[t] as usize..l.start[t + 1] as usize];
                for k in lo..hi {
                    if !ok[k - lo] {
                        continue;
                    }
                    let mut a = [0.0f32; 3];
                    for nd in nodes {
                        let v = self.facet.lit(nd.n, wi[k], wo, h[k - lo]);
                        let nw = nd.w as f32;
                        a[0] += nw * v[0];
                        a[1] += nw * v[1];
                        a[2] += nw * v[2];
                    }
                    for c in 0..3 {
                        acc[k - lo][c] += w * f64::from(a[c]);
                    }
                    if self.shadowing {
                        if let Some(hz) = &l.horizon {
                            vis[k - lo] += w * hz[t].visibility(wi[k]);
                        }
                    }
                }
            }
            for k in lo..hi {
                if !ok[k - lo] {
                    continue;
                }
                let v = if self.shadowing { vis[k - lo] } else { 1.0 };
                let s = v / wi[k].z;
                for c in 0..3 {
                    out[k][c] = (acc[k - lo][c] * s) as f32 + self.diffuse[c];
                }
            }
        }
    }
}
