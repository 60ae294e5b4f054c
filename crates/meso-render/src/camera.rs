//! Cameras: perspective and orthographic, with ray differentials.
//!
//! Image coordinates: `x` grows to the right and `y` grows **down**, in pixels, with pixel
//! `(i, j)` covering `[i, i+1) × [j, j+1)`. The camera looks from `position` towards `look_at`;
//! `up` fixes the roll (the image's up is `up` made orthogonal to the view direction).
//! Pixels are square.

use crate::error::SceneError;
use glam::DVec3;
use meso_core::display::Num;

/// How the image plane maps to rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// A pinhole camera; `fov_deg` is the **horizontal** field of view across the image width,
    /// in degrees, in `(0, 180)`.
    Perspective {
        /// Horizontal field of view, degrees.
        fov_deg: f64,
    },
    /// Parallel rays along the view direction; `width` is the extent of the image across its
    /// width in world units (the height follows from the aspect ratio).
    Orthographic {
        /// Image width in world units.
        width: f64,
    },
}

/// A camera: a projection, a position and an orientation (world units, right-handed world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    projection: Projection,
    position: DVec3,
    look_at: DVec3,
    up: DVec3,
    forward: DVec3,
    right: DVec3,
    true_up: DVec3,
    /// `tan(fov/2)` for perspective cameras (0 for orthographic).
    tan_half: f64,
}

/// A ray: origin and unit direction (world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin (world units).
    pub o: DVec3,
    /// Unit direction.
    pub d: DVec3,
}

impl Ray {
    /// The point at parameter `t` (world units along the unit direction).
    #[inline]
    #[must_use]
    pub fn at(&self, t: f64) -> DVec3 {
        self.o + self.d * t
    }
}

/// A primary ray with its differentials: the change of origin and (unit) direction per pixel
/// step in `x` (right) and `y` (down). Used to derive the footprint of a pixel on the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayDifferential {
    /// The central ray.
    pub ray: Ray,
    /// ∂origin/∂x per pixel.
    pub dodx: DVec3,
    /// ∂origin/∂y per pixel.
    pub dody: DVec3,
    /// ∂direction/∂x per pixel.
    pub dddx: DVec3,
    /// ∂direction/∂y per pixel.
    pub dddy: DVec3,
}

impl Camera {
    /// A camera; errors name the offending field (`camera.position`, `camera.up`, …) when
    /// a value is not finite, `position == look_at`, `up` is zero or parallel to the view
    /// direction, the field of view is outside `(0, 180)` degrees or the width is not positive.
    pub fn new(
        projection: Projection,
        position: DVec3,
        look_at: DVec3,
        up: DVec3,
    ) -> Result<Camera, SceneError> {
        crate::error::finite("camera.position", position)?;
        crate::error::finite("camera.look_at", look_at)?;
        crate::error::finite("camera.up", up)?;
        match projection {
            Projection::Perspective { fov_deg } => {
                if !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0) {
                    return Err(SceneError::invalid(
                        "camera.fov_deg",
                        format!("must be in (0, 180) degrees, got {}", Num(fov_deg)),
                    ));
                }
            }
            Projection::Orthographic { width } => {
                if !(width.is_finite() && width > 0.0) {
                    return Err(SceneError::invalid(
                        "camera.width",
                        format!(
                            "must be a positive number of world units, got {}",
                            Num(width)
                        ),
                    ));
                }
            }
        }
        let f = look_at - position;
        if f.length() < 1e-12 {
            return Err(SceneError::invalid(
                "camera.look_at",
                "must differ from camera.position".to_string(),
            ));
        }
        let forward = f.normalize();
        let r = forward.cross(up);
        if up.length() < 1e-12 || r.length() < 1e-9 * up.length() {
            return Err(SceneError::invalid(
                "camera.up",
                format!("must be non-zero and not parallel to the view direction, got {up:?}"),
            ));
        }
        let right = r.normalize();
        let true_up = right.cross(forward);
        let tan_half = match projection {
            Projection::Perspective { fov_deg } => (0.5 * fov_deg.to_radians()).tan(),
            Projection::Orthographic { .. } => 0.0,
        };
        Ok(Camera {
            tan_half,
            projection,
            position,
            look_at,
            up,
            forward,
            right,
            true_up,
        })
    }

    /// The projection.
    #[must_use]
    pub fn projection(&self) -> Projection {
        self.projection
    }
    /// The eye position.
    #[must_use]
    pub fn position(&self) -> DVec3 {
        self.position
    }
    /// The point looked at.
    #[must_use]
    pub fn look_at(&self) -> DVec3 {
        self.look_at
    }
    /// The `up` hint as given.
    #[must_use]
    pub fn up(&self) -> DVec3 {
        self.up
    }
    /// The orthonormal camera basis `(right, up, forward)`.
    #[must_use]
    pub fn basis(&self) -> (DVec3, DVec3, DVec3) {
        (self.right, self.true_up, self.forward)
    }

    /// The ray through the continuous image point `(x, y)` (pixels, `y` down) of a
    /// `width × height` image, without differentials: the same ray as
    /// [`Camera::generate_ray`]'s, for shading that does not need the pixel footprint.
    #[inline]
    #[must_use]
    pub fn ray(&self, x: f64, y: f64, width: u32, height: u32) -> Ray {
        let w = f64::from(width);
        let h = f64::from(height);
        let sx = 2.0 * x / w - 1.0;
        let sy = (1.0 - 2.0 * y / h) * (h / w);
        match self.projection {
            Projection::Orthographic { width: ww } => {
                let half = 0.5 * ww;
                Ray {
                    o: self.position + self.right * (sx * half) + self.true_up * (sy * half),
                    d: self.forward,
                }
            }
            Projection::Perspective { .. } => {
                let t = self.tan_half;
                let u = self.forward + self.right * (sx * t) + self.true_up * (sy * t);
                Ray {
                    o: self.position,
                    d: u * (1.0 / u.length()),
                }
            }
        }
    }

    /// The ray through the continuous image point `(x, y)` (pixels, `y` down) of a
    /// `width × height` image, with its per-pixel differentials.
    #[inline]
    #[must_use]
    pub fn generate_ray(&self, x: f64, y: f64, width: u32, height: u32) -> RayDifferential {
        let w = f64::from(width);
        let h = f64::from(height);
        // Normalised screen coordinates: sx in [-1, 1] across the width; sy scaled by aspect.
        let sx = 2.0 * x / w - 1.0;
        let sy = (1.0 - 2.0 * y / h) * (h / w);
        let step = 2.0 / w; // change of sx (and of sy, with sign) per pixel
        match self.projection {
            Projection::Orthographic { width: ww } => {
                let half = 0.5 * ww;
                let o = self.position + self.right * (sx * half) + self.true_up * (sy * half);
                RayDifferential {
                    ray: Ray { o, d: self.forward },
                    dodx: self.right * (step * half),
                    dody: -self.true_up * (step * half),
                    dddx: DVec3::ZERO,
                    dddy: DVec3::ZERO,
                }
            }
            Projection::Perspective { .. } => {
                let t = self.tan_half;
                let u = self.forward + self.right * (sx * t) + self.true_up * (sy * t);
                let inv = 1.0 / u.length();
                let d = u * inv;
                // d/dx of u/|u| = (du - d (d·du)) / |u|.
                let dux = self.right * (step * t);
                let duy = -self.true_up * (step * t);
                let dddx = (dux - d * d.dot(dux)) * inv;
                let dddy = (duy - d * d.dot(duy)) * inv;
                RayDifferential {
                    ray: Ray {
                        o: self.position,
                        d,
                    },
                    dodx: DVec3::ZERO,
                    dody: DVec3::ZERO,
                    dddx,
                    dddy,
                }
            }
        }
    }
}

/// [`Camera::ray`] with the per-image work hoisted out: the ray through image point
/// `(x, y)` is affine in `(x, y)` before normalisation, `base + x·dx + y·dy` (the direction for
/// a perspective camera, the origin for an orthographic one).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayGen {
    base: DVec3,
    dx: DVec3,
    dy: DVec3,
    /// Eye position (perspective) or view direction (orthographic).
    fixed: DVec3,
    perspective: bool,
}

impl RayGen {
    /// The generator of `camera`'s rays for a `width × height` image.
    pub(crate) fn new(camera: &Camera, width: u32, height: u32) -> RayGen {
        let w = f64::from(width);
        let aspect = f64::from(height) / w;
        // sx = x·2/w − 1, sy = aspect − y·2/w.
        let (scale, fixed, perspective, start) = match camera.projection {
            Projection::Orthographic { width: ww } => {
                (0.5 * ww, camera.forward, false, camera.position)
            }
            Projection::Perspective { .. } => {
                (camera.tan_half, camera.position, true, camera.forward)
            }
        };
        RayGen {
            base: start - camera.right * scale + camera.true_up * (aspect * scale),
            dx: camera.right * (2.0 * scale / w),
            dy: -camera.true_up * (2.0 * scale / w),
            fixed,
            perspective,
        }
    }

    /// The rays through image points `(xs[j], ys[j])`, `j < n` (pixels, `y` down), as a
    /// structure of arrays: the arithmetic of [`RayGen::ray`] in flat loops that vectorise.
    #[inline(always)]
    pub(crate) fn rays<const N: usize>(
        &self,
        n: usize,
        (xs, ys): (&[f64; N], &[f64; N]),
        o: &mut [[f64; N]; 3],
        d: &mut [[f64; N]; 3],
    ) {
        let n = n.min(N);
        let (b, dx, dy) = (self.base, self.dx, self.dy);
        let (vs, fixed_to) = if self.perspective { (d, o) } else { (o, d) };
        for j in 0..n {
            vs[0][j] = (b.x + dx.x * xs[j]) + dy.x * ys[j];
            vs[1][j] = (b.y + dx.y * xs[j]) + dy.y * ys[j];
            vs[2][j] = (b.z + dx.z * xs[j]) + dy.z * ys[j];
        }
        if self.perspective {
            let [vx, vy, vz] = vs;
            for ((x, y), z) in vx[..n].iter_mut().zip(&mut vy[..n]).zip(&mut vz[..n]) {
                let inv = 1.0 / (*x * *x + *y * *y + *z * *z).sqrt();
                *x *= inv;
                *y *= inv;
                *z *= inv;
            }
        }
        for (a, f) in fixed_to.iter_mut().enumerate() {
            f[..n].fill(self.fixed[a]);
        }
    }

    /// The ray through image point `(x, y)` (pixels, `y` down).
    #[inline(always)]
    pub(crate) fn ray(&self, x: f64, y: f64) -> Ray {
        let v = self.base + self.dx * x + self.dy * y;
        if self.perspective {
            Ray {
                o: self.fixed,
                d: v * (1.0 / v.length()),
            }
        } else {
            Ray {
                o: v,
                d: self.fixed,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orthographic_maps_pixels_to_world_points() {
        let cam = Camera::new(
            Projection::Orthographic { width: 2.5 },
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
        )
        .unwrap();
        let (w, h) = (256, 128);
        for (i, j) in [(0u32, 0u32), (255, 127), (17, 99), (128, 64)] {
            let r = cam.generate_ray(f64::from(i) + 0.5, f64::from(j) + 0.5, w, h);
            // Hit the plane z = 0.
            let t = -r.ray.o.z / r.ray.d.z;
            let p = r.ray.at(t);
            let px = 2.5 / 256.0;
            let ex = -1.25 + (f64::from(i) + 0.5) * px;
            let ey = 0.625 - (f64::from(j) + 0.5) * px;
            assert!(
                (p.x - ex).abs() < 1e-12 && (p.y - ey).abs() < 1e-12,
                "{p:?}"
            );
            assert!((r.ray.d - DVec3::NEG_Z).length() < 1e-15);
            assert!((r.dodx - DVec3::new(px, 0.0, 0.0)).length() < 1e-15);
            assert!((r.dody - DVec3::new(0.0, -px, 0.0)).length() < 1e-15);
        }
    }

    #[test]
    fn perspective_edges_span_the_field_of_view_and_differentials_match() {
        let cam = Camera::new(
            Projection::Perspective { fov_deg: 60.0 },
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::Y,
        )
        .unwrap();
        let (w, h) = (200, 100);
        let left = cam.generate_ray(0.0, 50.0, w, h).ray.d;
        let right = cam.generate_ray(200.0, 50.0, w, h).ray.d;
        assert!((left.angle_between(right) - 60f64.to_radians()).abs() < 1e-12);
        // Finite-difference check of the differentials.
        let r = cam.generate_ray(37.3, 81.2, w, h);
        let rx = cam.generate_ray(37.3 + 1e-4, 81.2, w, h);
        let ry = cam.generate_ray(37.3, 81.2 + 1e-4, w, h);
        assert!(((rx.ray.d - r.ray.d) / 1e-4 - r.dddx).length() < 1e-7);
        assert!(((ry.ray.d - r.ray.d) / 1e-4 - r.dddy).length() < 1e-7);
        // y grows down: a ray further down the image points lower.
        assert!(ry.ray.d.y < r.ray.d.y);
        // The differential-free ray is the same ray, bit for bit.
        for cam in [
            cam,
            Camera::new(
                Projection::Orthographic { width: 2.5 },
                DVec3::new(1.0, 2.0, 3.0),
                DVec3::ZERO,
                DVec3::Y,
            )
            .unwrap(),
        ] {
            let gen = RayGen::new(&cam, w, h);
            for (x, y) in [(37.3, 81.2), (0.5, 0.5), (199.9, 3.0)] {
                let r = cam.generate_ray(x, y, w, h).ray;
                assert_eq!(cam.ray(x, y, w, h), r);
                // The hoisted form agrees to rounding.
                let g = gen.ray(x, y);
                assert!((g.o - r.o).length() < 1e-12 && (g.d - r.d).length() < 1e-12);
            }
        }
    }

    #[test]
    fn bad_cameras_name_the_field() {
        let e = Camera::new(
            Projection::Perspective { fov_deg: 180.0 },
            DVec3::Z,
            DVec3::ZERO,
            DVec3::Y,
        )
        .unwrap_err();
        assert!(e.to_string().contains("camera.fov_deg"), "{e}");
        let e = Camera::new(
            Projection::Orthographic { width: 1.0 },
            DVec3::Z,
            DVec3::ZERO,
            DVec3::Z,
        )
        .unwrap_err();
        assert!(e.to_string().contains("camera.up"), "{e}");
        let e = Camera::new(
            Projection::Orthographic { width: 0.0 },
            DVec3::Z,
            DVec3::ZERO,
            DVec3::Y,
        )
        .unwrap_err();
        assert!(e.to_string().contains("camera.width"), "{e}");
    }
}
