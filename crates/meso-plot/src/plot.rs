//! [`LinePlot`]: axes, nice ticks, labels, title, several series and a legend; linear or log y.

use crate::canvas::{Canvas, Rect};
use crate::color::{self, Rgb};
use crate::font::{self, Anchor};
use crate::ticks;
use crate::PlotError;

/// How a series' line is stroked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineStyle {
    /// A continuous line.
    Solid,
    /// Dashes (about 4 line widths on, 2.5 off).
    Dashed,
    /// No line: markers only.
    None,
}

/// One data series of a [`LinePlot`], or a curve of a [`PolarPlot`](crate::PolarPlot)
/// ([`PolarSeries`](crate::PolarSeries)); also used for legends elsewhere.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Name shown in the legend (empty: not listed).
    pub name: String,
    /// Points `[x, y]` (polar: `[θ, value]`); non-finite points (and non-positive `y` on a log
    /// axis, negative values in a polar plot) break the line.
    pub points: Vec<[f64; 2]>,
    /// Colour; `None` takes the next palette colour.
    pub color: Option<Rgb>,
    /// Line width in pixels at text scale 1 (scaled with the plot's text scale).
    pub width: f64,
    /// Line style.
    pub style: LineStyle,
    /// Draw a small disc at every point.
    pub markers: bool,
}

impl Series {
    /// A solid series with the default width and a palette colour.
    #[must_use]
    pub fn new(name: impl Into<String>, points: Vec<[f64; 2]>) -> Series {
        Series {
            name: name.into(),
            points,
            color: None,
            width: 1.5,
            style: LineStyle::Solid,
            markers: false,
        }
    }
    /// Set the colour.
    #[must_use]
    pub fn with_color(mut self, c: Rgb) -> Series {
        self.color = Some(c);
        self
    }
    /// Set the line style.
    #[must_use]
    pub fn with_style(mut self, s: LineStyle) -> Series {
        self.style = s;
        self
    }
    /// Set the line width (pixels at text scale 1).
    #[must_use]
    pub fn with_width(mut self, w: f64) -> Series {
        self.width = w;
        self
    }
    /// Turn point markers on or off.
    #[must_use]
    pub fn with_markers(mut self, on: bool) -> Series {
        self.markers = on;
        self
    }
}

/// The text scale used when a plot's `text_scale` is 0: 1 below 560 pixels wide, else 2.
#[must_use]
pub(crate) fn auto_text_scale(w: u32, h: u32) -> u32 {
    if w >= 560 && h >= 360 {
        2
    } else {
        1
    }
}

/// A legend entry: name, colour, style, markers.
pub(crate) struct LegendEntry<'a> {
    pub name: &'a str,
    pub color: Rgb,
    pub style: LineStyle,
    pub markers: bool,
}

/// Draw a legend box with its top-right corner at `(right, top)`.
pub(crate) fn draw_legend(
    canvas: &mut Canvas,
    right: i32,
    top: i32,
    entries: &[LegendEntry],
    ts: u32,
) {
    let entries: Vec<&LegendEntry> = entries.iter().filter(|e| !e.name.is_empty()).collect();
    if entries.is_empty() {
        return;
    }
    let u = ts as i32;
    let sample = 16 * u;
    let row = (font::LINE_HEIGHT * ts) as i32;
    let pad = 5 * u;
    let text_w = entries
        .iter()
        .map(|e| font::text_width(e.name, ts) as i32)
        .max()
        .unwrap_or(0);
    let w = pad + sample + 4 * u + text_w + pad;
    let h = pad + row * entries.len() as i32 - (row - (font::CAP_HEIGHT * ts) as i32) + pad;
    let r = Rect::new(right - w, top, w as u32, h as u32);
    canvas.blend_rect(r, color::WHITE, 0.92);
    canvas.stroke_rect(r, 1, color::hex(0xC8C8C8));
    for (k, e) in entries.iter().enumerate() {
        let y = top + pad + k as i32 * row;
        let cy = y as f64 + f64::from(font::CAP_HEIGHT * ts) / 2.0;
        let (x0, x1) = (f64::from(r.x + pad), f64::from(r.x + pad + sample));
        let lw = 1.5 * f64::from(ts);
        match e.style {
            LineStyle::Solid => canvas.line([x0, cy], [x1, cy], lw, e.color),
            LineStyle::Dashed => {
                canvas.dashed_polyline(&[[x0, cy], [x1, cy]], lw, 4.0 * lw, 2.5 * lw, e.color)
            }
            LineStyle::None => {}
        }
        if e.markers || e.style == LineStyle::None {
            canvas.disc([(x0 + x1) / 2.0, cy], 2.0 * f64::from(ts), e.color);
        }
        font::draw_text(
            canvas,
            r.x + pad + sample + 4 * u,
            y,
            e.name,
            ts,
            color::INK,
        );
    }
}

/// Stroke one series given already-projected screen points.
pub(crate) fn stroke_series(canvas: &mut Canvas, pts: &[[f64; 2]], s: &Series, c: Rgb, ts: u32) {
    let lw = s.width * f64::from(ts);
    match s.style {
        LineStyle::Solid => canvas.polyline(pts, lw, c),
        LineStyle::Dashed => {
            canvas.dashed_polyline(pts, lw, 4.0 * lw.max(1.0), 2.5 * lw.max(1.0), c)
        }
        LineStyle::None => {}
    }
    if s.markers || s.style == LineStyle::None {
        for p in pts {
            canvas.disc(*p, 2.0 * f64::from(ts), c);
        }
    }
}

/// The text scale for a plot whose own setting is `text_scale` (0: chosen from the area).
#[must_use]
pub(crate) fn resolve_text_scale(text_scale: u32, area: Rect) -> u32 {
    if text_scale > 0 {
        text_scale
    } else {
        auto_text_scale(area.w, area.h)
    }
}

/// Spacing shared by the plots, in pixels, derived from the text scale.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Metrics {
    /// Integer text scale.
    pub ts: u32,
    /// One unit: the text scale as a pixel count.
    pub u: i32,
    /// Outer padding of the area.
    pub pad: i32,
    /// Small gap between neighbouring elements.
    pub gap: i32,
    /// Cap height of text at scale `ts`.
    pub cap: i32,
}

impl Metrics {
    /// The metrics of a plot with text scale setting `text_scale` drawn into `area`.
    #[must_use]
    pub(crate) fn new(text_scale: u32, area: Rect) -> Metrics {
        let ts = resolve_text_scale(text_scale, area);
        let u = ts as i32;
        Metrics {
            ts,
            u,
            pad: 10 * u,
            gap: 5 * u,
            cap: (font::CAP_HEIGHT * ts) as i32,
        }
    }

    /// The text scale of titles.
    #[must_use]
    pub(crate) fn title_scale(&self) -> u32 {
        self.ts + 1
    }

    /// The height a title takes above the plot, its gap included (0 without a title).
    #[must_use]
    pub(crate) fn title_height(&self, title: &str) -> i32 {
        if title.is_empty() {
            0
        } else {
            (font::CAP_HEIGHT * self.title_scale()) as i32 + 3 * self.gap
        }
    }
}

/// One curve ready to stroke: its legend name, look and points already projected to the screen.
pub(crate) struct Curve<'a> {
    pub name: &'a str,
    pub color: Option<Rgb>,
    pub width: f64,
    pub style: LineStyle,
    pub markers: bool,
    pub points: Vec<[f64; 2]>,
}

impl<'a> Curve<'a> {
    /// A curve named `name` with the look `(color, width, style, markers)`, its `points`
    /// projected by `project` (`None`, a point that is not drawn, breaks the line).
    pub(crate) fn project(
        name: &'a str,
        look: (Option<Rgb>, f64, LineStyle, bool),
        points: &[[f64; 2]],
        project: impl Fn(&[f64; 2]) -> Option<[f64; 2]>,
    ) -> Curve<'a> {
        let (color, width, style, markers) = look;
        Curve {
            name,
            color,
            width,
            style,
            markers,
            points: points
                .iter()
                .map(|p| project(p).unwrap_or([f64::NAN, f64::NAN]))
                .collect(),
        }
    }
}

/// A new `width`×`height` paper-coloured canvas with `draw` drawn over all of it.
pub(crate) fn render_on_paper(
    width: u32,
    height: u32,
    draw: impl FnOnce(&mut Canvas, Rect) -> Result<(), PlotError>,
) -> Result<Canvas, PlotError> {
    let mut c = Canvas::try_new(width, height, color::PAPER)?;
    draw(&mut c, Rect::new(0, 0, width, height))?;
    Ok(c)
}

/// Stroke `curves` in order, clipped to `clip` (uncoloured curves take palette colours by
/// index), and return their legend entries.
pub(crate) fn draw_curves<'a>(
    canvas: &mut Canvas,
    clip: Rect,
    curves: Vec<Curve<'a>>,
    ts: u32,
) -> Vec<LegendEntry<'a>> {
    let saved = canvas.clip();
    canvas.set_clip(Some(clip));
    let mut legend = Vec::new();
    for (i, cv) in curves.into_iter().enumerate() {
        let c = cv.color.unwrap_or_else(|| color::palette(i));
        let look = Series {
            name: String::new(),
            points: Vec::new(),
            color: Some(c),
            width: cv.width,
            style: cv.style,
            markers: cv.markers,
        };
        stroke_series(canvas, &cv.points, &look, c, ts);
        legend.push(LegendEntry {
            name: cv.name,
            color: c,
            style: cv.style,
            markers: cv.markers,
        });
    }
    canvas.set_clip(saved);
    legend
}

/// Draw the title (at title scale, top-left corner at `title_at`, if not empty) and then,
/// when `legend_at` is given, the legend with its top-right corner there.
pub(crate) fn draw_title_and_legend(
    canvas: &mut Canvas,
    m: &Metrics,
    title: &str,
    title_at: (i32, i32),
    legend_at: Option<(i32, i32)>,
    legend: &[LegendEntry],
) {
    if !title.is_empty() {
        font::draw_text(
            canvas,
            title_at.0,
            title_at.1,
            title,
            m.title_scale(),
            color::INK,
        );
    }
    if let Some((right, top)) = legend_at {
        draw_legend(canvas, right, top, legend, m.ts);
    }
}

/// A 2-D line plot.
#[derive(Debug, Clone, PartialEq)]
pub struct LinePlot {
    /// Title above the plot (empty: none).
    pub title: String,
    /// Label of the x axis (empty: none).
    pub x_label: String,
    /// Label of the y axis, drawn rotated (empty: none).
    pub y_label: String,
    /// Logarithmic y axis (decade ticks; non-positive values are not drawn).
    pub log_y: bool,
    /// Fixed x range; `None`: the data range.
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range; `None`: the data range extended to nice ticks (or whole decades).
    pub y_range: Option<(f64, f64)>,
    /// The series, drawn in order.
    pub series: Vec<Series>,
    /// Show a legend (top right, inside the axes) when at least one series is named.
    pub legend: bool,
    /// Integer text scale; 0 chooses from the size (1 below 560 px wide, else 2).
    pub text_scale: u32,
}

impl LinePlot {
    /// An empty plot with a title.
    #[must_use]
    pub fn new(title: impl Into<String>) -> LinePlot {
        LinePlot {
            title: title.into(),
            x_label: String::new(),
            y_label: String::new(),
            log_y: false,
            x_range: None,
            y_range: None,
            series: Vec::new(),
            legend: true,
            text_scale: 0,
        }
    }

    /// Add a series.
    pub fn add(&mut self, s: Series) -> &mut LinePlot {
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
        let (x0, x1, y0, y1) = self.data_range()?;
        let (ymin, ymax, yticks) = self.y_axis(y0, y1);
        let xticks = x_ticks(x0, x1);
        let f = self.frame(area, &m, [x0, x1, ymin, ymax], &xticks, &yticks)?;
        self.draw_grid(canvas, &f, &xticks, &yticks);
        let legend = draw_curves(canvas, f.plot, self.curves(&f), m.ts);
        draw_axes(canvas, &f, &m, &xticks, &yticks);
        self.draw_axis_labels(canvas, &f, &m, area);
        let legend_at = self.legend.then_some((f.right - m.gap, f.top + m.gap));
        draw_title_and_legend(
            canvas,
            &m,
            &self.title,
            (f.left, area.y + m.pad),
            legend_at,
            &legend,
        );
        Ok(())
    }

    /// Whether `y` can be drawn on this plot's y axis.
    fn ok_y(&self, y: f64) -> bool {
        y.is_finite() && (!self.log_y || y > 0.0)
    }

    /// The x and y ranges `(x0, x1, y0, y1)`: the drawable data's (or the fixed ranges), an
    /// empty x range widened.
    fn data_range(&self) -> Result<(f64, f64, f64, f64), PlotError> {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for s in &self.series {
            for p in &s.points {
                if p[0].is_finite() && self.ok_y(p[1]) {
                    x0 = x0.min(p[0]);
                    x1 = x1.max(p[0]);
                    y0 = y0.min(p[1]);
                    y1 = y1.max(p[1]);
                }
            }
        }
        if let Some((a, b)) = self.x_range {
            (x0, x1) = (a.min(b), a.max(b));
        }
        if let Some((a, b)) = self.y_range {
            (y0, y1) = (a.min(b), a.max(b));
        }
        if !(x0.is_finite()
            && x1.is_finite()
            && y0.is_finite()
            && y1.is_finite()
            && x0 <= x1
            && y0 <= y1)
        {
            return Err(PlotError::NoData(format!(
                "plot '{}' has no finite{} points",
                self.title,
                if self.log_y { " positive" } else { "" }
            )));
        }
        if self.log_y && y0 <= 0.0 {
            return Err(PlotError::Invalid("log y range must be positive".into()));
        }
        if x1 - x0 <= 0.0 {
            let d = if x0 == 0.0 { 1.0 } else { 0.5 * x0.abs() };
            (x0, x1) = (x0 - d, x1 + d);
        }
        Ok((x0, x1, y0, y1))
    }

    /// The drawn y range and its labelled ticks: whole decades on a log axis, nice ticks on a
    /// linear one (the data range extended to them unless the range is fixed).
    fn y_axis(&self, y0: f64, y1: f64) -> (f64, f64, Ticks) {
        if self.log_y {
            let decs = ticks::log_decades(y0, y1);
            let (a, b) = if self.y_range.is_some() {
                (y0, y1)
            } else {
                (
                    10f64.powi(*decs.first().unwrap_or(&0)),
                    10f64.powi(*decs.last().unwrap_or(&1)),
                )
            };
            let b = if b <= a { a * 10.0 } else { b };
            let t = decs
                .into_iter()
                .filter(|k| {
                    let v = 10f64.powi(*k);
                    v >= a * (1.0 - 1e-9) && v <= b * (1.0 + 1e-9)
                })
                .map(|k| (10f64.powi(k), ticks::format_decade(k)))
                .collect();
            (a, b, t)
        } else {
            let t = ticks::nice_ticks(y0, y1, 5);
            let (a, b) = if self.y_range.is_some() && y1 > y0 {
                (y0, y1)
            } else {
                (t.min, t.max)
            };
            let vals: Ticks = ticks::ticks_within(a, b, 5)
                .into_iter()
                .map(|v| (v, ticks::format_tick(v, t.step)))
                .collect();
            (a, b, vals)
        }
    }

    /// Place the axes in `area`, leaving room for the title, tick labels and axis labels;
    /// `range` is `[x0, x1, ymin, ymax]`.
    fn frame(
        &self,
        area: Rect,
        m: &Metrics,
        range: [f64; 4],
        xticks: &Ticks,
        yticks: &Ticks,
    ) -> Result<Frame, PlotError> {
        let tick_len = 4 * m.u;
        let ylab_w = yticks
            .iter()
            .map(|(_, s)| font::text_width(s, m.ts) as i32)
            .max()
            .unwrap_or(0);
        let mut left = area.x + m.pad + ylab_w + m.gap + tick_len;
        if !self.y_label.is_empty() {
            left += m.cap + 2 * m.gap;
        }
        let mut top = area.y + m.pad;
        if !self.title.is_empty() {
            top += m.title_height(&self.title);
        } else {
            top += m.cap / 2;
        }
        let last_x_label = xticks
            .last()
            .map(|(_, s)| font::text_width(s, m.ts) as i32)
            .unwrap_or(0);
        let right = area.right() - m.pad - (last_x_label / 2).max(m.gap);
        let mut bottom = area.bottom() - m.pad - tick_len - m.gap - m.cap;
        if !self.x_label.is_empty() {
            bottom -= m.cap + 2 * m.gap;
        }
        if right - left < 20 || bottom - top < 20 {
            return Err(PlotError::Invalid(format!(
                "area {}×{} too small for the plot",
                area.w, area.h
            )));
        }
        let [x0, x1, ymin, ymax] = range;
        Ok(Frame {
            left,
            top,
            right,
            bottom,
            plot: Rect::new(left, top, (right - left) as u32, (bottom - top) as u32),
            x0,
            x1,
            ymin,
            ymax,
            log_y: self.log_y,
            pl: f64::from(left) + 0.5,
            pr: f64::from(right) - 0.5,
            pt: f64::from(top) + 0.5,
            pb: f64::from(bottom) - 0.5,
        })
    }

    /// Grid lines at the ticks (and, on a log axis, faint lines at 2..9 of every decade).
    fn draw_grid(&self, canvas: &mut Canvas, f: &Frame, xticks: &Ticks, yticks: &Ticks) {
        for (v, _) in yticks {
            let y = f.sy(*v).round() - 0.5;
            canvas.line([f.pl, y + 1.0], [f.pr, y + 1.0], 1.0, color::GRID);
        }
        if self.log_y {
            let decs = ticks::log_decades(f.ymin, f.ymax);
            for k in decs {
                for m in 2..10 {
                    let v = f64::from(m) * 10f64.powi(k);
                    if v > f.ymin && v < f.ymax {
                        let y = f.sy(v).round() + 0.5;
                        canvas.polyline_alpha(&[[f.pl, y], [f.pr, y]], 1.0, color::GRID, 0.45);
                    }
                }
            }
        }
        for (v, _) in xticks {
            let x = f.sx(*v).round() + 0.5;
            canvas.line([x, f.pt], [x, f.pb], 1.0, color::GRID);
        }
    }

    /// The series projected to the screen (undrawable points break the line).
    fn curves(&self, f: &Frame) -> Vec<Curve<'_>> {
        self.series
            .iter()
            .map(|s| {
                let look = (s.color, s.width, s.style, s.markers);
                Curve::project(&s.name, look, &s.points, |p| {
                    (p[0].is_finite() && self.ok_y(p[1])).then(|| [f.sx(p[0]), f.sy(p[1])])
                })
            })
            .collect()
    }

    /// The x label under the tick labels and the y label, rotated, left of them.
    fn draw_axis_labels(&self, canvas: &mut Canvas, f: &Frame, m: &Metrics, area: Rect) {
        let tick_len = 4 * m.u;
        if !self.x_label.is_empty() {
            let y = f.bottom + 1 + tick_len + m.gap + m.cap + 2 * m.gap;
            font::draw_text_anchored(
                canvas,
                f.left + f.plot.w as i32 / 2,
                y,
                &self.x_label,
                m.ts,
                color::INK,
                Anchor::TopCenter,
            );
        }
        if !self.y_label.is_empty() {
            let w = font::text_width(&self.y_label, m.ts) as i32;
            font::draw_text_vertical(
                canvas,
                area.x + m.pad,
                f.top + f.plot.h as i32 / 2 - w / 2,
                &self.y_label,
                m.ts,
                color::INK,
            );
        }
    }
}

/// Tick positions with their labels.
type Ticks = Vec<(f64, String)>;

/// Nice x ticks over `[x0, x1]` with their labels.
fn x_ticks(x0: f64, x1: f64) -> Ticks {
    let xstep = ticks::nice_ticks(x0, x1, 6).step;
    ticks::ticks_within(x0, x1, 6)
        .into_iter()
        .map(|v| (v, ticks::format_tick(v, xstep)))
        .collect()
}

/// Where a [`LinePlot`]'s axes lie on the canvas and how data maps onto them.
struct Frame {
    left: i32,
    top: i32,
    right: i32,
    bottom: i32,
    /// The axes rectangle (series are clipped to it).
    plot: Rect,
    x0: f64,
    x1: f64,
    ymin: f64,
    ymax: f64,
    log_y: bool,
    /// Pixel-centre bounds of the axes: left, right, top, bottom.
    pl: f64,
    pr: f64,
    pt: f64,
    pb: f64,
}

impl Frame {
    /// Screen x of data `x`.
    fn sx(&self, x: f64) -> f64 {
        self.pl + (x - self.x0) / (self.x1 - self.x0) * (self.pr - self.pl)
    }

    /// Screen y of data `y` (NaN for non-positive `y` on a log axis).
    fn sy(&self, y: f64) -> f64 {
        let t = if self.log_y {
            if y > 0.0 {
                (y / self.ymin).ln() / (self.ymax / self.ymin).ln()
            } else {
                f64::NAN
            }
        } else {
            (y - self.ymin) / (self.ymax - self.ymin)
        };
        self.pb - t * (self.pb - self.pt)
    }
}

/// The left and bottom axis lines with outward ticks and their labels.
fn draw_axes(canvas: &mut Canvas, f: &Frame, m: &Metrics, xticks: &Ticks, yticks: &Ticks) {
    let tick_len = 4 * m.u;
    canvas.fill_rect(Rect::new(f.left - 1, f.top, 1, f.plot.h + 1), color::AXIS);
    canvas.fill_rect(
        Rect::new(f.left - 1, f.bottom, f.plot.w + 1, 1),
        color::AXIS,
    );
    for (v, s) in yticks {
        let y = f.sy(*v).round() as i32;
        canvas.fill_rect(
            Rect::new(f.left - 1 - tick_len, y, tick_len as u32, 1),
            color::AXIS,
        );
        font::draw_text_anchored(
            canvas,
            f.left - 1 - tick_len - m.gap,
            y,
            s,
            m.ts,
            color::INK_SOFT,
            Anchor::MiddleRight,
        );
    }
    for (v, s) in xticks {
        let x = f.sx(*v).round() as i32;
        canvas.fill_rect(Rect::new(x, f.bottom + 1, 1, tick_len as u32), color::AXIS);
        font::draw_text_anchored(
            canvas,
            x,
            f.bottom + 1 + tick_len + m.gap,
            s,
            m.ts,
            color::INK_SOFT,
            Anchor::TopCenter,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count_colour(c: &Canvas, col: Rgb) -> usize {
        c.pixels().iter().filter(|p| **p == col).count()
    }

    #[test]
    fn renders_series_in_their_colours() {
        let mut p = LinePlot::new("Test");
        p.x_label = "x".into();
        p.y_label = "y".into();
        let red = color::hex(0xFF0000);
        let blue = color::hex(0x0000FF);
        p.add(
            Series::new(
                "a",
                (0..50).map(|i| [f64::from(i), f64::from(i * i)]).collect(),
            )
            .with_color(red)
            .with_width(2.0),
        );
        p.add(
            Series::new("b", (0..50).map(|i| [f64::from(i), 100.0]).collect())
                .with_color(blue)
                .with_width(2.0),
        );
        let c = p.render(400, 300).unwrap();
        assert!(count_colour(&c, red) > 100);
        assert!(count_colour(&c, blue) > 100);
    }

    #[test]
    fn log_axis_and_errors() {
        let mut p = LinePlot::new("log");
        p.log_y = true;
        p.add(Series::new("", vec![[0.0, 1e-3], [1.0, 10.0], [2.0, -1.0]]));
        assert!(p.render(300, 200).is_ok());
        let mut empty = LinePlot::new("empty");
        empty.add(Series::new("nan", vec![[f64::NAN, 1.0]]));
        assert!(matches!(empty.render(300, 200), Err(PlotError::NoData(_))));
        let mut tiny = LinePlot::new("tiny");
        tiny.add(Series::new("", vec![[0.0, 0.0], [1.0, 1.0]]));
        assert!(tiny.render(30, 20).is_err());
        assert!(tiny.render(0, 20).is_err());
    }

    #[test]
    fn series_stay_inside_the_axes() {
        let mut p = LinePlot::new("");
        p.legend = false;
        p.x_range = Some((0.0, 1.0));
        p.y_range = Some((0.0, 1.0));
        let red = color::hex(0xFF0000);
        p.add(Series::new("", vec![[-5.0, -5.0], [5.0, 5.0]]).with_color(red));
        let c = p.render(300, 300).unwrap();
        // Red pixels exist, none in the outer 10-pixel margin.
        assert!(count_colour(&c, red) > 50);
        for y in 0..300 {
            for x in 0..300 {
                if x < 10 || y < 10 || x >= 290 || y >= 290 {
                    assert_ne!(c.get(x, y), Some(red));
                }
            }
        }
    }
}
