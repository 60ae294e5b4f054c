//! Primary rays of the stream path, a segment of a tile's row at a time: the camera rays, their
//! closest hits and the hit frames as a structure of arrays.
//!
//! Scenes made only of a few spheres (material previews, the paper's figures; see
//! [`Scene::sphere_only`]) take a vectorised path: every ray against every sphere in one flat
//! loop of selects, then the spheres' frames (normal, tangent along ∂p/∂φ, bitangent, the
//! face-the-viewer flip, the viewer's local direction) in another, so that the square roots
//! and divisions of neighbouring pixels run side by side in vector registers. Other scenes go
//! ray by ray through the BVH ([`Scene::closest_hit`], [`Scene::hit_frame`]). Both compute
//! the same numbers as the per-hit path, in the same order of operations
//! (`stream_matches_per_hit_path*` in `crates/meso-render/tests/stream.rs`).

// The lanes' loops index several arrays in step, by design.
#![allow(clippy::needless_range_loop)]

use super::{shadow_eps, shadow_eps_xyz, PixelContext};
use crate::camera::Ray;
use crate::sampling::PixelSampler;
use crate::scene::{LeafSphere, Scene, Skip};
use glam::DVec3;

/// Pixels of a row segment (tiles wider than this are cut into segments).
pub(crate) const ROW: usize = 64;

/// `ROW` values of one quantity.
type R<T> = [T; ROW];

/// One row segment's camera rays and hits (about 17 KB; one per thread, reused).
pub(crate) struct RowHits {
    /// Pixels in the segment.
    pub n: usize,
    /// Image-plane position of each ray (pixels, `y` down).
    px: R<f64>,
    py: R<f64>,
    /// Ray origin and unit direction (world).
    pub o: [R<f64>; 3],
    pub d: [R<f64>; 3],
    /// Distance to the closest hit; whether there is one.
    t: R<f64>,
    pub hit: R<bool>,
    /// The hit's frame, as [`crate::scene::HitFrame`] (valid where `hit`): position,
    /// geometric normal and shading frame (world), all facing the viewer.
    pub p: [R<f64>; 3],
    pub ng: [R<f64>; 3],
    pub ft: [R<f64>; 3],
    pub fb: [R<f64>; 3],
    pub fnrm: [R<f64>; 3],
    /// Direction to the viewer in the shading frame.
    pub wo: [R<f32>; 3],
    /// The offset of the shadow-ray origin along the geometric normal.
    pub eps: R<f64>,
    pub material: R<u32>,
    pub skip: R<Skip>,
    /// Sphere-only path: which sphere (index into [`Scene::sphere_only`]) each ray hit.
    which: R<u32>,
    /// Sphere-only path: |pole × n| (the tangent is taken from `Frame::from_normal` where it
    /// is ≤ 1e-12, at the poles).
    sin_t: R<f64>,
    /// Sphere-only path: the hit sphere's centre, pole and radius per lane, and n·d (< 0:
    /// the ray arrived from outside).
    cen: [R<f64>; 3],
    pole: [R<f64>; 3],
    rad: R<f64>,
    dn: R<f64>,
    /// Sphere-only path: `which` and `wo` as f64 inside the vectorised loops.
    which_f: R<f64>,
    wo64: [R<f64>; 3],
}

impl Default for RowHits {
    fn default() -> Self {
        let z3 = [[0.0; ROW]; 3];
        RowHits {
            n: 0,
            px: [0.0; ROW],
            py: [0.0; ROW],
            o: z3,
            d: z3,
            t: [0.0; ROW],
            hit: [false; ROW],
            p: z3,
            ng: z3,
            ft: z3,
            fb: z3,
            fnrm: z3,
            wo: [[0.0; ROW]; 3],
            eps: [0.0; ROW],
            material: [0; ROW],
            skip: [Skip::None; ROW],
            which: [0; ROW],
            sin_t: [0.0; ROW],
            cen: z3,
            pole: z3,
            rad: [1.0; ROW],
            dn: [0.0; ROW],
            which_f: [0.0; ROW],
            wo64: z3,
        }
    }
}

impl RowHits {
    /// Trace sample `k` of pixels `x0..x1` (at most [`ROW`]) of row `y`.
    pub(crate) fn trace(
        &mut self,
        scene: &Scene,
        c: &PixelContext,
        (x0, x1): (u32, u32),
        y: u32,
        k: u32,
    ) {
        let n = (x1 - x0) as usize;
        debug_assert!(n <= ROW);
        self.n = n;
        // Image-plane positions (jittered through the sampler with several samples).
        for j in 0..n {
            let x = x0 + j as u32;
            let jit = if c.spp == 1 {
                [0.5, 0.5]
            } else {
                PixelSampler::deferred(x, y, c.seed, k).get2(0)
            };
            self.px[j] = f64::from(x) + jit[0];
            self.py[j] = f64::from(y) + jit[1];
        }
        match scene.sphere_only() {
            Some(spheres) => self.spheres(scene, c, spheres),
            None => {
                c.rays
                    .rays(n, (&self.px, &self.py), &mut self.o, &mut self.d);
                self.trace_one_by_one(scene);
            }
        }
    }

    /// The sphere-only path, compiled for the widest vectors the CPU has.
    fn spheres(&mut self, scene: &Scene, c: &PixelContext, spheres: &[LeafSphere]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports AVX-512F/VL, AVX2 and FMA (checked just above).
                unsafe { self.spheres_avx512(scene, c, spheres) };
                return;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                unsafe { self.spheres_avx2(scene, c, spheres) };
                return;
            }
        }
        self.spheres_impl(scene, c, spheres);
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn spheres_avx2(&mut self, scene: &Scene, c: &PixelContext, spheres: &[LeafSphere]) {
        self.spheres_impl(scene, c, spheres);
    }

    /// # Safety
    /// The CPU must support AVX-512F/VL, AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
    unsafe fn spheres_avx512(&mut self, scene: &Scene, c: &PixelContext, spheres: &[LeafSphere]) {
        self.spheres_impl(scene, c, spheres);
    }

    /// Camera rays, intersections and frames of a sphere-only scene.
    #[inline(always)]
    fn spheres_impl(&mut self, scene: &Scene, c: &PixelContext, spheres: &[LeafSphere]) {
        c.rays
            .rays(self.n, (&self.px, &self.py), &mut self.o, &mut self.d);
        self.intersect_spheres(spheres);
        self.sphere_frames(scene, spheres);
    }

    fn ray(&self, j: usize) -> Ray {
        Ray {
            o: DVec3::new(self.o[0][j], self.o[1][j], self.o[2][j]),
            d: DVec3::new(self.d[0][j], self.d[1][j], self.d[2][j]),
        }
    }

    /// Any scene: the BVH and the full hit frame, ray by ray.
    fn trace_one_by_one(&mut self, scene: &Scene) {
        for j in 0..self.n {
            let ray = self.ray(j);
            self.hit[j] = false;
            let Some(h) = scene.closest_hit(&ray) else {
                continue;
            };
            self.hit[j] = true;
            let f = scene.hit_frame(&ray, &h);
            let wo = f.frame.to_local(-ray.d);
            for a in 0..3 {
                self.p[a][j] = f.position[a];
                self.ng[a][j] = f.geometric_normal[a];
                self.ft[a][j] = f.frame.t[a];
                self.fb[a][j] = f.frame.b[a];
                self.fnrm[a][j] = f.frame.n[a];
                self.wo[a][j] = wo[a] as f32;
            }
            self.eps[j] = shadow_eps(f.position);
            self.material[j] = f.material.0;
            self.skip[j] = f.skip;
        }
    }

    /// Sphere-only scenes: every ray against every sphere (in BVH leaf order, keeping the
    /// nearer hit as the BVH leaf loop does), with the arithmetic of the sphere test in
    /// `crate::bvh` written as selects.
    #[inline(always)]
    fn intersect_spheres(&mut self, spheres: &[LeafSphere]) {
        let n = self.n.min(ROW);
        self.t[..n].fill(f64::INFINITY);
        // The sphere index as f64 inside the loop: lanes of one width vectorise.
        let which = &mut self.which_f;
        which[..n].fill(0.0);
        for (si, s) in spheres.iter().enumerate() {
            let (c, r2, sf) = (s.center, s.radius * s.radius, si as f64);
            for j in 0..n {
                let (dx, dy, dz) = (self.d[0][j], self.d[1][j], self.d[2][j]);
                let (ox, oy, oz) = (self.o[0][j] - c.x, self.o[1][j] - c.y, self.o[2][j] - c.z);
                let b = ox * dx + oy * dy + oz * dz;
                let (fx, fy, fz) = (ox - dx * b, oy - dy * b, oz - dz * b);
                let disc = r2 - (fx * fx + fy * fy + fz * fz);
                let sq = disc.max(0.0).sqrt();
                let cc = (ox * ox + oy * oy + oz * oz) - r2;
                let q = -b - sq.copysign(b);
                let (t0, t1) = (cc / q, q);
                let (t0, t1) = if t0 > t1 { (t1, t0) } else { (t0, t1) };
                let tmax = self.t[j];
                // `&` rather than `&&`: selects, not branches.
                let th = if (t0 > 0.0) & (t0 < tmax) {
                    t0
                } else if (t1 > 0.0) & (t1 < tmax) {
                    t1
                } else {
                    f64::INFINITY
                };
                let take = (disc >= 0.0) & (th < tmax);
                self.t[j] = if take { th } else { tmax };
                which[j] = if take { sf } else { which[j] };
            }
        }
        for j in 0..n {
            self.which[j] = self.which_f[j] as u32;
            self.hit[j] = self.t[j] < f64::INFINITY;
        }
    }

    /// Sphere-only scenes: the hit frames of `Scene::hit_frame`'s sphere branch, vectorised
    /// (lanes without a hit compute finite garbage that is never read).
    #[inline(always)]
    fn sphere_frames(&mut self, scene: &Scene, spheres: &[LeafSphere]) {
        let n = self.n.min(ROW);
        // The hit sphere's constants per lane (a gather; one sphere in most scenes).
        for j in 0..n {
            let s = &spheres[self.which[j] as usize];
            for a in 0..3 {
                self.cen[a][j] = s.center[a];
                self.pole[a][j] = s.pole[a];
            }
            self.rad[j] = s.radius;
        }
        // Short loops of independent lanes, each simple enough for the vectoriser.
        // n = (o + d·t − c) / r (unit to rounding, as in `Scene::hit_frame`), the position
        // c + n·r, and n·d (its sign: which side the ray arrived from).
        for j in 0..n {
            let t = if self.t[j] < f64::INFINITY {
                self.t[j]
            } else {
                0.0
            };
            let inv_r = 1.0 / self.rad[j];
            let mut dn = 0.0;
            for a in 0..3 {
                let na = ((self.o[a][j] + self.d[a][j] * t) - self.cen[a][j]) * inv_r;
                self.fnrm[a][j] = na;
                self.p[a][j] = self.cen[a][j] + na * self.rad[j];
                dn += na * self.d[a][j];
            }
            self.dn[j] = dn;
        }
        // `Sphere::frame_at`: the tangent along pole × n (∂p/∂φ), |pole × n| = sin θ.
        for j in 0..n {
            let (nx, ny, nz) = (self.fnrm[0][j], self.fnrm[1][j], self.fnrm[2][j]);
            let (px, py, pz) = (self.pole[0][j], self.pole[1][j], self.pole[2][j]);
            let (ax, ay, az) = (py * nz - pz * ny, pz * nx - px * nz, px * ny - py * nx);
            let sin_t = (ax * ax + ay * ay + az * az).sqrt();
            self.sin_t[j] = sin_t;
            let inv = 1.0 / sin_t.max(1e-12);
            self.ft[0][j] = ax * inv;
            self.ft[1][j] = ay * inv;
            self.ft[2][j] = az * inv;
        }
        // Bitangent n × t; `face_viewer` turns n, b and the geometric normal towards the
        // ray's origin; then the viewer's direction `Frame::to_local(−d)` and the shadow
        // offset.
        for j in 0..n {
            let (nx, ny, nz) = (self.fnrm[0][j], self.fnrm[1][j], self.fnrm[2][j]);
            let (tx, ty, tz) = (self.ft[0][j], self.ft[1][j], self.ft[2][j]);
            let (bx, by, bz) = (ny * tz - ty * nz, nz * tx - tz * nx, nx * ty - tx * ny);
            let sg = if self.dn[j] > 0.0 { -1.0 } else { 1.0 };
            let (nx, ny, nz) = (nx * sg, ny * sg, nz * sg);
            let (bx, by, bz) = (bx * sg, by * sg, bz * sg);
            let (dx, dy, dz) = (self.d[0][j], self.d[1][j], self.d[2][j]);
            self.ng[0][j] = nx;
            self.ng[1][j] = ny;
            self.ng[2][j] = nz;
            self.fnrm[0][j] = nx;
            self.fnrm[1][j] = ny;
            self.fnrm[2][j] = nz;
            self.fb[0][j] = bx;
            self.fb[1][j] = by;
            self.fb[2][j] = bz;
            // `Frame::to_local(−d)`, in f64 here and narrowed below: one width per loop.
            self.wo64[0][j] = -(dx * tx + dy * ty + dz * tz);
            self.wo64[1][j] = -(dx * bx + dy * by + dz * bz);
            self.wo64[2][j] = -(dx * nx + dy * ny + dz * nz);
            let (px, py, pz) = (self.p[0][j], self.p[1][j], self.p[2][j]);
            self.eps[j] = shadow_eps_xyz(px, py, pz);
        }
        for a in 0..3 {
            for j in 0..n {
                self.wo[a][j] = self.wo64[a][j] as f32;
            }
        }
        for j in 0..n {
            let s = &spheres[self.which[j] as usize];
            self.material[j] = s.material.0;
            self.skip[j] = if self.dn[j] < 0.0 {
                Skip::Prim(s.prim)
            } else {
                Skip::None
            };
        }
        let degenerate = (0..n).any(|j| self.hit[j] && at_pole(self.sin_t[j]));
        if degenerate {
            // Hits at the poles: the full frame of `Scene::hit_frame`, hit by hit.
            for j in 0..n {
                if self.hit[j] && at_pole(self.sin_t[j]) {
                    let ray = self.ray(j);
                    let f = scene.sphere_hit_frame(&ray, self.t[j], self.which[j] as usize);
                    let wo = f.frame.to_local(-ray.d);
                    for a in 0..3 {
                        self.ng[a][j] = f.geometric_normal[a];
                        self.ft[a][j] = f.frame.t[a];
                        self.fb[a][j] = f.frame.b[a];
                        self.fnrm[a][j] = f.frame.n[a];
                        self.wo[a][j] = wo[a] as f32;
                    }
                }
            }
        }
    }
}

/// Whether `|pole × n| = sin_t` is too small for a tangent (the hit is at a pole, or NaN):
/// `Sphere::frame_at` then falls back to `Frame::from_normal`.
#[inline]
fn at_pole(sin_t: f64) -> bool {
    sin_t.is_nan() || sin_t <= 1e-12
}

#[cfg(test)]
mod tests {
    use crate::*;
    use glam::DVec3;
    use std::sync::Arc;

    fn scene(spheres: usize, plane: bool) -> Scene {
        let cam = Camera::new(
            Projection::Orthographic { width: 2.0 },
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
        )
        .expect("camera");
        let mut b = SceneBuilder::new(cam, ImageSettings::default());
        let m = b.material(Arc::new(Lambert { albedo: [0.5; 3] }));
        for k in 0..spheres {
            b.sphere(DVec3::new(k as f64, 0.0, 0.0), 0.4, DVec3::Y, m)
                .expect("sphere");
        }
        if plane {
            b.plane(DVec3::new(0.0, -1.0, 0.0), DVec3::Y, DVec3::X, 1.0, m)
                .expect("plane");
        }
        b.build().expect("scene")
    }

    #[test]
    fn sphere_only_path_is_taken_exactly_for_a_leaf_of_spheres() {
        for k in 1..=4 {
            let s = scene(k, false);
            let leaf = s.sphere_only().expect("a leaf of spheres");
            assert_eq!(leaf.len(), k);
            // Leaf order and sphere indices cover every sphere once.
            let mut idx: Vec<u32> = leaf.iter().map(|l| l.index).collect();
            idx.sort_unstable();
            assert_eq!(idx, (0..k as u32).collect::<Vec<_>>());
        }
        assert!(scene(2, true).sphere_only().is_none(), "a plane");
        assert!(scene(40, false).sphere_only().is_none(), "more than a leaf");
    }
}
