//! Pictures of a material: its NDF on the equal-area hemisphere disc and polar BRDF slices.
//!
//! The disc is meso-plot's convention (Lambert azimuthal equal-area, `ρ = √2 sin(θ/2)`, tangent
//! `+x` to the right, bitangent `+y` up), the same as the editor's handle disc.

use crate::error::ApiError;
use glam::DVec3;
use meso_core::frame::spherical_direction;
use meso_core::material::Material;
use meso_core::ndf::Ndf;
use meso_plot::{
    color, hemisphere_map_range, Canvas, ColorMap, PolarPlot, PolarSeries, ValueScale,
};
use serde::Deserialize;

/// How the NDF picture looks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NdfStyle {
    /// meso-plot's labelled hemisphere map with a colour bar (light background).
    #[default]
    Plot,
    /// The bare disc filling the whole square picture (dark outside), for the editor's handles.
    Disc,
}

/// Linear or logarithmic colour scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scale {
    /// Linear from 0 to the maximum.
    #[default]
    Linear,
    /// Four decades below the maximum.
    Log,
}

/// The body of `POST /api/ndf.png` (besides `material`).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NdfParams {
    /// Picture side in pixels (64..=1024).
    pub size: u32,
    /// Picture style.
    pub style: NdfStyle,
    /// Colour scale.
    pub scale: Scale,
}

impl Default for NdfParams {
    fn default() -> Self {
        NdfParams {
            size: 320,
            style: NdfStyle::Plot,
            scale: Scale::Linear,
        }
    }
}

/// The body of `POST /api/slices.png` (besides `material`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SliceParams {
    /// Picture width (160..=1600).
    pub width: u32,
    /// Picture height (120..=1200).
    pub height: u32,
    /// Incidence angles in degrees (1 to 4 values in [0, 89]).
    pub theta_i_deg: Vec<f64>,
    /// Azimuths of the slice planes in degrees (1 to 4 values); 0° is the tangent plane.
    pub planes_deg: Vec<f64>,
}

impl Default for SliceParams {
    fn default() -> Self {
        SliceParams {
            width: 480,
            height: 320,
            theta_i_deg: vec![45.0],
            planes_deg: vec![0.0, 90.0],
        }
    }
}

/// Disc coordinates `(u, v)`, `u² + v² ≤ 1`, to the upper-hemisphere direction (Lambert
/// azimuthal equal-area: `ρ = √2 sin(θ/2)`); `None` outside the disc.
#[must_use]
pub fn lambert_to_direction(u: f64, v: f64) -> Option<DVec3> {
    let r2 = u * u + v * v;
    if r2.is_nan() || r2 > 1.0 {
        return None;
    }
    let s = (2.0 - r2).sqrt();
    Some(DVec3::new(u * s, v * s, 1.0 - r2))
}

fn png(c: &Canvas) -> Result<Vec<u8>, ApiError> {
    c.to_png_bytes()
        .map_err(|e| ApiError::internal(format!("png: {e}")))
}

/// The panel colour of the editor (outside the disc in [`NdfStyle::Disc`]).
const PANEL: [f32; 3] = [0.094, 0.098, 0.11];

/// Render the NDF picture.
///
/// # Errors
/// 400 for a size out of range; 500 if encoding fails.
pub fn ndf_png(m: &Material, p: NdfParams) -> Result<Vec<u8>, ApiError> {
    if !(64..=1024).contains(&p.size) {
        return Err(ApiError::bad_request(format!(
            "size: must be in [64, 1024] pixels, got {}",
            p.size
        )));
    }
    let ndf = &m.ndf;
    let n = p.size as usize;
    // Upper-hemisphere maximum on a fine sample for a stable range.
    let mut hi: f64 = 0.0;
    if !ndf.is_singular() {
        let k = 96;
        for j in 0..k {
            for i in 0..k {
                let u = -1.0 + 2.0 * (i as f64 + 0.5) / k as f64;
                let v = -1.0 + 2.0 * (j as f64 + 0.5) / k as f64;
                if let Some(d) = lambert_to_direction(u, v) {
                    hi = hi.max(ndf.eval(d));
                }
            }
        }
        if let Ndf::PhongPeaks(pp) = ndf {
            for l in pp.lobes() {
                if l.axis.z >= 0.0 {
                    hi = hi.max(ndf.eval(l.axis));
                }
            }
        }
        // GGX and Beckmann (and their mixtures) peak at the normal (for α ≤ 1), which the sample misses when α is
        // below its spacing: the colour bar reads the true maximum, as for Phong peaks.
        if let Ndf::Microfacet(_) | Ndf::Mixture(_) = ndf {
            hi = hi.max(ndf.eval(DVec3::Z));
        }
    }
    let hi = hi.max(1e-12);
    let (vs, range) = match p.scale {
        Scale::Linear => (ValueScale::Linear, (0.0, hi)),
        Scale::Log => (ValueScale::Log, (hi * 1e-4, hi)),
    };
    match p.style {
        NdfStyle::Disc => {
            let mut bytes = vec![0u8; n * n * 3];
            let r = n as f64 / 2.0;
            for y in 0..n {
                for x in 0..n {
                    let u = (x as f64 + 0.5 - r) / r;
                    let v = -(y as f64 + 0.5 - r) / r;
                    let c = match lambert_to_direction(u, v) {
                        Some(d) if !ndf.is_singular() => {
                            let val = ndf.eval(d).max(range.0);
                            ColorMap::Magma.map(val, range.0, range.1, vs)
                        }
                        Some(_) => [0.06, 0.065, 0.075],
                        None => PANEL,
                    };
                    let o = (y * n + x) * 3;
                    for (b, ci) in bytes[o..o + 3].iter_mut().zip(c) {
                        *b = (ci.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
                    }
                }
            }
            let c = Canvas::from_rgb8(p.size, p.size, &bytes)
                .map_err(|e| ApiError::internal(e.to_string()))?;
            png(&c)
        }
        NdfStyle::Plot => {
            let singular = ndf.is_singular();
            let map = hemisphere_map_range(
                |d| {
                    if singular {
                        0.93
                    } else {
                        ndf.eval(d).max(range.0)
                    }
                },
                p.size,
                if singular {
                    ColorMap::Gray
                } else {
                    ColorMap::Magma
                },
                if singular { ValueScale::Linear } else { vs },
                true,
                Some(if singular { (0.0, 1.0) } else { range }),
            )
            .map_err(|e| ApiError::internal(e.to_string()))?;
            if let Ndf::Deltas(d) = ndf {
                let mut c = map.canvas.clone();
                let g = map.geometry;
                for (k, wn) in d.normals().iter().enumerate() {
                    if let Some(px) = g.pixel_of(wn.normal) {
                        let r = (g.radius * 0.12 * wn.weight.sqrt()).max(3.0);
                        c.disc_outlined(px, r, color::palette(k), 1.5, color::INK);
                    }
                }
                png(&c)
            } else {
                png(&map.with_colorbar("n(m) 1/sr"))
            }
        }
    }
}

/// Render polar BRDF slices: for each plane azimuth φ and incidence θᵢ, the luminance of the
/// BRDF (1/sr) for outgoing directions in that plane, the light on the φ + 180° side.
///
/// # Errors
/// 400 for parameters out of range; 500 if drawing fails.
pub fn slices_png(m: &Material, p: &SliceParams) -> Result<Vec<u8>, ApiError> {
    if !(160..=1600).contains(&p.width) || !(120..=1200).contains(&p.height) {
        return Err(ApiError::bad_request(format!(
            "width, height: must be in [160, 1600] × [120, 1200], got {} × {}",
            p.width, p.height
        )));
    }
    if p.theta_i_deg.is_empty() || p.theta_i_deg.len() > 4 {
        return Err(ApiError::bad_request("theta_i_deg: give 1 to 4 angles"));
    }
    if p.planes_deg.is_empty() || p.planes_deg.len() > 4 {
        return Err(ApiError::bad_request("planes_deg: give 1 to 4 azimuths"));
    }
    if let Some(t) = p
        .theta_i_deg
        .iter()
        .find(|t| !(t.is_finite() && (0.0..=89.0).contains(*t)))
    {
        return Err(ApiError::bad_request(format!(
            "theta_i_deg: {t} is not in [0, 89]"
        )));
    }
    if let Some(t) = p.planes_deg.iter().find(|t| !t.is_finite()) {
        return Err(ApiError::bad_request(format!(
            "planes_deg: {t} is not a finite angle"
        )));
    }
    let fast = crate::preview::plot_brdf(m);
    let lum = |f: [f64; 3]| 0.2126 * f[0] + 0.7152 * f[1] + 0.0722 * f[2];
    let ti0 = p.theta_i_deg[0];
    let mut plot = PolarPlot::new(if p.theta_i_deg.len() == 1 {
        format!("BRDF slices, θi = {ti0}°")
    } else {
        "BRDF slices".to_string()
    });
    plot.r_label = "f (1/sr)".into();
    plot.incident = Some(-ti0.to_radians());
    plot.incident_label = "light".into();
    let mut k = 0;
    for &phi_deg in &p.planes_deg {
        let phi = phi_deg.to_radians();
        for &ti in &p.theta_i_deg {
            let wi = spherical_direction(ti.to_radians(), phi + std::f64::consts::PI);
            let s = PolarSeries::from_fn(
                if p.theta_i_deg.len() == 1 {
                    format!("φ = {phi_deg}°")
                } else {
                    format!("φ = {phi_deg}°, θi = {ti}°")
                },
                |t| {
                    let o = if t >= 0.0 {
                        spherical_direction(t, phi)
                    } else {
                        spherical_direction(-t, phi + std::f64::consts::PI)
                    };
                    let o = DVec3::new(o.x, o.y, o.z.max(1e-4)).normalize();
                    lum(fast.eval(wi, o))
                },
                181,
            )
            .with_color(color::palette(k));
            plot.add(s);
            k += 1;
        }
    }
    let c = plot
        .render(p.width, p.height)
        .map_err(|e| ApiError::internal(e.to_string()))?;
    png(&c)
}
