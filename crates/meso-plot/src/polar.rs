//! [`PolarPlot`]: a function of θ drawn in polar coordinates, as BRDF and NDF slices are drawn
//! in the literature: the radius is the value, θ is measured from the normal (straight up),
//! positive θ to the right of the vertical axis and negative θ to the left (the two
//! half-planes of the slice).

use crate::canvas::{arc_points, Canvas, Rect};
use crate::color;
use crate::font::{self, Anchor};
use crate::plot::{draw_curves, draw_title_and_legend, render_on_paper, Curve, Metrics, Series};
use crate::ticks;
use crate::PlotError;
use std::f64::consts::FRAC_PI_2;

/// One curve of a [`PolarPlot`]: a [`Series`] whose points are samples `[θ, value]` with θ in
/// radians, signed (negative: left half-plane), in `[−π/2, π/2]`; non-finite or negative values
/// break the curve.
pub type PolarSeries = Series;

impl Series {
    /// A [`PolarSeries`] sampling `f(θ)` at `n` (≥ 2) evenly spaced θ in `[−π/2, π/2]`.
    #[must_use]
    pub fn from_fn(name: impl Into<String>, f: impl Fn(f64) -> f64, n: usize) -> PolarSeries {
        let n = n.max(2);
        let pts = (0..n)
            .map(|k| {
                let t = -FRAC_PI_2 + std::f64::consts::PI * k as f64 / (n - 1) as f64;
                [t, f(t)]
            })
            .collect();
        PolarSeries::new(name, pts)
    }
}

/// A polar slice plot over the upper half-plane.
#[derive(Debug, Clone, PartialEq)]
pub struct PolarPlot {
    /// Title above the plot (empty: none).
    pub title: String,
    /// Caption of the radial axis, under its tick labels (empty: none).
    pub r_label: String,
    /// The curves.
    pub series: Vec<PolarSeries>,
    /// Fixed outer radius value; `None`: the data maximum rounded up to a nice number.
    pub r_max: Option<f64>,
    /// Incident direction θᵢ (radians, signed) drawn as a dashed ray, if any.
    pub incident: Option<f64>,
    /// Label at the end of the incident ray.
    pub incident_label: String,
    /// Show a legend (top right) when at least one series is named.
    pub legend: bool,
    /// Integer text scale; 0 chooses from the size.
    pub text_scale: u32,
}

impl PolarPlot {
    /// An empty polar plot with a title.
    #[must_use]
    pub fn new(title: impl Into<String>) -> PolarPlot {
        PolarPlot {
            title: title.into(),
            r_label: String::new(),
            series: Vec::new(),
            r_max: None,
            incident: None,
            incident_label: String::from("in"),
            legend: true,
            text_scale: 0,
        }
    }

    /// Add a curve.
    pub fn add(&mut self, s: PolarSeries) -> &mut PolarPlot {
        self.series.push(s);
        self
    }

    /// Render on a new white `width`×`height` canvas.
    pub fn render(&self, width: u32, height: u32) -> Result<Canvas, PlotError> {
        render_on_paper(width, height, |c, area| self.draw(c, area))
    }

    /// Draw into `area` of an existing canvas (the area is not cleared).
    pub fn draw(&self, canvas: &mut Canvas, area: Rect) -> Result<(), PlotError> {
        let m = Metrics::new(self.text_scale, area);
        let rmax = self.radial_range()?;
        let rticks: Vec<f64> = ticks::ticks_within(0.0, rmax, 4)
            .into_iter()
            .filter(|v| *v > 0.0)
            .collect();
        let f = self.frame(area, &m, rmax)?;
        draw_polar_grid(canvas, &f, &rticks);
        draw_angle_labels(canvas, &f, &m);
        self.draw_radial_labels(canvas, &f, &m, &rticks);
        self.draw_incident(canvas, &f, &m);
        // Curves, clipped to the upper half-plane region.
        let clip = Rect::new(area.x, area.y, area.w, (f.base + 1 - area.y).max(0) as u32);
        let legend = draw_curves(canvas, clip, self.curves(&f), m.ts);
        let title_at = (area.x + m.pad, area.y + m.pad);
        let legend_at = self.legend.then_some((
            area.right() - m.pad,
            area.y + m.pad + m.title_height(&self.title),
        ));
        draw_title_and_legend(canvas, &m, &self.title, title_at, legend_at, &legend);
        Ok(())
    }

    /// The outer radius value: `r_max`, or the data maximum rounded up to a nice number.
    fn radial_range(&self) -> Result<f64, PlotError> {
        let vmax = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| p[0].is_finite() && p[1].is_finite() && p[1] >= 0.0)
            .map(|p| p[1])
            .fold(f64::NAN, f64::max);
        match self.r_max {
            Some(r) if r.is_finite() && r > 0.0 => Ok(r),
            Some(r) => Err(PlotError::Invalid(format!("r_max {r} must be positive"))),
            None if vmax.is_finite() && vmax > 0.0 => Ok(ticks::nice_ticks(0.0, vmax, 4).max),
            None => Err(PlotError::NoData(format!(
                "polar plot '{}' has no positive finite values",
                self.title
            ))),
        }
    }

    /// Place the half disc in `area`, leaving room for the title and the labels.
    fn frame(&self, area: Rect, m: &Metrics, rmax: f64) -> Result<PolarFrame, PlotError> {
        let top = area.y + m.pad + m.title_height(&self.title);
        let label_w = font::text_width("90°", m.ts) as i32;
        let top = top + m.cap + 2 * m.gap; // room for the 0° label
        let mut base = area.bottom() - m.pad - m.gap - m.cap; // r tick labels under the baseline
        if !self.r_label.is_empty() {
            base -= m.cap + 2 * m.gap;
        }
        let half_w = area.w as i32 / 2 - m.pad - label_w - 2 * m.gap;
        let radius = half_w.min(base - top);
        if radius < 20 {
            return Err(PlotError::Invalid(format!(
                "area {}×{} too small for a polar plot",
                area.w, area.h
            )));
        }
        Ok(PolarFrame {
            base,
            cx: f64::from(area.x) + f64::from(area.w) / 2.0,
            cy: f64::from(base) + 0.5,
            rr: f64::from(radius),
            rmax,
        })
    }

    /// Radial tick labels (and small ticks) under the baseline on both sides, and the
    /// radial axis caption under them.
    fn draw_radial_labels(&self, canvas: &mut Canvas, f: &PolarFrame, m: &Metrics, rticks: &[f64]) {
        let step = ticks::nice_ticks(0.0, f.rmax, 4).step;
        let y_lab = f.base + 1 + m.gap;
        font::draw_text_anchored(
            canvas,
            f.cx as i32,
            y_lab,
            "0",
            m.ts,
            color::INK_SOFT,
            Anchor::TopCenter,
        );
        for v in rticks {
            let text = ticks::format_tick(*v, step);
            let d = (v / f.rmax * f.rr).round() as i32;
            for side in [-1, 1] {
                let x = f.cx as i32 + side * d;
                canvas.fill_rect(Rect::new(x, f.base + 1, 1, (2 * m.u) as u32), color::AXIS);
                font::draw_text_anchored(
                    canvas,
                    x,
                    y_lab,
                    &text,
                    m.ts,
                    color::INK_SOFT,
                    Anchor::TopCenter,
                );
            }
        }
        if !self.r_label.is_empty() {
            font::draw_text_anchored(
                canvas,
                f.cx as i32,
                y_lab + m.cap + 2 * m.gap,
                &self.r_label,
                m.ts,
                color::INK,
                Anchor::TopCenter,
            );
        }
    }

    /// The incident direction: a dashed ray with an arrow head towards the surface and its
    /// label.
    fn draw_incident(&self, canvas: &mut Canvas, f: &PolarFrame, m: &Metrics) {
        let Some(ti) = self.incident.filter(|t| t.is_finite()) else {
            return;
        };
        let (cx, cy, rr) = (f.cx, f.cy, f.rr);
        let ti = ti.clamp(-FRAC_PI_2, FRAC_PI_2);
        let end = f.to_screen(ti, f.rmax);
        let lw = f64::from(m.ts);
        canvas.dashed_polyline(&[[cx, cy], end], lw, 6.0 * lw, 4.0 * lw, color::INK_SOFT);
        // Arrow head pointing at the surface.
        let (dx, dy) = ((cx - end[0]) / rr, (cy - end[1]) / rr);
        let head = 7.0 * lw;
        let tip = [cx - dx * 0.35 * rr, cy - dy * 0.35 * rr];
        let back = [tip[0] - dx * head, tip[1] - dy * head];
        let (nx, ny) = (-dy * head * 0.45, dx * head * 0.45);
        canvas.polyline(
            &[
                [back[0] + nx, back[1] + ny],
                tip,
                [back[0] - nx, back[1] - ny],
            ],
            1.5 * lw,
            color::INK_SOFT,
        );
        if !self.incident_label.is_empty() {
            let p = f.to_screen(ti, f.rmax * 0.75);
            let anchor = if ti < 0.0 {
                Anchor::BottomRight
            } else {
                Anchor::BottomLeft
            };
            let off = if ti < 0.0 { -m.gap } else { m.gap };
            font::draw_text_anchored(
                canvas,
                p[0] as i32 + off,
                p[1] as i32 - m.gap,
                &self.incident_label,
                m.ts,
                color::INK_SOFT,
                anchor,
            );
        }
    }

    /// The curves projected to the screen (non-finite or negative values break them).
    fn curves(&self, f: &PolarFrame) -> Vec<Curve<'_>> {
        self.series
            .iter()
            .map(|s| {
                let look = (s.color, s.width, s.style, s.markers);
                Curve::project(&s.name, look, &s.points, |p| {
                    (p[0].is_finite() && p[1].is_finite() && p[1] >= 0.0)
                        .then(|| f.to_screen(p[0].clamp(-FRAC_PI_2, FRAC_PI_2), p[1]))
                })
            })
            .collect()
    }
}

/// Where a [`PolarPlot`]'s half disc lies on the canvas.
struct PolarFrame {
    /// Pixel row of the baseline.
    base: i32,
    /// Screen centre of the disc.
    cx: f64,
    cy: f64,
    /// Radius in pixels.
    rr: f64,
    /// The value at the outer radius.
    rmax: f64,
}

impl PolarFrame {
    /// Screen position of the value `r` at angle `theta`.
    fn to_screen(&self, theta: f64, r: f64) -> [f64; 2] {
        let s = r / self.rmax * self.rr;
        [self.cx + s * theta.sin(), self.cy - s * theta.cos()]
    }
}

/// Grid: spokes every 15°, semicircles at the radial ticks, the outer arc and the baseline.
fn draw_polar_grid(canvas: &mut Canvas, f: &PolarFrame, rticks: &[f64]) {
    let (cx, cy, rr, rmax) = (f.cx, f.cy, f.rr, f.rmax);
    for k in -6i32..=6 {
        let t = f64::from(k) * 15f64.to_radians();
        let alpha = if k % 2 == 0 { 1.0 } else { 0.5 };
        canvas.polyline_alpha(&[[cx, cy], f.to_screen(t, rmax)], 1.0, color::GRID, alpha);
    }
    for v in rticks {
        let r = v / rmax * rr;
        let c = if (v - rmax).abs() < 1e-9 * rmax {
            color::AXIS
        } else {
            color::GRID
        };
        canvas.polyline(&arc_points([cx, cy], r, 0.0, std::f64::consts::PI), 1.0, c);
    }
    if rticks.last().is_none_or(|v| (v - rmax).abs() > 1e-9 * rmax) {
        canvas.polyline(
            &arc_points([cx, cy], rr, 0.0, std::f64::consts::PI),
            1.0,
            color::AXIS,
        );
    }
    canvas.line([cx - rr - 0.5, cy], [cx + rr + 0.5, cy], 1.0, color::AXIS);
}

/// Angle labels (0° to 90° either side) around the outside of the half disc.
fn draw_angle_labels(canvas: &mut Canvas, f: &PolarFrame, m: &Metrics) {
    for k in -3i32..=3 {
        let t = f64::from(k) * 30f64.to_radians();
        let [x, y] = f.to_screen(t, f.rmax * (1.0 + f64::from(2 * m.gap) / f.rr));
        let text = format!("{}°", (k * 30).abs());
        let anchor = match k {
            0 => Anchor::BottomCenter,
            3 => Anchor::BottomLeft,
            -3 => Anchor::BottomRight,
            k if k > 0 => Anchor::BottomLeft,
            _ => Anchor::BottomRight,
        };
        let (x, y) = (x.round() as i32, y.round() as i32);
        let y = if k.abs() == 3 {
            f.cy as i32 - m.gap / 2
        } else {
            y
        };
        font::draw_text_anchored(canvas, x, y, &text, m.ts, color::INK_SOFT, anchor);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_function_is_a_semicircle() {
        // f = 1 everywhere with r_max = 1: the curve coincides with the outer arc, so every red
        // pixel lies at the same distance from the centre.
        let red = color::hex(0xFF0000);
        let mut p = PolarPlot::new("");
        p.legend = false;
        p.r_max = Some(2.0);
        p.add(PolarSeries::from_fn("one", |_| 1.0, 181).with_color(red));
        let c = p.render(400, 300).unwrap();
        let reds: Vec<(i32, i32)> = (0..300)
            .flat_map(|y| (0..400).map(move |x| (x, y)))
            .filter(|&(x, y)| c.get(x, y) == Some(red))
            .collect();
        assert!(reds.len() > 100);
        let cx = reds.iter().map(|p| f64::from(p.0)).sum::<f64>() / reds.len() as f64;
        assert!(
            (cx - 199.5).abs() < 1.5,
            "symmetric about the vertical axis: {cx}"
        );
        let ymax = reds.iter().map(|p| p.1).max().unwrap();
        let ymin = reds.iter().map(|p| p.1).min().unwrap();
        let xmin = reds.iter().map(|p| p.0).min().unwrap();
        let xmax = reds.iter().map(|p| p.0).max().unwrap();
        // Width of the semicircle is twice its height.
        let (w, h) = (f64::from(xmax - xmin), f64::from(ymax - ymin));
        assert!((w / h - 2.0).abs() < 0.06, "w {w} h {h}");
    }

    #[test]
    fn right_half_plane_is_positive_theta() {
        let red = color::hex(0xFF0000);
        let mut p = PolarPlot::new("");
        p.legend = false;
        p.add(PolarSeries::new("", vec![[0.05, 0.3], [FRAC_PI_2 * 0.5, 1.0]]).with_color(red));
        let c = p.render(300, 220).unwrap();
        let reds: Vec<i32> = (0..220)
            .flat_map(|y| (0..300).map(move |x| (x, y)))
            .filter(|&(x, y)| c.get(x, y).is_some_and(|p| p[0] > 0.9 && p[1] < 0.6))
            .map(|(x, _)| x)
            .collect();
        assert!(!reds.is_empty());
        assert!(reds.iter().all(|&x| x >= 148), "{:?}", reds.iter().min());
    }

    #[test]
    fn errors_on_empty_or_bad_input() {
        let mut p = PolarPlot::new("x");
        assert!(matches!(p.render(300, 300), Err(PlotError::NoData(_))));
        p.add(PolarSeries::from_fn("", |t| t.cos(), 50));
        p.r_max = Some(-1.0);
        assert!(p.render(300, 300).is_err());
        p.r_max = None;
        assert!(p.render(300, 300).is_ok());
        assert!(p.render(40, 30).is_err());
    }
}
