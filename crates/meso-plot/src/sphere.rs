//! Hemisphere maps: a function on the upper (or lower) hemisphere drawn as a disc in the
//! Lambert azimuthal equal-area projection, so that equal areas of the disc are equal solid
//! angles.
//!
//! Conventions (those of `meso_core::frame`): the local frame has the normal on +z, the tangent
//! +x pointing **right** in the picture and the bitangent +y pointing **up**; θ is measured from
//! +z (for the lower hemisphere, from −z), φ from +x towards +y. A direction at polar angle θ
//! from the pole lands at disc radius `ρ = √2 · sin(θ/2)` (1 at the horizon), so the disc area
//! inside ρ is proportional to the solid angle `2π(1 − cos θ)`. The lower hemisphere is drawn
//! with the same x-right, y-up orientation (seen through the surface from above).

use crate::canvas::{Canvas, Rect};
use crate::color::{self, Rgb};
use crate::colormap::{colorbar_extent, colorbar_scaled, ColorMap, ValueScale};
use crate::font::{self, Anchor};
use crate::PlotError;
use glam::DVec3;

/// Disc coordinates `(u, v)` with `u² + v² ≤ 1` → unit direction on the chosen hemisphere.
/// `None` outside the disc.
#[must_use]
pub fn lambert_to_direction(u: f64, v: f64, upper: bool) -> Option<DVec3> {
    let r2 = u * u + v * v;
    if r2.is_nan() || r2 > 1.0 {
        return None;
    }
    let s = (2.0 - r2).sqrt();
    let z = 1.0 - r2;
    Some(DVec3::new(u * s, v * s, if upper { z } else { -z }))
}

/// Unit direction → disc coordinates `(u, v)` of the hemisphere containing it
/// (`z ≥ 0` upper, `z ≤ 0` lower); inverse of [`lambert_to_direction`].
#[must_use]
pub fn direction_to_lambert(d: DVec3) -> (f64, f64) {
    let d = d.normalize_or_zero();
    let z = d.z.abs();
    let k = (1.0 / (1.0 + z)).sqrt(); // ρ / sin θ = √2 sin(θ/2) / sin θ
    (d.x * k, d.y * k)
}

/// Where a hemisphere disc sits in a picture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscGeometry {
    /// Centre x in pixel coordinates (continuous; pixel `i` covers `[i, i+1)`).
    pub cx: f64,
    /// Centre y in pixel coordinates.
    pub cy: f64,
    /// Radius of the disc (the horizon) in pixels.
    pub radius: f64,
    /// Upper (`z > 0`) or lower hemisphere.
    pub upper: bool,
}

impl DiscGeometry {
    /// The direction seen at continuous pixel position `(x, y)` (use `i + 0.5` for the centre of
    /// pixel `i`); `None` outside the disc.
    #[must_use]
    pub fn direction_at(&self, x: f64, y: f64) -> Option<DVec3> {
        let u = (x - self.cx) / self.radius;
        let v = -(y - self.cy) / self.radius;
        lambert_to_direction(u, v, self.upper)
    }

    /// The pixel position of direction `d`; `None` if `d` is on the other hemisphere
    /// (the horizon `z = 0` belongs to both).
    #[must_use]
    pub fn pixel_of(&self, d: DVec3) -> Option<[f64; 2]> {
        if (self.upper && d.z < 0.0) || (!self.upper && d.z > 0.0) || !d.is_finite() {
            return None;
        }
        let (u, v) = direction_to_lambert(d);
        Some([self.cx + u * self.radius, self.cy - v * self.radius])
    }

    /// Disc radius (pixels) of the circle of polar angle `theta` (radians from the pole).
    #[must_use]
    pub fn circle_radius(&self, theta: f64) -> f64 {
        std::f64::consts::SQRT_2 * (0.5 * theta).sin() * self.radius
    }
}

/// A rendered hemisphere map with its value range, for colour bars and picking.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereMap {
    /// The picture (disc, outline, guides and labels).
    pub canvas: Canvas,
    /// Value mapped to the low end of the colour map.
    pub min: f64,
    /// Value mapped to the high end of the colour map.
    pub max: f64,
    /// The colour map used.
    pub map: ColorMap,
    /// The value scale used.
    pub scale: ValueScale,
    /// Where the disc is.
    pub geometry: DiscGeometry,
    /// Integer text scale used for the labels.
    pub text_scale: u32,
}

impl SphereMap {
    /// The map with a vertical colour bar and its `label` to the right.
    #[must_use]
    pub fn with_colorbar(&self, label: &str) -> Canvas {
        let ts = self.text_scale;
        let bar_w = 12 * ts;
        let extra = 6 * ts + bar_w + colorbar_extent(ts, label) + 8 * ts;
        let (w, h) = (self.canvas.width(), self.canvas.height());
        let mut c = Canvas::new(w + extra, h, color::PAPER);
        c.blit(&self.canvas, self.canvas.rect(), crate::Filter::Nearest);
        let g = self.geometry;
        let top = (g.cy - g.radius).round() as i32;
        let rect = Rect::new(
            w as i32 + 6 * ts as i32 - g.radius as i32 / 10,
            top,
            bar_w,
            (2.0 * g.radius).round() as u32,
        );
        colorbar_scaled(
            &mut c, rect, self.map, self.min, self.max, self.scale, 5, label, ts,
        );
        c
    }
}

/// Render `f` over a hemisphere as a `size`×`size` Lambert equal-area disc picture with the
/// value range chosen from the data (see [`hemisphere_map_range`]).
pub fn hemisphere_map(
    f: impl Fn(DVec3) -> f64,
    size: u32,
    map: ColorMap,
    scale: ValueScale,
    upper: bool,
) -> Result<SphereMap, PlotError> {
    hemisphere_map_range(f, size, map, scale, upper, None)
}

/// Render `f` over the upper (`upper = true`) or lower hemisphere as a `size`×`size` picture:
/// a Lambert azimuthal equal-area disc with a thin outline, θ = 30° and 60° circles, and φ
/// ticks labelled 0°, 90°, 180°, 270° (φ = 0° on the right, 90° at the top).
///
/// `range`: the values mapped to the ends of the colour map. `None` chooses from the data:
/// linear maps span `[min(0, lo), hi]` (symmetric `[−m, m]` for a diverging map); log maps span
/// `[max(lo⁺, hi·10⁻⁴), hi]` where `lo⁺` is the smallest positive value.
/// Non-finite values of `f` are drawn grey.
pub fn hemisphere_map_range(
    f: impl Fn(DVec3) -> f64,
    size: u32,
    map: ColorMap,
    scale: ValueScale,
    upper: bool,
    range: Option<(f64, f64)>,
) -> Result<SphereMap, PlotError> {
    if !(64..=Canvas::MAX_SIDE).contains(&size) {
        return Err(PlotError::InvalidSize {
            width: size,
            height: size,
        });
    }
    let ts: u32 = if size >= 400 { 2 } else { 1 };
    let margin = font::text_width("180°", ts) as i32 + 10 * ts as i32;
    let radius = f64::from(size) / 2.0 - f64::from(margin);
    let g = DiscGeometry {
        cx: f64::from(size) / 2.0,
        cy: f64::from(size) / 2.0,
        radius,
        upper,
    };
    let (values, coverage) = sample_disc(&f, &g, size as usize);
    let (min, max) = value_range(range, &values, map, scale)?;
    let mut c = Canvas::new(size, size, color::PAPER);
    paint_values(&mut c, &values, &coverage, size as usize, |v| {
        map.map(v, min, max, scale)
    });
    draw_guides(&mut c, &g, map, ts);
    // Hemisphere tag in the top-left corner.
    let u = ts as i32;
    let tag = if upper { "z > 0" } else { "z < 0" };
    font::draw_text(&mut c, 4 * u, 4 * u, tag, ts, color::INK_SOFT);

    Ok(SphereMap {
        canvas: c,
        min,
        max,
        map,
        scale,
        geometry: g,
        text_scale: ts,
    })
}

/// Sample `f` at every pixel of an `n`×`n` picture whose centre is inside (or within half a
/// pixel of) the disc: the values (NaN outside) and each pixel's coverage by the disc.
fn sample_disc(f: &impl Fn(DVec3) -> f64, g: &DiscGeometry, n: usize) -> (Vec<f64>, Vec<f32>) {
    let radius = g.radius;
    let mut values = vec![f64::NAN; n * n];
    let mut coverage = vec![0f32; n * n];
    for y in 0..n {
        for x in 0..n {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let d = ((px - g.cx).powi(2) + (py - g.cy).powi(2)).sqrt();
            let cov = (radius + 0.5 - d).clamp(0.0, 1.0);
            if cov <= 0.0 {
                continue;
            }
            // Pixels straddling the horizon sample at the horizon.
            let k = if d > radius { radius / d } else { 1.0 };
            let dir = g.direction_at(g.cx + (px - g.cx) * k, g.cy + (py - g.cy) * k);
            if let Some(dir) = dir {
                values[y * n + x] = f(dir);
                coverage[y * n + x] = cov as f32;
            }
        }
    }
    (values, coverage)
}

/// The colour map's value range: the given `range` (checked) or one chosen from the data.
fn value_range(
    range: Option<(f64, f64)>,
    values: &[f64],
    map: ColorMap,
    scale: ValueScale,
) -> Result<(f64, f64), PlotError> {
    match range {
        Some((a, b)) if a.is_finite() && b.is_finite() && a < b => {
            if scale == ValueScale::Log && a <= 0.0 {
                return Err(PlotError::Invalid(format!(
                    "log range [{a}, {b}] must be positive"
                )));
            }
            Ok((a, b))
        }
        Some((a, b)) => Err(PlotError::Invalid(format!("invalid range [{a}, {b}]"))),
        None => auto_range(values, map, scale),
    }
}

/// Blend every covered pixel's colour (`to_color` of its value, grey where it is not finite)
/// onto the canvas, weighted by its coverage.
fn paint_values(
    c: &mut Canvas,
    values: &[f64],
    coverage: &[f32],
    n: usize,
    to_color: impl Fn(f64) -> Rgb,
) {
    let missing: Rgb = color::hex(0x9A9A9A);
    for y in 0..n {
        for x in 0..n {
            let k = coverage[y * n + x];
            if k > 0.0 {
                let v = values[y * n + x];
                let col = if v.is_finite() { to_color(v) } else { missing };
                c.blend(x as i32, y as i32, col, k);
            }
        }
    }
}

/// Guides over the data: θ = 30°, 60° circles with their labels, the φ axes with their
/// ticks and labels, the pole mark and the outline.
fn draw_guides(c: &mut Canvas, g: &DiscGeometry, map: ColorMap, ts: u32) {
    let centre = [g.cx, g.cy];
    // Light guides over dark maps, dark guides over maps with a light end or middle.
    let light_bg = matches!(map, ColorMap::BlueWhiteRed | ColorMap::Gray);
    let (guide, halo) = if light_bg {
        (color::hex(0x303030), color::WHITE)
    } else {
        (color::WHITE, color::hex(0x303030))
    };
    for deg in [30.0f64, 60.0] {
        c.circle_alpha(
            centre,
            g.circle_radius(deg.to_radians()),
            f64::from(ts),
            guide,
            0.55,
        );
    }
    draw_phi_axes(c, g, guide, ts);
    // Small centre mark (the pole).
    c.disc_alpha(centre, 1.5 * f64::from(ts), guide, 0.7);
    draw_theta_labels(c, g, guide, halo, ts);
    c.circle(centre, g.radius, f64::from(ts), color::AXIS);
}

/// The φ = 0°, 90°, 180°, 270° axes: a short inner mark, an outer tick and a label each.
fn draw_phi_axes(c: &mut Canvas, g: &DiscGeometry, guide: Rgb, ts: u32) {
    let radius = g.radius;
    let tick = 5.0 * f64::from(ts);
    for (k, label) in ["0°", "90°", "180°", "270°"].iter().enumerate() {
        let a = k as f64 * std::f64::consts::FRAC_PI_2;
        let (ca, sa) = (a.cos(), -a.sin());
        // A short inner cross-hair mark and an outer tick.
        c.polyline_alpha(
            &[
                [g.cx + ca * (radius - tick), g.cy + sa * (radius - tick)],
                [g.cx + ca * radius, g.cy + sa * radius],
            ],
            f64::from(ts),
            guide,
            0.55,
        );
        c.line(
            [g.cx + ca * radius, g.cy + sa * radius],
            [g.cx + ca * (radius + tick), g.cy + sa * (radius + tick)],
            f64::from(ts),
            color::AXIS,
        );
        let off = radius + tick + 3.0 * f64::from(ts);
        let (lx, ly) = (
            (g.cx + ca * off).round() as i32,
            (g.cy + sa * off).round() as i32,
        );
        let anchor = match k {
            0 => Anchor::MiddleLeft,
            1 => Anchor::BottomCenter,
            2 => Anchor::MiddleRight,
            _ => Anchor::TopCenter,
        };
        font::draw_text_anchored(c, lx, ly, label, ts, color::INK_SOFT, anchor);
    }
}

/// θ labels on the 30° and 60° circles, along φ = 45°, with a halo for contrast on any colour.
fn draw_theta_labels(c: &mut Canvas, g: &DiscGeometry, guide: Rgb, halo: Rgb, ts: u32) {
    let u = ts as i32;
    for deg in [30.0f64, 60.0] {
        let r = g.circle_radius(deg.to_radians());
        let a = 45f64.to_radians();
        let (x, y) = (
            g.cx + r * a.cos() + 3.0 * f64::from(ts),
            g.cy - r * a.sin() - 3.0 * f64::from(ts),
        );
        let text = format!("{}°", deg as i32);
        let (x0, y0) = font::anchored_origin(x as i32, y as i32, &text, ts, Anchor::BottomLeft);
        for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
            font::draw_text(c, x0 + dx * u, y0 + dy * u, &text, ts, halo);
        }
        font::draw_text(c, x0, y0, &text, ts, guide);
    }
}

fn auto_range(values: &[f64], map: ColorMap, scale: ValueScale) -> Result<(f64, f64), PlotError> {
    let finite = values.iter().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return Err(PlotError::NoData(
            "the function has no finite value on the hemisphere".into(),
        ));
    }
    match scale {
        ValueScale::Linear => {
            let (a, b) = if map.is_diverging() {
                let m = lo.abs().max(hi.abs());
                (-m, m)
            } else {
                (lo.min(0.0), hi)
            };
            Ok(if b > a { (a, b) } else { (a, a + 1.0) })
        }
        ValueScale::Log => {
            if hi <= 0.0 {
                return Err(PlotError::NoData("no positive value for a log map".into()));
            }
            let lo_pos = values
                .iter()
                .copied()
                .filter(|v| v.is_finite() && *v > 0.0)
                .fold(f64::MAX, f64::min);
            let a = lo_pos.max(hi * 1e-4);
            Ok(if hi > a { (a, hi) } else { (hi / 10.0, hi) })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::frame::{spherical_angles, spherical_direction};

    #[test]
    fn projection_round_trips() {
        for (t, p) in [(0.1, 0.2), (1.0, 2.0), (1.5, 4.0), (0.7, 5.9)] {
            let d = spherical_direction(t, p);
            let (u, v) = direction_to_lambert(d);
            let back = lambert_to_direction(u, v, true).unwrap();
            assert!((back - d).length() < 1e-12);
            let dl = DVec3::new(d.x, d.y, -d.z);
            let (u2, v2) = direction_to_lambert(dl);
            assert!((lambert_to_direction(u2, v2, false).unwrap() - dl).length() < 1e-12);
        }
        assert!(lambert_to_direction(0.8, 0.8, true).is_none());
        assert!(lambert_to_direction(f64::NAN, 0.0, true).is_none());
    }

    #[test]
    fn equal_area_sixty_degree_circle_holds_half_the_pixels() {
        // Solid-angle fraction of θ < 60° is 1 − cos 60° = 0.5 of the hemisphere.
        let m = hemisphere_map(|d| d.z, 512, ColorMap::Viridis, ValueScale::Linear, true).unwrap();
        let g = m.geometry;
        let (mut inside, mut total) = (0usize, 0usize);
        for y in 0..512 {
            for x in 0..512 {
                if let Some(d) = g.direction_at(f64::from(x) + 0.5, f64::from(y) + 0.5) {
                    total += 1;
                    if spherical_angles(d).0 < 60f64.to_radians() {
                        inside += 1;
                    }
                }
            }
        }
        let frac = inside as f64 / total as f64;
        assert!((frac - 0.5).abs() < 0.005, "fraction {frac}");
        // And for 30°: 1 − cos 30°.
        let r30 = g.circle_radius(30f64.to_radians()) / g.radius;
        assert!((r30 * r30 - (1.0 - 30f64.to_radians().cos())).abs() < 1e-12);
    }

    #[test]
    fn orientation_follows_the_frame() {
        // f = x: bright on the right (tangent +x), dark on the left; f = y: bright at the top.
        let m = hemisphere_map(|d| d.x, 256, ColorMap::Gray, ValueScale::Linear, true).unwrap();
        let g = m.geometry;
        let at = |c: &Canvas, x: f64, y: f64| c.get(x as i32, y as i32).unwrap()[0];
        let right = at(&m.canvas, g.cx + 0.8 * g.radius, g.cy);
        let left = at(&m.canvas, g.cx - 0.8 * g.radius, g.cy);
        assert!(right > 0.8 && left < 0.05, "{right} {left}");
        let m = hemisphere_map(|d| d.y, 256, ColorMap::Gray, ValueScale::Linear, false).unwrap();
        let top = at(&m.canvas, g.cx, g.cy - 0.8 * g.radius);
        let bottom = at(&m.canvas, g.cx, g.cy + 0.8 * g.radius);
        assert!(top > 0.8 && bottom < 0.05);
        // pixel_of inverts direction_at.
        let d = spherical_direction(0.9, 1.1);
        let p = g.pixel_of(d).unwrap();
        assert!((g.direction_at(p[0], p[1]).unwrap() - d).length() < 1e-9);
        assert!(g.pixel_of(DVec3::new(0.0, 0.0, -1.0)).is_none());
    }

    #[test]
    fn ranges_and_errors() {
        let m = hemisphere_map(
            |d| d.z.powi(20),
            128,
            ColorMap::Magma,
            ValueScale::Log,
            true,
        )
        .unwrap();
        assert!((m.max - 1.0).abs() < 0.02, "{} {}", m.min, m.max);
        assert!((m.min / m.max - 1e-4).abs() < 1e-12, "{} {}", m.min, m.max);
        let m = hemisphere_map(
            |d| d.x,
            128,
            ColorMap::BlueWhiteRed,
            ValueScale::Linear,
            true,
        )
        .unwrap();
        assert!((m.min + m.max).abs() < 1e-12);
        assert!(hemisphere_map(
            |_| f64::NAN,
            128,
            ColorMap::Viridis,
            ValueScale::Linear,
            true
        )
        .is_err());
        assert!(hemisphere_map(|_| -1.0, 128, ColorMap::Viridis, ValueScale::Log, true).is_err());
        assert!(hemisphere_map(|_| 1.0, 8, ColorMap::Viridis, ValueScale::Linear, true).is_err());
        assert!(hemisphere_map_range(
            |_| 1.0,
            128,
            ColorMap::Viridis,
            ValueScale::Linear,
            true,
            Some((1.0, 0.0))
        )
        .is_err());
        let with_bar = m.with_colorbar("value");
        assert!(with_bar.width() > m.canvas.width());
    }
}
