//! The plots of a fit (`meso fit --plot DIR`): in-plane polar slices of data, fitted closed form
//! and written material, and spheres of data and model under one light with the exposure taken
//! from the data (so that the eye can judge a fit rather than a clipped highlight).

use crate::job::Data;
use glam::DVec3;
use meso_plot::{Canvas, LineStyle, PlotError, PolarPlot, PolarSeries, Sheet};
use rayon::prelude::*;

/// The names of the PNGs [`plot_files`] draws, in its order.
pub const PLOT_FILES: [&str; 2] = ["slices.png", "spheres.png"];

/// A BRDF (1/sr, RGB) of local directions `(i, o)`.
pub type Brdf<'a> = &'a (dyn Fn(DVec3, DVec3) -> [f64; 3] + Sync);

/// Rec. 709 luminance.
fn luminance(v: [f64; 3]) -> f64 {
    0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]
}

/// The in-plane pair for signed outgoing θo: light at `(θi, φ = 180°)`, viewer at `(|θo|, 0°)`
/// for θo ≥ 0 and `(|θo|, 180°)` otherwise.
fn in_plane(theta_i: f64, theta_o: f64) -> (DVec3, DVec3) {
    let wi = meso_core::frame::spherical_direction(theta_i, std::f64::consts::PI);
    let po = if theta_o >= 0.0 {
        0.0
    } else {
        std::f64::consts::PI
    };
    (wi, meso_core::frame::spherical_direction(theta_o.abs(), po))
}

/// Polar slices (in-plane, θi = 0°, 30°, 60°) of `ln(1 + Y cos θi)` for the data, the fitted
/// closed form `model` and the written material `exact`, and rendered spheres of data and model,
/// as PNG files in memory, in the order of [`PLOT_FILES`].
///
/// # Errors
/// A plot that cannot be drawn or encoded.
pub fn plot_files(
    data: &Data,
    model: Brdf<'_>,
    exact: Brdf<'_>,
) -> Result<[Vec<u8>; 2], PlotError> {
    Ok([slices_png(data, model, exact)?, spheres_png(data, model)?])
}

/// The polar slices of [`plot_files`].
fn slices_png(data: &Data, model: Brdf<'_>, exact: Brdf<'_>) -> Result<Vec<u8>, PlotError> {
    let lm = |f: [f64; 3], ci: f64| (luminance(f) * ci).max(0.0).ln_1p();
    let mut sheet = Sheet::new(
        "in-plane slices: ln(1 + Y·cos θi), Y = luminance of the BRDF",
        3,
        420,
        420,
    );
    for ti_deg in [0.0f64, 30.0, 60.0] {
        let ti = ti_deg.to_radians();
        let ci = ti.cos();
        let thetas: Vec<f64> = (-89..=89).map(|d| f64::from(d).to_radians()).collect();
        let mut plot = PolarPlot::new(format!("θi = {ti_deg}°"));
        plot.incident = Some(-ti);
        plot.incident_label = "light".into();
        plot.r_label = "ln(1 + Y cos θi)".into();
        // Data.
        let data_pts: Vec<[f64; 2]> = match &data.merl {
            Some(t) => thetas
                .iter()
                .step_by(2)
                .filter_map(|&to| {
                    let (wi, wo) = in_plane(ti, to);
                    t.lookup(wi, wo).map(|f| [to, lm(f, ci)])
                })
                .collect(),
            None => data
                .samples
                .samples
                .iter()
                .filter_map(|s| {
                    let (th_i, ph_i) = meso_core::frame::spherical_angles(s.wi);
                    let (th_o, ph_o) = meso_core::frame::spherical_angles(s.wo);
                    let dphi = (ph_o - ph_i).rem_euclid(2.0 * std::f64::consts::PI);
                    let in_plane =
                        (dphi - std::f64::consts::PI).abs() < 0.05 || th_i < 0.02 || th_o < 0.02;
                    if (th_i - ti).abs() < 0.05 && in_plane {
                        let sign = if dphi.cos() < 0.0 { 1.0 } else { -1.0 };
                        Some([sign * th_o, lm(s.rgb, ci)])
                    } else {
                        None
                    }
                })
                .collect(),
        };
        plot.add(
            PolarSeries::new("data", data_pts)
                .with_color(meso_plot::color::hex(0x222222))
                .with_style(LineStyle::Solid)
                .with_markers(true),
        );
        let mpts = thetas
            .iter()
            .map(|&to| {
                let (wi, wo) = in_plane(ti, to);
                [to, lm(model(wi, wo), ci)]
            })
            .collect();
        plot.add(
            PolarSeries::new("fitted model", mpts).with_color(meso_plot::color::hex(0xD62728)),
        );
        let epts: Vec<[f64; 2]> = thetas
            .par_iter()
            .step_by(3)
            .map(|&to| {
                let (wi, wo) = in_plane(ti, to);
                [to, lm(exact(wi, wo), ci)]
            })
            .collect();
        plot.add(
            PolarSeries::new("written material (exact)", epts)
                .with_color(meso_plot::color::hex(0x1F77B4))
                .with_style(LineStyle::Dashed),
        );
        let c = plot.render(420, 420)?;
        sheet.add(c, format!("θi = {ti_deg}°, in the plane of incidence"));
    }
    sheet.render()?.to_png_bytes()
}

/// The spheres of [`plot_files`]: data (MERL tables; a note for scattered samples) and model
/// under the same directional light, with the same exposure taken from the data.
fn spheres_png(data: &Data, model: Brdf<'_>) -> Result<Vec<u8>, PlotError> {
    let light = DVec3::new(-0.5, 0.55, 0.67).normalize();
    let size = 320usize;
    let render = |f: &(dyn Fn(DVec3, DVec3) -> Option<[f64; 3]> + Sync)| -> Vec<Option<[f64; 3]>> {
        (0..size * size)
            .into_par_iter()
            .map(|p| {
                let (px, py) = (p % size, p / size);
                let x = (px as f64 + 0.5) / size as f64 * 2.0 - 1.0;
                let y = 1.0 - (py as f64 + 0.5) / size as f64 * 2.0;
                let r2 = x * x + y * y;
                if r2 >= 1.0 {
                    return None;
                }
                let n = DVec3::new(x, y, (1.0 - r2).sqrt());
                let t = if x * x + y * y > 1e-12 {
                    DVec3::new(-y, x, 0.0).normalize()
                } else {
                    DVec3::X
                };
                let b = n.cross(t);
                let to_local = |w: DVec3| DVec3::new(w.dot(t), w.dot(b), w.dot(n));
                let (wi, wo) = (to_local(light), to_local(DVec3::Z));
                if wi.z <= 0.0 || wo.z <= 0.0 {
                    return Some([0.0; 3]);
                }
                f(wi, wo).map(|v| v.map(|c| c * wi.z))
            })
            .collect()
    };
    let model_img = render(&|wi, wo| Some(model(wi, wo)));
    let data_img = data
        .merl
        .as_ref()
        .map(|t| render(&|wi, wo| t.lookup(wi, wo)));
    // Exposure: the 90th percentile of the reference image's luminance maps to 0.6 (before the
    // tone curve), highlights roll off with x/(1+x).
    let reference = data_img.as_ref().unwrap_or(&model_img);
    let mut lum: Vec<f64> = reference
        .iter()
        .flatten()
        .map(|v| luminance(*v))
        .filter(|l| *l > 0.0)
        .collect();
    lum.sort_by(f64::total_cmp);
    let p90 = lum
        .get(lum.len() * 9 / 10)
        .copied()
        .unwrap_or(1.0)
        .max(1e-12);
    let exposure = 1.5 / p90;
    let to_canvas = |img: &[Option<[f64; 3]>]| -> Result<Canvas, PlotError> {
        let mut v = Vec::with_capacity(size * size * 3);
        for p in img {
            match p {
                None => v.extend([0.25f32, 0.25, 0.27]),
                Some(c) => v.extend(c.map(|x| {
                    let e = x * exposure;
                    let t = e / (1.0 + e);
                    srgb(t) as f32
                })),
            }
        }
        Canvas::from_rgb_f32(size as u32, size as u32, &v)
    };
    let mut sheet = Sheet::new(
        "sphere under a directional light (same light, same exposure)",
        2,
        size as u32,
        size as u32,
    );
    match &data_img {
        Some(d) => {
            sheet.add(to_canvas(d)?, "data (MERL, nearest cell)");
        }
        None => {
            let mut c = Canvas::new(size as u32, size as u32, [0.25, 0.25, 0.27]);
            meso_plot::draw_text(
                &mut c,
                20,
                (size / 2) as i32,
                "CSV data: no image",
                2,
                [1.0; 3],
            );
            sheet.add(c, "data (scattered samples)");
        }
    }
    sheet.add(to_canvas(&model_img)?, "fitted model");
    sheet.render()?.to_png_bytes()
}

/// Linear → sRGB transfer.
fn srgb(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}
