//! Light between facets, solved on the facets themselves: the radiosity of a tileable height
//! map's triangles under a directional light, for **Lambert** facets — what
//! `[shadowing] kind = "visibility"` with `interreflection = true` adds to the single bounce
//! (`meso_core::convolution::deltas_interreflection` asks the material's visibility model for
//! it through `VisibilityModel::interreflected`).
//!
//! # Model
//! Every triangle of the map (`crate::facets`, triangles mode) is cut into the four triangles
//! of its midpoint subdivision; each of these **patches** `p` (unit normal `n_p`, its
//! triangle's; microsurface area `a_p`, a quarter of its triangle's; centre `c_p`) has a uniform
//! exitant radiance `L_p`. Per unit irradiance from the light (normal to `i`), albedo `ρ`:
//!
//! ```text
//! L_p = ρ/π (n_p·i)⁺ V_i(p)  +  ρ · (1/R) Σ_k L_{g(p,k)}
//! ```
//!
//! where `V_i(p)` is the share of the patch's own four sub-triangle centres from which the
//! shadow ray towards `i` leaves the (tiled) surface (one point per patch was 4 % off the lit
//! area of V-grooves at 60°: their shadow edges fall at the same place in every groove) and
//! `g(p, k)` is the patch hit by the `k`-th of `R` stratified cosine-weighted rays from `c_p`
//! about `n_p` (a ray that leaves the surface adds nothing: the light is directional, the sky
//! black). The second term is the irradiance from the surface, `π ∫ L cos/π dω`, estimated by
//! those rays. The rays are traced once, when the model is built (`R` per patch, at most
//! [`RAY_BUDGET`] in all); each direction pair then traces four rays per patch towards `i` and
//! four towards `o`, and solves the system by Jacobi iteration (a Neumann series: iteration `b`
//! adds bounce `b + 1`). With `V_o(p)` likewise, the BRDF the viewer sees is
//!
//! ```text
//! f(i, o) = Σ_p a_p (n_p·o)⁺ V_o(p) L_p / (A cos θ_o cos θ_i),   A = Σ_p a_p n_p·z
//! ```
//!
//! and what this module returns is its part beyond the first bounce (`L_p` minus its direct
//! term), to be added to the single-bounce BRDF of the facets' own visibility model. It is the
//! gonioreflectometer's physics (`crate::gonio`, `bounces > 1`), with the surface's radiance held
//! per patch and the geometry's rays traced once instead of per pair; the test
//! `tests/interreflection.rs` compares the two (a whole triangle per patch was 3.3 % off the ray
//! tracer on V-grooves 4 cells wide, whose walls' radiance changes across a triangle).

use crate::facets::{FacetNormals, NormalMode};
use crate::gonio::Gonio;
use crate::heightmap::{Border, HeightMap};
use glam::DVec3;
use meso_core::frame::Frame;
use rand::RngExt;
use rand::SeedableRng;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Hit index of a ray that leaves the surface.
const SKY: u32 = u32::MAX;
/// The most rays traced to build the system (so that the build stays within seconds on large
/// maps) …
pub const RAY_BUDGET: usize = 1 << 21;
/// … with between these many strata per side per patch (`R` = side², 4 to 64 rays a patch).
const STRATA_MIN: usize = 2;
const STRATA_MAX: usize = 8;
/// Jacobi iterations stop when no patch's radiance changes by more than this fraction of the
/// largest, or after [`MAX_ITERATIONS`].
const TOLERANCE: f64 = 1e-9;
/// The most iterations (bounces beyond the first) of the solve.
const MAX_ITERATIONS: usize = 1000;
/// Offset of the rays' origins along the facet normal (cell units).
const OFFSET: f64 = 1e-7;
/// Patches per triangle: its midpoint subdivision.
const PATCHES: usize = 4;
/// The most patches solved (a 256² map: ≈ 60 MB of points, rays and radiances); the light
/// between the facets of larger maps is path traced instead
/// (`crate::facet_ndf::traced_interreflection`).
pub const MAX_PATCHES: usize = 1 << 19;

/// The centres of the midpoint subdivision of triangle `v`: the corner triangles at `v[0]`,
/// `v[1]`, `v[2]`, then the middle one (the order of [`sub_triangle`]).
fn triangle_points(v: [DVec3; 3]) -> [DVec3; PATCHES] {
    let (f, s) = (4.0 / 6.0, 1.0 / 6.0);
    [
        f * v[0] + s * v[1] + s * v[2],
        s * v[0] + f * v[1] + s * v[2],
        s * v[0] + s * v[1] + f * v[2],
        (v[0] + v[1] + v[2]) / 3.0,
    ]
}

/// The four triangles of the midpoint subdivision of `v`, in the order of [`triangle_points`].
fn sub_triangles(v: [DVec3; 3]) -> [[DVec3; 3]; PATCHES] {
    let (m01, m12, m02) = (
        (v[0] + v[1]) / 2.0,
        (v[1] + v[2]) / 2.0,
        (v[0] + v[2]) / 2.0,
    );
    [
        [v[0], m01, m02],
        [m01, v[1], m12],
        [m02, m12, v[2]],
        [m01, m12, m02],
    ]
}

/// Which of the four triangles of the midpoint subdivision holds the point of barycentric
/// coordinates `b` (order of [`triangle_points`]).
fn sub_triangle(b: [f64; 3]) -> usize {
    b.iter().position(|&x| x > 0.5).unwrap_or(3)
}

/// The patches of a wrapped height map with the patches each one sees: everything the radiosity
/// solve needs (module docs).
#[derive(Clone, Debug)]
pub struct FacetRadiosity {
    gonio: Gonio,
    /// Per patch ([`PATCHES`] per triangle, in the triangles' order), the four points of its
    /// own midpoint subdivision in cell space (x along columns, y along rows, heights in cell
    /// units): the last is its centre, where its rays leave; all four are traced towards the
    /// light and the viewer.
    points: Vec<[DVec3; PATCHES]>,
    /// Unit normal of each triangle.
    normal: Vec<DVec3>,
    /// Microsurface area of each triangle (cell units).
    area: Vec<f64>,
    /// `Σ a n·z`: the macro area (cells).
    projected: f64,
    /// Rays per patch.
    rays: usize,
    /// `hits[p · rays + k]`: the patch the `k`-th ray of patch `p` hits, or [`SKY`].
    hits: Vec<u32>,
    cols: usize,
}

impl FacetRadiosity {
    /// Trace the rays between the patches of `map`.
    ///
    /// # Errors
    /// A clamped map (the surface must tile, as in the gonioreflectometer), one without
    /// facets, or one of more than [`MAX_PATCHES`] / 8 cells (checked before allocating).
    pub fn new(map: &HeightMap) -> Result<FacetRadiosity, String> {
        if map.border() != Border::Wrap {
            return Err("light between facets needs a wrapped height map (--wrap)".into());
        }
        let (cols, rows) = (map.cells_x(), map.cells_y());
        // Checked before anything of the map's size is allocated.
        if cols * rows * 2 * PATCHES > MAX_PATCHES {
            return Err(format!(
                "light between facets is solved on maps of at most {} cells ({} × {} here): \
                 use a tile of the map",
                MAX_PATCHES / (2 * PATCHES),
                cols,
                rows
            ));
        }
        let gonio = Gonio::new(map).map_err(|e| e.to_string())?;
        let facets = FacetNormals::from_heightmap(map, NormalMode::Triangles);
        let n = facets.normals.len();
        if n == 0 {
            return Err("the height map has no facets".into());
        }
        let s = map.texel_size();
        let z = |r: usize, c: usize| map.at(r as isize, c as isize) / s;
        let mut points = Vec::with_capacity(n * PATCHES);
        for r in 0..rows {
            for c in 0..cols {
                let (x, y) = (c as f64, r as f64);
                let v = |dx: f64, dy: f64, h: f64| DVec3::new(x + dx, y + dy, h);
                let (h00, h01, h10, h11) = (z(r, c), z(r, c + 1), z(r + 1, c), z(r + 1, c + 1));
                // Triangle A (x, y), (x + 1, y), (x + 1, y + 1); B (x, y), (x + 1, y + 1),
                // (x, y + 1) (`crate::facets`, `Gonio`).
                for tri in [
                    [v(0.0, 0.0, h00), v(1.0, 0.0, h01), v(1.0, 1.0, h11)],
                    [v(0.0, 0.0, h00), v(1.0, 1.0, h11), v(0.0, 1.0, h10)],
                ] {
                    for sub in sub_triangles(tri) {
                        points.push(triangle_points(sub));
                    }
                }
            }
        }
        let patches = n * PATCHES;
        let side = ((RAY_BUDGET / patches) as f64)
            .sqrt()
            .floor()
            .clamp(STRATA_MIN as f64, STRATA_MAX as f64) as usize;
        let rays = side * side;
        let projected = facets
            .weights
            .iter()
            .zip(&facets.normals)
            .map(|(a, m)| a * m.z)
            .sum();
        let mut out = FacetRadiosity {
            gonio,
            points,
            normal: facets.normals,
            projected,
            area: facets.weights,
            rays,
            hits: Vec::new(),
            cols,
        };
        let hits: Vec<Vec<u32>> = (0..patches)
            .into_par_iter()
            .map(|p| {
                let m = out.normal[p / PATCHES];
                let frame = Frame::from_normal_tangent(m, DVec3::X);
                let mut rng = rand_pcg::Pcg64::seed_from_u64(
                    0x5EED_u64 ^ (p as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
                );
                let origin = out.points[p][PATCHES - 1] + m * OFFSET;
                let mut row = Vec::with_capacity(rays);
                for a in 0..side {
                    for b in 0..side {
                        let u1 = (a as f64 + rng.random::<f64>()) / side as f64;
                        let u2 = (b as f64 + rng.random::<f64>()) / side as f64;
                        let (r, ph) = (u1.sqrt(), 2.0 * PI * u2);
                        let d = frame.to_world(DVec3::new(
                            r * ph.cos(),
                            r * ph.sin(),
                            (1.0 - u1).sqrt(),
                        ));
                        row.push(out.hit_patch(origin, d));
                    }
                }
                row
            })
            .collect();
        out.hits = hits.concat();
        Ok(out)
    }

    /// Rays traced from each patch (a quarter of a triangle) to build the system.
    #[must_use]
    pub fn rays_per_patch(&self) -> usize {
        self.rays
    }

    /// The patch the ray `origin + t d` hits first, or [`SKY`].
    fn hit_patch(&self, origin: DVec3, d: DVec3) -> u32 {
        let Some(hit) = self.gonio.intersect(origin, d, 1e-9) else {
            return SKY;
        };
        // The tracer's own cell and triangle (triangle 0 holds y ≤ x within the cell);
        // barycentric coordinates on the vertex order of `new`.
        let [r, c] = hit.cell;
        let [fx, fy] = hit.local;
        let k = usize::from(hit.triangle);
        let b = if k == 0 {
            [1.0 - fx, fx - fy, fy]
        } else {
            [1.0 - fy, fx, fy - fx]
        };
        (((r * self.cols + c) * 2 + k) * PATCHES + sub_triangle(b)) as u32
    }

    /// Microsurface area of patch `p` (cell units).
    fn patch_area(&self, p: usize) -> f64 {
        self.area[p / PATCHES] / PATCHES as f64
    }

    /// `(n_p·w)⁺` times the share of patch `p`'s points that see `w` ([`FacetRadiosity::open`]).
    fn projected_cos(&self, p: usize, w: DVec3) -> f64 {
        let c = self.normal[p / PATCHES].dot(w);
        if c > 0.0 {
            c * self.open(p, w)
        } else {
            0.0
        }
    }

    /// Each patch's direct irradiance / π under a light of unit irradiance from `i`.
    fn direct(&self, i: DVec3) -> Vec<f64> {
        (0..self.points.len())
            .into_par_iter()
            .map(|p| self.projected_cos(p, i) / PI)
            .collect()
    }

    /// The share of patch `p`'s four points from which the ray towards `w` leaves the surface.
    fn open(&self, p: usize, w: DVec3) -> f64 {
        let m = self.normal[p / PATCHES] * OFFSET;
        let open = self.points[p]
            .iter()
            .filter(|&&q| self.gonio.intersect(q + m, w, 1e-9).is_none())
            .count();
        open as f64 / PATCHES as f64
    }

    /// The BRDF (1/sr, RGB) of the light that scatters more than once between the facets, for
    /// albedo `albedo`, light direction `i` and view direction `o` (unit, macro frame): at most
    /// `bounces` scattering events in all when given (as `meso gonio --bounces`), to convergence
    /// otherwise (module docs). Zero when either direction is at or below the horizon.
    #[must_use]
    pub fn multi_bounce(
        &self,
        albedo: [f64; 3],
        i: DVec3,
        o: DVec3,
        bounces: Option<usize>,
    ) -> [f64; 3] {
        if i.z <= 0.0 || o.z <= 0.0 {
            return [0.0; 3];
        }
        let direct = self.direct(i);
        let seen: Vec<f64> = (0..self.points.len())
            .into_par_iter()
            .map(|p| self.patch_area(p) * self.projected_cos(p, o))
            .collect();
        let iterations = bounces.map_or(MAX_ITERATIONS, |b| b.saturating_sub(1));
        let norm = 1.0 / (self.projected * o.z * i.z);
        albedo.map(|rho| {
            if rho <= 0.0 {
                return 0.0;
            }
            self.solve(rho, &direct, iterations)
                .iter()
                .zip(&direct)
                .zip(&seen)
                .map(|((lp, e), v)| v * (lp - rho * e))
                .sum::<f64>()
                * norm
        })
    }

    /// Each patch's exitant radiance `L_p` for albedo `rho` and direct irradiance / π
    /// `direct[p]`, after `iterations` Jacobi steps at most (module docs).
    fn solve(&self, rho: f64, direct: &[f64], iterations: usize) -> Vec<f64> {
        let inv_r = 1.0 / self.rays as f64;
        let mut l: Vec<f64> = direct.iter().map(|e| rho * e).collect();
        let mut next = vec![0.0; l.len()];
        for _ in 0..iterations {
            let change = next
                .par_iter_mut()
                .enumerate()
                .map(|(p, out)| {
                    let hits = &self.hits[p * self.rays..(p + 1) * self.rays];
                    let gathered: f64 = hits
                        .iter()
                        .filter(|&&g| g != SKY)
                        .map(|&g| l[g as usize])
                        .sum();
                    *out = rho * (direct[p] + gathered * inv_r);
                    (*out - l[p]).abs()
                })
                .reduce(|| 0.0, f64::max);
            std::mem::swap(&mut l, &mut next);
            let top = l.iter().copied().fold(0.0, f64::max);
            if change <= TOLERANCE * top {
                break;
            }
        }
        l
    }
}

/// A [`FacetRadiosity`] built on first use from a loader of its height map: what a facet NDF's
/// visibility model ([`crate::FacetVisibility`]) carries, so that only materials that ask for the
/// light between facets (`interreflection = true`) pay for tracing it.
pub struct LazyRadiosity {
    load: Box<dyn Fn() -> Result<HeightMap, String> + Send + Sync>,
    built: std::sync::OnceLock<Result<FacetRadiosity, String>>,
    traced: std::sync::OnceLock<Result<Gonio, String>>,
}

impl LazyRadiosity {
    /// A radiosity model of the map `load` returns, built at the first [`LazyRadiosity::get`].
    pub fn new(load: impl Fn() -> Result<HeightMap, String> + Send + Sync + 'static) -> Self {
        LazyRadiosity {
            load: Box::new(load),
            built: std::sync::OnceLock::new(),
            traced: std::sync::OnceLock::new(),
        }
    }

    /// The ray tracer of the same map (what the light between glossy facets is path traced
    /// on, `crate::facet_ndf`), built on the first call; the radiosity's own when that is
    /// built already.
    ///
    /// # Errors
    /// Why it cannot be built (the map does not load, or is clamped: [`Gonio::new`]).
    pub fn tracer(&self) -> Result<&Gonio, &str> {
        if let Some(Ok(r)) = self.built.get() {
            return Ok(&r.gonio);
        }
        self.traced
            .get_or_init(|| Gonio::new(&(self.load)()?).map_err(|e| e.to_string()))
            .as_ref()
            .map_err(String::as_str)
    }

    /// The model, built on the first call.
    ///
    /// # Errors
    /// Why it cannot be built (the map does not load, or is clamped: [`FacetRadiosity::new`]).
    pub fn get(&self) -> Result<&FacetRadiosity, &str> {
        self.built
            .get_or_init(|| FacetRadiosity::new(&(self.load)()?))
            .as_ref()
            .map_err(String::as_str)
    }
}

impl std::fmt::Debug for LazyRadiosity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LazyRadiosity")
            .field("built", &self.built.get().map(Result::is_ok))
            .field("traced", &self.traced.get().map(Result::is_ok))
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures;

    /// With white facets (ρ = 1) nothing is absorbed: all the light that falls on the surface
    /// leaves it, after however many bounces. Escaping flux `Σ a_p π L_p s_p` (`s_p` the share of
    /// the patch's rays that reach the sky) against the incident flux `Σ a_p (n_p·i)⁺ V_i(p)`,
    /// which is the macro area times `cos θ_i` for a height field. The balance holds up to the
    /// rays' sampling of the form factors (their reciprocity `a_p F_pq = a_q F_qp` is only
    /// statistical). Independent of the gonioreflectometer.
    #[test]
    fn white_facets_return_all_the_light() {
        let maps = [
            fixtures::v_grooves(32, 8, 0.25, 1.0 / 32.0).unwrap(),
            fixtures::half_cylinders(32, 8, 1.0 / 32.0, -1.0).unwrap(),
        ];
        for map in &maps {
            let r = FacetRadiosity::new(map).unwrap();
            for deg in [10.0f64, 40.0, 60.0] {
                let t = deg.to_radians();
                let i = DVec3::new(t.sin() * 0.6, t.sin() * 0.8, t.cos());
                let n = r.points.len();
                let direct = r.direct(i);
                let l = r.solve(1.0, &direct, MAX_ITERATIONS);
                let area = |p: usize| r.patch_area(p);
                let incident: f64 = (0..n).map(|p| area(p) * PI * direct[p]).sum();
                let escaped: f64 = (0..n)
                    .map(|p| {
                        let hits = &r.hits[p * r.rays..(p + 1) * r.rays];
                        let sky = hits.iter().filter(|&&g| g == SKY).count() as f64;
                        area(p) * PI * l[p] * sky / r.rays as f64
                    })
                    .sum();
                let macro_flux = r.projected * i.z;
                eprintln!(
                    "light {deg}°: escaped / incident {}, lit area / macro {}",
                    escaped / incident,
                    incident / macro_flux
                );
                assert!(
                    (escaped / incident - 1.0).abs() < 0.01,
                    "light {deg}°: escaped {escaped}, incident {incident}"
                );
                assert!(
                    (incident / macro_flux - 1.0).abs() < 0.02,
                    "light {deg}°: lit projected area {incident} against {macro_flux}"
                );
            }
        }
    }

    /// A plane sees nothing of itself: no light beyond the first bounce.
    #[test]
    fn a_plane_has_no_second_bounce() {
        let map = HeightMap::from_fn(16, 16, 1.0, Border::Wrap, |_, _| 0.0).unwrap();
        let r = FacetRadiosity::new(&map).unwrap();
        let f = r.multi_bounce(
            [0.9; 3],
            DVec3::new(0.3, 0.2, 0.9).normalize(),
            DVec3::Z,
            None,
        );
        assert_eq!(f, [0.0; 3]);
    }

    /// Maps beyond [`MAX_PATCHES`] are refused with a message, before their rays are
    /// allocated.
    #[test]
    fn too_large_a_map_is_refused() {
        let map = HeightMap::from_fn(257, 257, 1.0, Border::Wrap, |_, _| 0.0).unwrap();
        let e = FacetRadiosity::new(&map).unwrap_err();
        assert!(e.contains("at most 65536 cells (257 × 257 here)"), "{e}");
    }
}
