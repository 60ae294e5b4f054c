//! Light sources. All quantities are RGB, linear, in radiometric units with world lengths in
//! metres (or any consistent unit):
//!
//! | kind | parameters | emission |
//! |---|---|---|
//! | [`Light::Point`] | `position`, `intensity` (W/sr) | `E = I cos θ / r²` |
//! | [`Light::Directional`] | `direction` (unit, **towards** the light), `irradiance` (W/m², measured perpendicular to the direction) | `E = E⊥ cos θ` |
//! | [`Light::Linear`] | segment `start`–`end`, `intensity` per unit length (W/(sr·m)) | a line of isotropic point emitters (the paper's extended source, Poulin & Amanatides 1990) |
//! | [`Light::Sphere`] | `center`, `radius`, `radiance` (W/(m²·sr)) | uniform radiance; sampled by solid angle (uniform cone) |
//! | [`Light::Rectangle`] | `corner`, `edge_u`, `edge_v`, `radiance`, `two_sided` | uniform radiance from the side of `edge_u × edge_v` (both if `two_sided`); sampled uniformly by area |
//! | environment | see [`EnvironmentMap`] | importance sampled by its 2-D piecewise-constant distribution |
//!
//! Lights are not visible to camera rays and do not occlude each other; scene geometry occludes
//! them (soft shadows for the extended lights).

use crate::sampling::{sample_uniform_cone, uniform_cone_pdf, Distribution2D};
use glam::DVec3;
use meso_core::frame::Frame;
use std::f64::consts::PI;

/// A light source (see the module table for units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// An isotropic point light.
    Point {
        /// Position.
        position: DVec3,
        /// Radiant intensity, W/sr.
        intensity: DVec3,
    },
    /// A distant light.
    Directional {
        /// Unit direction **towards** the light.
        direction: DVec3,
        /// Irradiance on a surface perpendicular to `direction`, W/m².
        irradiance: DVec3,
    },
    /// A segment of isotropic emitters.
    Linear {
        /// One end.
        start: DVec3,
        /// The other end.
        end: DVec3,
        /// Radiant intensity per unit length, W/(sr·m).
        intensity: DVec3,
    },
    /// A spherical area light of uniform radiance.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius > 0.
        radius: f64,
        /// Radiance, W/(m²·sr).
        radiance: DVec3,
    },
    /// A parallelogram area light of uniform radiance.
    Rectangle {
        /// A corner.
        corner: DVec3,
        /// First edge from the corner.
        edge_u: DVec3,
        /// Second edge from the corner; emission is towards `edge_u × edge_v`.
        edge_v: DVec3,
        /// Radiance, W/(m²·sr).
        radiance: DVec3,
        /// Emit from both faces.
        two_sided: bool,
    },
}

/// One light sample seen from a receiving point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit world direction from the receiver towards the sampled light point.
    pub wi: DVec3,
    /// Distance to the sampled point (`f64::INFINITY` for distant lights).
    pub dist: f64,
    /// The Monte Carlo weight `L·(geometry)/pdf`: the receiver gets `f · weight · cos θi`.
    /// For a point light this is `I/r²`, for a directional light `E⊥`.
    pub weight: DVec3,
}

impl Light {
    /// True for lights without extent (point, directional): their sample ignores `u`.
    #[inline]
    #[must_use]
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Point { .. } | Light::Directional { .. })
    }

    /// Sample the light as seen from `p`, with `u ∈ [0,1)²`. `None` when the light cannot
    /// contribute (the receiver is inside a sphere light or behind a one-sided rectangle, …).
    #[inline]
    #[must_use]
    pub fn sample(&self, p: DVec3, u: [f64; 2]) -> Option<LightSample> {
        match *self {
            Light::Point {
                position,
                intensity,
            } => {
                let d = position - p;
                let r2 = d.length_squared();
                if r2 <= 0.0 {
                    return None;
                }
                let r = r2.sqrt();
                // One division instead of six (this runs per light and pixel).
                let inv = 1.0 / r;
                Some(LightSample {
                    wi: d * inv,
                    dist: r,
                    weight: intensity * (inv * inv),
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                wi: direction,
                dist: f64::INFINITY,
                weight: irradiance,
            }),
            Light::Linear {
                start,
                end,
                intensity,
            } => {
                let x = start + (end - start) * u[0];
                let d = x - p;
                let r2 = d.length_squared();
                if r2 <= 0.0 {
                    return None;
                }
                let r = r2.sqrt();
                let len = (end - start).length();
                Some(LightSample {
                    wi: d / r,
                    dist: r,
                    weight: intensity * (len / r2),
                })
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                let dc = center - p;
                let d2 = dc.length_squared();
                if d2 <= radius * radius {
                    return None;
                }
                let dcl = d2.sqrt();
                let sin2 = radius * radius / d2;
                let cos_max = (1.0 - sin2).max(0.0).sqrt();
                let frame = Frame::from_normal(dc / dcl);
                let wi = frame.to_world(sample_uniform_cone(u, cos_max));
                // Distance to the near intersection with the light sphere.
                let b = wi.dot(dc);
                let disc = (radius * radius - (d2 - b * b)).max(0.0);
                let dist = (b - disc.sqrt()).max(0.0);
                Some(LightSample {
                    wi,
                    dist,
                    weight: radiance / uniform_cone_pdf(cos_max),
                })
            }
            Light::Rectangle {
                corner,
                edge_u,
                edge_v,
                radiance,
                two_sided,
            } => {
                let x = corner + edge_u * u[0] + edge_v * u[1];
                let nn = edge_u.cross(edge_v);
                let area = nn.length();
                let d = x - p;
                let r2 = d.length_squared();
                if r2 <= 0.0 || area <= 0.0 {
                    return None;
                }
                let r = r2.sqrt();
                let wi = d / r;
                let mut cos_l = -wi.dot(nn) / area;
                if two_sided {
                    cos_l = cos_l.abs();
                }
                if cos_l <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    dist: r,
                    weight: radiance * (cos_l * area / r2),
                })
            }
        }
    }
}

/// An equirectangular environment map of linear radiance (W/(m²·sr)), importance sampled.
///
/// Mapping (world `+y` up): a direction `d = (sin θ cos φ, cos θ, sin θ sin φ)` with θ from `+y`
/// and φ from `+x` towards `+z` is looked up at column `u = ((φ − rotation)/2π) mod 1` and row
/// `v = θ/π` (row 0 is the zenith). Texels are piecewise constant (no interpolation), so the
/// sampling density matches the map exactly. The sampling distribution is proportional to
/// the texel luminance × sin θ; the solid-angle density is `pdf_uv / (2π² sin θ)`.
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
    scale: f32,
    rotation: f64,
    dist: Distribution2D,
}

/// The estimated peak memory (bytes) of [`EnvironmentMap::from_file`] on a file of `file_bytes`
/// bytes holding a `width × height` image of `bytes_per_pixel` decoded bytes per pixel: the
/// file, the decoded image, its float RGB conversion, the linear texels and the sampling
/// distribution (f64 function and CDF per texel).
#[must_use]
pub fn environment_bytes(file_bytes: u64, width: u64, height: u64, bytes_per_pixel: u64) -> u64 {
    file_bytes.saturating_add(
        width
            .saturating_mul(height)
            .saturating_mul(bytes_per_pixel + 12 + 12 + 24),
    )
}

impl EnvironmentMap {
    /// A map from row-major linear RGB texels (`width × height`, row 0 = zenith), a radiance
    /// `scale` and a rotation about `+y` in radians. Returns `None` if the sizes do not match,
    /// the map is empty or a texel is negative or not finite.
    #[must_use]
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<[f32; 3]>,
        scale: f32,
        rotation: f64,
    ) -> Option<EnvironmentMap> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return None;
        }
        if texels
            .iter()
            .flatten()
            .any(|v| !(v.is_finite() && *v >= 0.0))
            || !(scale.is_finite() && scale >= 0.0)
        {
            return None;
        }
        let mut f = vec![0.0; width * height];
        for v in 0..height {
            let sin_t = (PI * (v as f64 + 0.5) / height as f64).sin();
            for u in 0..width {
                let t = texels[v * width + u];
                let lum =
                    0.2126 * f64::from(t[0]) + 0.7152 * f64::from(t[1]) + 0.0722 * f64::from(t[2]);
                // Keep a floor so that every non-black texel can be sampled.
                let maxc = f64::from(t[0].max(t[1]).max(t[2]));
                f[v * width + u] = (lum.max(1e-3 * maxc)) * sin_t;
            }
        }
        Some(EnvironmentMap {
            width,
            height,
            dist: Distribution2D::new(&f, width, height),
            texels,
            scale,
            rotation,
        })
    }

    /// A constant environment of radiance `l` everywhere (`None` if `l` is negative or not
    /// finite).
    #[must_use]
    pub fn constant(l: [f32; 3]) -> Option<EnvironmentMap> {
        EnvironmentMap::new(1, 1, vec![l], 1.0, 0.0)
    }

    /// Load an equirectangular map from an image file (OpenEXR for HDR; PNG is read as sRGB
    /// and linearised), with a radiance `scale` and a rotation about `+y` in radians. Errors
    /// name the file and the problem.
    pub fn from_file(
        path: &std::path::Path,
        scale: f32,
        rotation: f64,
    ) -> Result<EnvironmentMap, crate::error::SceneError> {
        let err = |message: String| crate::error::SceneError::Environment {
            file: path.to_path_buf(),
            message,
        };
        if let Some(problem) = crate::error::input_path_problem(path) {
            return Err(err(problem));
        }
        let bytes = meso_core::io::read_limited(path, crate::limits::MAX_ENVIRONMENT_BYTES)
            .map_err(|e| err(format!("cannot read: {e}")))?;
        // The memory of decoding, from the header (before the pixels are decoded).
        {
            use image::ImageDecoder;
            let probe = image::ImageReader::new(std::io::Cursor::new(&bytes[..]))
                .with_guessed_format()
                .map_err(|e| err(format!("cannot read: {e}")))?;
            if let Ok(d) = probe.into_decoder() {
                let (w, h) = d.dimensions();
                let estimate = environment_bytes(
                    bytes.len() as u64,
                    u64::from(w),
                    u64::from(h),
                    u64::from(d.color_type().bytes_per_pixel()),
                );
                meso_core::budget::check(path, "loading the environment map", estimate)
                    .map_err(|e| crate::error::SceneError::Budget(e.to_string()))?;
            }
        }
        let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| err(format!("cannot read: {e}")))?;
        let dynimg = reader
            .decode()
            .map_err(|e| err(format!("cannot decode: {e}")))?;
        let is_float = matches!(
            dynimg,
            image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
        );
        let img = dynimg.into_rgb32f();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let mut texels: Vec<[f32; 3]> = img.pixels().map(|p| p.0).collect();
        if !is_float {
            for t in &mut texels {
                *t = t.map(crate::image::srgb_to_linear);
            }
        }
        if let Some(k) = texels
            .iter()
            .position(|t| t.iter().any(|v| !(v.is_finite() && *v >= 0.0)))
        {
            return Err(err(format!(
                "texel ({}, {}) is negative or not finite: {:?}",
                k % w.max(1),
                k / w.max(1),
                texels[k]
            )));
        }
        EnvironmentMap::new(w, h, texels, scale, rotation)
            .ok_or_else(|| err(format!("invalid map ({w}×{h}, scale {scale})")))
    }

    /// Map size `(width, height)` in texels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn dir_to_uv(&self, d: DVec3) -> [f64; 2] {
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let phi = d.z.atan2(d.x) - self.rotation;
        let u = (phi / (2.0 * PI)).rem_euclid(1.0);
        [u, theta / PI]
    }

    fn uv_to_dir(&self, uv: [f64; 2]) -> (DVec3, f64) {
        let theta = PI * uv[1];
        let phi = 2.0 * PI * uv[0] + self.rotation;
        let (st, ct) = theta.sin_cos();
        (DVec3::new(st * phi.cos(), ct, st * phi.sin()), st)
    }

    fn texel(&self, uv: [f64; 2]) -> DVec3 {
        let x = ((uv[0] * self.width as f64) as usize).min(self.width - 1);
        let y = ((uv[1] * self.height as f64) as usize).min(self.height - 1);
        let t = self.texels[y * self.width + x];
        DVec3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2])) * f64::from(self.scale)
    }

    /// Radiance arriving from the unit world direction `d` (i.e. seen looking along `d`).
    #[inline]
    #[must_use]
    pub fn radiance(&self, d: DVec3) -> DVec3 {
        self.texel(self.dir_to_uv(d))
    }

    /// The solid-angle density (1/sr) with which [`EnvironmentMap::sample`] returns `d`.
    #[must_use]
    pub fn pdf(&self, d: DVec3) -> f64 {
        let uv = self.dir_to_uv(d);
        let st = (PI * uv[1]).sin();
        if st <= 0.0 {
            return 0.0;
        }
        self.dist.pdf(uv) / (2.0 * PI * PI * st)
    }

    /// Importance-sample an incident direction; the weight is `L(wi)/pdf(wi)`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> Option<LightSample> {
        let (uv, pdf_uv) = self.dist.sample(u);
        let (wi, st) = self.uv_to_dir(uv);
        if pdf_uv <= 0.0 || st <= 0.0 {
            return None;
        }
        let pdf = pdf_uv / (2.0 * PI * PI * st);
        Some(LightSample {
            wi,
            dist: f64::INFINITY,
            weight: self.texel(uv) / pdf,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn environment_pdf_integrates_to_one_and_matches_sampling() {
        // A map with a bright band and a dim rest.
        let (w, h) = (16usize, 8usize);
        let texels: Vec<[f32; 3]> = (0..w * h)
            .map(|k| {
                let (x, y) = (k % w, k / w);
                let v = if x == 3 && y == 2 {
                    40.0
                } else {
                    0.5 + (y as f32) * 0.1
                };
                [v, v * 0.8, v * 1.1]
            })
            .collect();
        let env = EnvironmentMap::new(w, h, texels, 1.0, 0.4).unwrap();
        // ∫ pdf dω by quadrature over (θ, φ).
        let (nt, np) = (400, 400);
        let mut total = 0.0;
        for i in 0..nt {
            let th = PI * (i as f64 + 0.5) / nt as f64;
            for j in 0..np {
                let ph = 2.0 * PI * (j as f64 + 0.5) / np as f64;
                let d = DVec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin());
                total += env.pdf(d) * th.sin() * (PI / nt as f64) * (2.0 * PI / np as f64);
            }
        }
        assert!((total - 1.0).abs() < 5e-3, "∫pdf = {total}");
        // Chi-square-like test: sample counts per texel vs the expected counts from the pdf.
        let n = 400_000u32;
        let mut counts = vec![0f64; w * h];
        for k in 0..n {
            let u = [
                f64::from(sobol_burley::sample(k % 65536, 0, 11 + k / 65536)),
                f64::from(sobol_burley::sample(k % 65536, 1, 11 + k / 65536)),
            ];
            let s = env.sample(u).unwrap();
            let uv = env.dir_to_uv(s.wi);
            let x = ((uv[0] * w as f64) as usize).min(w - 1);
            let y = ((uv[1] * h as f64) as usize).min(h - 1);
            counts[y * w + x] += 1.0;
            // weight = L/pdf
            let l = env.radiance(s.wi);
            assert!(((s.weight * env.pdf(s.wi)) - l).length() < 1e-6 * l.length().max(1.0));
        }
        let mut chi2 = 0.0;
        for y in 0..h {
            for x in 0..w {
                // Expected probability of the texel: ∫ pdf over its solid angle, by quadrature.
                let mut p = 0.0;
                let m = 20;
                for a in 0..m {
                    for b in 0..m {
                        let uv = [
                            (x as f64 + (a as f64 + 0.5) / m as f64) / w as f64,
                            (y as f64 + (b as f64 + 0.5) / m as f64) / h as f64,
                        ];
                        let (d, st) = env.uv_to_dir(uv);
                        p += env.pdf(d) * st * 2.0 * PI * PI / (w * h * m * m) as f64;
                    }
                }
                let e = p * f64::from(n);
                chi2 += (counts[y * w + x] - e).powi(2) / e;
            }
        }
        // 127 degrees of freedom: the 0.01 critical value is about 166.
        assert!(chi2 < 166.0, "chi2 = {chi2}");
    }

    #[test]
    fn lights_give_their_analytic_irradiance_at_a_point() {
        let p = DVec3::ZERO;
        let n = DVec3::Y;
        let l = Light::Point {
            position: DVec3::new(0.0, 2.0, 0.0),
            intensity: DVec3::splat(8.0),
        };
        let s = l.sample(p, [0.5, 0.5]).unwrap();
        assert!((s.weight.x * s.wi.dot(n) - 2.0).abs() < 1e-12);
        // Linear light: a segment from (-a, h, 0) to (a, h, 0), irradiance on the plane y = 0
        // at the origin: I ∫ h/(x²+h²)^{3/2} dx = I · 2a / (h √(a²+h²)).
        let (a, h) = (1.5, 0.7);
        let l = Light::Linear {
            start: DVec3::new(-a, h, 0.0),
            end: DVec3::new(a, h, 0.0),
            intensity: DVec3::splat(1.0),
        };
        let m = 20000;
        let e: f64 = (0..m)
            .map(|k| {
                let s = l.sample(p, [(k as f64 + 0.5) / m as f64, 0.0]).unwrap();
                s.weight.x * s.wi.dot(n).max(0.0)
            })
            .sum::<f64>()
            / m as f64;
        let exact = 2.0 * a / (h * (a * a + h * h).sqrt());
        assert!((e - exact).abs() < 1e-6 * exact, "{e} vs {exact}");
    }
}
