//! The intersection queries the renderer asks of a built [`Scene`]: closest hits as shading
//! points or as the stream path's hit frames, and shadow-ray occlusion.

use super::Scene;
use crate::bvh::Prim;
use crate::camera::{Ray, RayDifferential};
use crate::geometry::{face_viewer, finish_shading_point, MaterialId, ShadingPoint};
use glam::DVec3;
use meso_core::frame::Frame;

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
}
