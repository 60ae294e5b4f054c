//! The raster [`Canvas`]: an RGB f32 image with anti-aliased drawing primitives and PNG output.

use crate::color::Rgb;
use crate::PlotError;
use std::path::Path;

/// An integer rectangle in pixel coordinates (`x`, `y` of the top-left corner, `w`×`h` pixels).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// Left edge (pixel column).
    pub x: i32,
    /// Top edge (pixel row).
    pub y: i32,
    /// Width in pixels.
    pub w: u32,
    /// Height in pixels.
    pub h: u32,
}

impl Rect {
    /// A rectangle from its top-left corner and size.
    #[must_use]
    pub const fn new(x: i32, y: i32, w: u32, h: u32) -> Rect {
        Rect { x, y, w, h }
    }
    /// One past the right edge.
    #[must_use]
    pub fn right(&self) -> i32 {
        self.x.saturating_add(self.w as i32)
    }
    /// One past the bottom edge.
    #[must_use]
    pub fn bottom(&self) -> i32 {
        self.y.saturating_add(self.h as i32)
    }
    /// Whether the pixel `(x, y)` lies inside.
    #[must_use]
    pub fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x && y >= self.y && x < self.right() && y < self.bottom()
    }
}

/// Resampling filter for [`Canvas::blit`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Filter {
    /// Nearest neighbour: crisp pixels (for pixel art, masks, magnified data).
    Nearest,
    /// Bilinear interpolation (for modest magnification).
    Bilinear,
    /// Area average over the source footprint (for minification without aliasing);
    /// falls back to bilinear when magnifying.
    Area,
}

/// An RGB raster image, `f32` per channel, row-major, top row first.
///
/// Values are display-referred (sRGB-encoded) in `[0, 1]`; they are clamped and rounded to 8 bits
/// on output. Pixel `(x, y)` covers the square `[x, x+1) × [y, y+1)`, so its centre is at
/// `(x + 0.5, y + 0.5)`: a 1-pixel line through `y = k + 0.5` is perfectly crisp.
/// All drawing is clipped to the canvas; nothing panics on out-of-range coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    width: u32,
    height: u32,
    data: Vec<Rgb>,
    clip: Option<Rect>,
}

/// Distance from point `p` to the segment `a`–`b`.
fn dist_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (px, py) = (p[0] - a[0], p[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        ((px * dx + py * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (ex, ey) = (px - t * dx, py - t * dy);
    (ex * ex + ey * ey).sqrt()
}

impl Canvas {
    /// The largest supported side length in pixels.
    pub const MAX_SIDE: u32 = 16384;

    /// A `width`×`height` canvas filled with `background`. Sizes are clamped to
    /// `1..=`[`Canvas::MAX_SIDE`]; use [`Canvas::try_new`] to reject bad sizes instead.
    #[must_use]
    pub fn new(width: u32, height: u32, background: Rgb) -> Canvas {
        let width = width.clamp(1, Self::MAX_SIDE);
        let height = height.clamp(1, Self::MAX_SIDE);
        Canvas {
            width,
            height,
            data: vec![background; width as usize * height as usize],
            clip: None,
        }
    }

    /// Like [`Canvas::new`], but an error for a zero or oversized side.
    pub fn try_new(width: u32, height: u32, background: Rgb) -> Result<Canvas, PlotError> {
        if width == 0 || height == 0 || width > Self::MAX_SIDE || height > Self::MAX_SIDE {
            return Err(PlotError::InvalidSize { width, height });
        }
        Ok(Canvas::new(width, height, background))
    }

    /// A canvas from 8-bit RGB bytes (`width * height * 3` values, row-major).
    pub fn from_rgb8(width: u32, height: u32, bytes: &[u8]) -> Result<Canvas, PlotError> {
        Canvas::from_rgb(width, height, bytes, channel_u8)
    }

    /// A canvas from f32 RGB values (`width * height * 3` values, row-major, display-referred).
    pub fn from_rgb_f32(width: u32, height: u32, values: &[f32]) -> Result<Canvas, PlotError> {
        Canvas::from_rgb(width, height, values, channel_f32)
    }

    /// A canvas from RGB values of any type (`width * height * 3`, row-major), each channel read
    /// by `channel` ([`Canvas::from_rgb8`], [`Canvas::from_rgb_f32`]).
    fn from_rgb<T: Copy>(
        width: u32,
        height: u32,
        values: &[T],
        channel: impl Fn(T) -> f32,
    ) -> Result<Canvas, PlotError> {
        check_buffer(width, height, values.len())?;
        let data = values
            .chunks_exact(3)
            .map(|p| [p[0], p[1], p[2]].map(&channel))
            .collect();
        Ok(Canvas {
            width,
            height,
            data,
            clip: None,
        })
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The whole canvas as a [`Rect`].
    #[must_use]
    pub fn rect(&self) -> Rect {
        Rect::new(0, 0, self.width, self.height)
    }

    /// The pixels, row-major.
    #[must_use]
    pub fn pixels(&self) -> &[Rgb] {
        &self.data
    }

    /// The colour at `(x, y)`, or `None` outside the canvas.
    #[must_use]
    pub fn get(&self, x: i32, y: i32) -> Option<Rgb> {
        self.index(x, y).map(|i| self.data[i])
    }

    fn index(&self, x: i32, y: i32) -> Option<usize> {
        if x < 0 || y < 0 || x as u32 >= self.width || y as u32 >= self.height {
            None
        } else {
            Some(y as usize * self.width as usize + x as usize)
        }
    }

    /// Restrict all drawing to `clip` (`None`: the whole canvas). Reading is not affected.
    pub fn set_clip(&mut self, clip: Option<Rect>) {
        self.clip = clip;
    }

    /// The current clip rectangle.
    #[must_use]
    pub fn clip(&self) -> Option<Rect> {
        self.clip
    }

    fn writable(&self, x: i32, y: i32) -> Option<usize> {
        match self.clip {
            Some(r) if !r.contains(x, y) => None,
            _ => self.index(x, y),
        }
    }

    /// Fill the whole canvas (within the clip rectangle) with one colour.
    pub fn fill(&mut self, c: Rgb) {
        match self.clip {
            None => self.data.fill(c),
            Some(r) => self.fill_rect(r, c),
        }
    }

    /// Set one pixel (ignored outside the canvas or the clip rectangle).
    pub fn set(&mut self, x: i32, y: i32, c: Rgb) {
        if let Some(i) = self.writable(x, y) {
            self.data[i] = c;
        }
    }

    /// Blend `c` over the pixel with opacity `alpha` in `[0, 1]` (ignored outside the canvas).
    pub fn blend(&mut self, x: i32, y: i32, c: Rgb, alpha: f32) {
        let a = if alpha.is_finite() {
            alpha.clamp(0.0, 1.0)
        } else {
            return;
        };
        if a <= 0.0 {
            return;
        }
        if let Some(i) = self.writable(x, y) {
            let p = &mut self.data[i];
            for k in 0..3 {
                p[k] += (c[k] - p[k]) * a;
            }
        }
    }

    /// Fill the rectangle with `c` (clipped).
    pub fn fill_rect(&mut self, r: Rect, c: Rgb) {
        self.blend_rect(r, c, 1.0);
    }

    /// Blend `c` over the rectangle with opacity `alpha` (clipped).
    pub fn blend_rect(&mut self, r: Rect, c: Rgb, alpha: f32) {
        let x0 = r.x.max(0);
        let y0 = r.y.max(0);
        let x1 = r.right().min(self.width as i32);
        let y1 = r.bottom().min(self.height as i32);
        for y in y0..y1 {
            for x in x0..x1 {
                self.blend(x, y, c, alpha);
            }
        }
    }

    /// A crisp 1-pixel-per-`width` rectangle outline drawn inside `r`.
    pub fn stroke_rect(&mut self, r: Rect, width: u32, c: Rgb) {
        let w = width.min(r.w).min(r.h);
        self.fill_rect(Rect::new(r.x, r.y, r.w, w), c);
        self.fill_rect(Rect::new(r.x, r.bottom() - w as i32, r.w, w), c);
        self.fill_rect(Rect::new(r.x, r.y, w, r.h), c);
        self.fill_rect(Rect::new(r.right() - w as i32, r.y, w, r.h), c);
    }

    /// Rasterise a coverage function over a clipped bounding box and blend once per pixel.
    /// `cov(px, py)` receives the pixel centre and returns coverage in `[0, 1]`.
    fn paint_coverage(
        &mut self,
        bbox: [f64; 4],
        c: Rgb,
        alpha: f32,
        cov: impl Fn(f64, f64) -> f64,
    ) {
        if !bbox.iter().all(|v| v.is_finite()) {
            return;
        }
        let x0 = (bbox[0].floor().max(0.0)) as i64;
        let y0 = (bbox[1].floor().max(0.0)) as i64;
        let x1 = (bbox[2].ceil().min(f64::from(self.width))) as i64;
        let y1 = (bbox[3].ceil().min(f64::from(self.height))) as i64;
        for y in y0..y1 {
            for x in x0..x1 {
                let k = cov(x as f64 + 0.5, y as f64 + 0.5);
                if k > 0.0 {
                    self.blend(x as i32, y as i32, c, alpha * k.min(1.0) as f32);
                }
            }
        }
    }

    /// An anti-aliased straight line of the given `width` (pixels) with round caps.
    pub fn line(&mut self, a: [f64; 2], b: [f64; 2], width: f64, c: Rgb) {
        self.polyline(&[a, b], width, c);
    }

    /// An anti-aliased polyline with round joins and caps. Each pixel is blended once, so joints
    /// are not darker than the strokes. Non-finite points break the line into pieces.
    pub fn polyline(&mut self, points: &[[f64; 2]], width: f64, c: Rgb) {
        self.polyline_alpha(points, width, c, 1.0);
    }

    /// [`Canvas::polyline`] with an overall opacity.
    pub fn polyline_alpha(&mut self, points: &[[f64; 2]], width: f64, c: Rgb, alpha: f32) {
        if !(width.is_finite() && width > 0.0) || points.is_empty() {
            return;
        }
        let hw = width * 0.5;
        // Thin lines: keep the footprint one pixel wide and reduce the intensity instead.
        let (hw_eff, gain) = if hw < 0.5 { (0.5, 2.0 * hw) } else { (hw, 1.0) };
        let finite: Vec<[f64; 2]> = points
            .iter()
            .copied()
            .filter(|p| p[0].is_finite() && p[1].is_finite())
            .collect();
        if finite.is_empty() {
            return;
        }
        let pad = hw_eff + 1.0;
        let mut bb = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for p in &finite {
            bb[0] = bb[0].min(p[0] - pad);
            bb[1] = bb[1].min(p[1] - pad);
            bb[2] = bb[2].max(p[0] + pad);
            bb[3] = bb[3].max(p[1] + pad);
        }
        let x0 = bb[0].floor().max(0.0) as i64;
        let y0 = bb[1].floor().max(0.0) as i64;
        let x1 = bb[2].ceil().min(f64::from(self.width)) as i64;
        let y1 = bb[3].ceil().min(f64::from(self.height)) as i64;
        if x1 <= x0 || y1 <= y0 {
            return;
        }
        let (bw, bh) = ((x1 - x0) as usize, (y1 - y0) as usize);
        let mut cov = vec![0f32; bw * bh];
        let mut segs: Vec<([f64; 2], [f64; 2])> = Vec::new();
        let mut prev: Option<[f64; 2]> = None;
        for p in points {
            if p[0].is_finite() && p[1].is_finite() {
                segs.push((prev.unwrap_or(*p), *p));
                prev = Some(*p);
            } else {
                prev = None;
            }
        }
        for (a, b) in segs {
            let sx0 = ((a[0].min(b[0]) - pad).floor() as i64).max(x0);
            let sy0 = ((a[1].min(b[1]) - pad).floor() as i64).max(y0);
            let sx1 = ((a[0].max(b[0]) + pad).ceil() as i64).min(x1);
            let sy1 = ((a[1].max(b[1]) + pad).ceil() as i64).min(y1);
            for y in sy0..sy1 {
                for x in sx0..sx1 {
                    let d = dist_to_segment([x as f64 + 0.5, y as f64 + 0.5], a, b);
                    let k = ((hw_eff + 0.5 - d).clamp(0.0, 1.0) * gain) as f32;
                    let slot = &mut cov[(y - y0) as usize * bw + (x - x0) as usize];
                    *slot = slot.max(k);
                }
            }
        }
        for y in 0..bh {
            for x in 0..bw {
                let k = cov[y * bw + x];
                if k > 0.0 {
                    self.blend(x as i32 + x0 as i32, y as i32 + y0 as i32, c, k * alpha);
                }
            }
        }
    }

    /// A dashed polyline: `dash` pixels drawn, `gap` pixels skipped, measured along the path.
    pub fn dashed_polyline(
        &mut self,
        points: &[[f64; 2]],
        width: f64,
        dash: f64,
        gap: f64,
        c: Rgb,
    ) {
        if !(dash > 0.0 && gap >= 0.0 && dash.is_finite() && gap.is_finite()) {
            self.polyline(points, width, c);
            return;
        }
        let period = dash + gap;
        let mut s = 0.0f64; // arc length at the start of the current segment
        let mut piece: Vec<[f64; 2]> = Vec::new();
        for w in points.windows(2) {
            let (a, b) = (w[0], w[1]);
            let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            if !len.is_finite() {
                if piece.len() > 1 {
                    self.polyline(&piece, width, c);
                }
                piece.clear();
                continue;
            }
            let at = |t: f64| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
            let mut t0 = 0.0;
            while t0 < len {
                let phase = (s + t0) % period;
                let on = phase < dash;
                let step = if on { dash - phase } else { period - phase };
                let t1 = (t0 + step).min(len);
                if on {
                    if piece.is_empty() {
                        piece.push(at(t0 / len.max(1e-12)));
                    }
                    piece.push(at(t1 / len.max(1e-12)));
                } else if !piece.is_empty() {
                    self.polyline(&piece, width, c);
                    piece.clear();
                }
                t0 = t1 + 1e-9;
            }
            s += len;
        }
        if piece.len() > 1 {
            self.polyline(&piece, width, c);
        }
    }

    /// A filled, anti-aliased disc of radius `r` centred at `centre`.
    pub fn disc(&mut self, centre: [f64; 2], r: f64, c: Rgb) {
        self.disc_alpha(centre, r, c, 1.0);
    }

    /// [`Canvas::disc`] with an overall opacity.
    pub fn disc_alpha(&mut self, centre: [f64; 2], r: f64, c: Rgb, alpha: f32) {
        if !(r.is_finite() && r > 0.0) {
            return;
        }
        let [cx, cy] = centre;
        let bb = [cx - r - 1.0, cy - r - 1.0, cx + r + 1.0, cy + r + 1.0];
        self.paint_coverage(bb, c, alpha, |x, y| {
            let d = ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
            (r + 0.5 - d).clamp(0.0, 1.0)
        });
    }

    /// An anti-aliased circle outline (a ring of the given stroke `width`) of radius `r`.
    pub fn circle(&mut self, centre: [f64; 2], r: f64, width: f64, c: Rgb) {
        self.circle_alpha(centre, r, width, c, 1.0);
    }

    /// [`Canvas::circle`] with an overall opacity.
    pub fn circle_alpha(&mut self, centre: [f64; 2], r: f64, width: f64, c: Rgb, alpha: f32) {
        if !(r.is_finite() && r >= 0.0 && width.is_finite() && width > 0.0) {
            return;
        }
        let [cx, cy] = centre;
        let hw = width * 0.5;
        let (hw_eff, gain) = if hw < 0.5 { (0.5, 2.0 * hw) } else { (hw, 1.0) };
        let e = r + hw_eff + 1.0;
        let bb = [cx - e, cy - e, cx + e, cy + e];
        self.paint_coverage(bb, c, alpha, |x, y| {
            let d = ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
            (hw_eff + 0.5 - (d - r).abs()).clamp(0.0, 1.0) * gain
        });
    }

    /// An anti-aliased disc with an outline: `fill` inside, a `stroke`-coloured ring of `width`.
    pub fn disc_outlined(&mut self, centre: [f64; 2], r: f64, fill: Rgb, width: f64, stroke: Rgb) {
        self.disc(centre, r, fill);
        self.circle(centre, r, width, stroke);
    }

    /// An arc of the circle of radius `r` from angle `a0` to `a1` (radians, measured
    /// counter-clockwise on screen from +x, i.e. `y` grows upwards for the angle).
    pub fn arc(&mut self, centre: [f64; 2], r: f64, a0: f64, a1: f64, width: f64, c: Rgb) {
        let pts = arc_points(centre, r, a0, a1);
        self.polyline(&pts, width, c);
    }

    /// Copy `src` into `dst` (scaled to the rectangle's size with `filter`; clipped).
    pub fn blit(&mut self, src: &Canvas, dst: Rect, filter: Filter) {
        self.blit_fn(src.width, src.height, dst, filter, |x, y| {
            src.data[y as usize * src.width as usize + x as usize]
        });
    }

    /// Copy 8-bit RGB bytes (`width * height * 3`, row-major) into `dst`, scaled with `filter`.
    pub fn blit_rgb8(
        &mut self,
        bytes: &[u8],
        width: u32,
        height: u32,
        dst: Rect,
        filter: Filter,
    ) -> Result<(), PlotError> {
        self.blit_rgb(bytes, width, height, dst, filter, channel_u8)
    }

    /// Copy f32 RGB values (`width * height * 3`, row-major, display-referred) into `dst`.
    pub fn blit_rgb_f32(
        &mut self,
        values: &[f32],
        width: u32,
        height: u32,
        dst: Rect,
        filter: Filter,
    ) -> Result<(), PlotError> {
        self.blit_rgb(values, width, height, dst, filter, channel_f32)
    }

    /// Copy RGB values of any type (`width * height * 3`, row-major) into `dst`, each channel
    /// read by `channel` ([`Canvas::blit_rgb8`], [`Canvas::blit_rgb_f32`]).
    fn blit_rgb<T: Copy>(
        &mut self,
        values: &[T],
        width: u32,
        height: u32,
        dst: Rect,
        filter: Filter,
        channel: impl Fn(T) -> f32,
    ) -> Result<(), PlotError> {
        check_buffer(width, height, values.len())?;
        self.blit_fn(width, height, dst, filter, |x, y| {
            let i = 3 * (y as usize * width as usize + x as usize);
            [values[i], values[i + 1], values[i + 2]].map(&channel)
        });
        Ok(())
    }

    fn blit_fn(
        &mut self,
        sw: u32,
        sh: u32,
        dst: Rect,
        filter: Filter,
        fetch: impl Fn(u32, u32) -> Rgb,
    ) {
        if sw == 0 || sh == 0 || dst.w == 0 || dst.h == 0 {
            return;
        }
        let sx = f64::from(sw) / f64::from(dst.w);
        let sy = f64::from(sh) / f64::from(dst.h);
        let minify = sx > 1.0 || sy > 1.0;
        for j in 0..dst.h {
            let y = dst.y + j as i32;
            if y < 0 || y >= self.height as i32 {
                continue;
            }
            for i in 0..dst.w {
                let x = dst.x + i as i32;
                if x < 0 || x >= self.width as i32 {
                    continue;
                }
                let c = match filter {
                    Filter::Nearest => {
                        let u = ((f64::from(i) + 0.5) * sx) as u32;
                        let v = ((f64::from(j) + 0.5) * sy) as u32;
                        fetch(u.min(sw - 1), v.min(sh - 1))
                    }
                    Filter::Area if minify => {
                        let u0 = (f64::from(i) * sx).floor() as u32;
                        let v0 = (f64::from(j) * sy).floor() as u32;
                        let u1 = ((f64::from(i + 1) * sx).ceil() as u32).clamp(u0 + 1, sw);
                        let v1 = ((f64::from(j + 1) * sy).ceil() as u32).clamp(v0 + 1, sh);
                        let mut acc = [0f32; 3];
                        for v in v0.min(sh - 1)..v1 {
                            for u in u0.min(sw - 1)..u1 {
                                let p = fetch(u, v);
                                for k in 0..3 {
                                    acc[k] += p[k];
                                }
                            }
                        }
                        let n = ((v1 - v0.min(sh - 1)) * (u1 - u0.min(sw - 1))) as f32;
                        acc.map(|a| a / n)
                    }
                    Filter::Bilinear | Filter::Area => {
                        let u = ((f64::from(i) + 0.5) * sx - 0.5).clamp(0.0, f64::from(sw - 1));
                        let v = ((f64::from(j) + 0.5) * sy - 0.5).clamp(0.0, f64::from(sh - 1));
                        let (u0, v0) = (u.floor() as u32, v.floor() as u32);
                        let (u1, v1) = ((u0 + 1).min(sw - 1), (v0 + 1).min(sh - 1));
                        let (fu, fv) = ((u - f64::from(u0)) as f32, (v - f64::from(v0)) as f32);
                        let top = crate::color::lerp(fetch(u0, v0), fetch(u1, v0), fu);
                        let bot = crate::color::lerp(fetch(u0, v1), fetch(u1, v1), fu);
                        crate::color::lerp(top, bot, fv)
                    }
                };
                self.set(x, y, c);
            }
        }
    }

    /// The pixels as 8-bit RGB bytes (clamped, rounded), row-major.
    #[must_use]
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.data
            .iter()
            .flat_map(|p| p.map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
            .collect()
    }

    /// Encode as an 8-bit RGB PNG in memory (e.g. to serve over HTTP).
    pub fn to_png_bytes(&self) -> Result<Vec<u8>, PlotError> {
        let mut out = Vec::new();
        self.encode_png(&mut out)
            .map_err(|e| PlotError::Png(e.to_string()))?;
        Ok(out)
    }

    fn encode_png(&self, w: &mut dyn std::io::Write) -> Result<(), image::ImageError> {
        use image::ImageEncoder;
        let enc = image::codecs::png::PngEncoder::new(w);
        enc.write_image(
            &self.to_rgb8(),
            self.width,
            self.height,
            image::ExtendedColorType::Rgb8,
        )
    }

    /// Write an 8-bit RGB PNG atomically (through [`meso_core::io::write_atomic_with`]): on any
    /// error no partial file is left at `path`.
    pub fn write_png(&self, path: impl AsRef<Path>) -> Result<(), PlotError> {
        meso_core::io::write_atomic_with(path.as_ref(), |w| {
            self.encode_png(w).map_err(|e| match e {
                image::ImageError::IoError(io) => io,
                other => std::io::Error::other(other.to_string()),
            })
        })?;
        Ok(())
    }
}

/// Points along an arc (angles counter-clockwise on screen from +x), about one per 2 pixels.
pub(crate) fn arc_points(centre: [f64; 2], r: f64, a0: f64, a1: f64) -> Vec<[f64; 2]> {
    if !(r.is_finite() && a0.is_finite() && a1.is_finite()) {
        return Vec::new();
    }
    let n = ((r.abs() * (a1 - a0).abs() / 2.0).ceil() as usize).clamp(8, 4096);
    (0..=n)
        .map(|k| {
            let a = a0 + (a1 - a0) * k as f64 / n as f64;
            [centre[0] + r * a.cos(), centre[1] - r * a.sin()]
        })
        .collect()
}

/// An 8-bit channel as a colour value in `[0, 1]`.
fn channel_u8(v: u8) -> f32 {
    f32::from(v) / 255.0
}

/// An `f32` channel as a colour value: itself, 0 where not finite.
fn channel_f32(v: f32) -> f32 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

fn check_buffer(width: u32, height: u32, got: usize) -> Result<(), PlotError> {
    if width == 0 || height == 0 || width > Canvas::MAX_SIDE || height > Canvas::MAX_SIDE {
        return Err(PlotError::InvalidSize { width, height });
    }
    let expected = width as usize * height as usize * 3;
    if got != expected {
        return Err(PlotError::BufferSize {
            width,
            height,
            expected,
            got,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::{BLACK, WHITE};

    #[test]
    fn png_round_trip() {
        let mut c = Canvas::new(37, 23, [0.2, 0.4, 0.6]);
        c.set(0, 0, [1.0, 0.0, 0.0]);
        c.set(36, 22, [0.0, 1.0, 0.0]);
        c.line([2.0, 3.0], [30.0, 19.0], 1.5, [0.9, 0.8, 0.1]);
        let dir = std::env::temp_dir().join(format!("meso-plot-rt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rt.png");
        c.write_png(&path).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (37, 23));
        assert_eq!(img.as_raw(), &c.to_rgb8());
        assert_eq!(img.get_pixel(0, 0).0, [255, 0, 0]);
        assert_eq!(img.get_pixel(36, 22).0, [0, 255, 0]);
        assert_eq!(img.get_pixel(10, 0).0, [51, 102, 153]);
        // In-memory bytes decode to the same pixels.
        let mem = image::load_from_memory(&c.to_png_bytes().unwrap())
            .unwrap()
            .to_rgb8();
        assert_eq!(mem.as_raw(), img.as_raw());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn write_png_to_missing_dir_fails_cleanly() {
        let c = Canvas::new(4, 4, WHITE);
        let p = std::env::temp_dir()
            .join(format!("meso-plot-nodir-{}", std::process::id()))
            .join("x.png");
        assert!(matches!(c.write_png(&p), Err(PlotError::Io(_))));
        assert!(!p.exists());
    }

    #[test]
    fn line_lights_only_pixels_near_segment() {
        let mut c = Canvas::new(64, 48, WHITE);
        let (a, b) = ([5.3, 7.1], [57.8, 40.2]);
        c.line(a, b, 1.0, BLACK);
        let mut lit = 0;
        for y in 0..48 {
            for x in 0..64 {
                let p = c.get(x, y).unwrap();
                let d = dist_to_segment([x as f64 + 0.5, y as f64 + 0.5], a, b);
                if p != WHITE {
                    lit += 1;
                    assert!(d < 1.0 + 1e-9, "pixel ({x},{y}) lit at distance {d}");
                }
                if d < 0.25 {
                    assert!(
                        p[0] < 0.5,
                        "pixel ({x},{y}) on the segment is too light: {p:?}"
                    );
                }
            }
        }
        // Roughly one to two pixels per unit of length.
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        assert!(
            lit as f64 > len && (lit as f64) < 3.0 * len,
            "lit {lit}, len {len}"
        );
    }

    #[test]
    fn crisp_horizontal_line_and_clipping() {
        let mut c = Canvas::new(20, 10, WHITE);
        c.line([-50.0, 4.5], [80.0, 4.5], 1.0, BLACK);
        for x in 0..20 {
            assert_eq!(c.get(x, 4), Some(BLACK));
            assert_eq!(c.get(x, 3), Some(WHITE));
            assert_eq!(c.get(x, 5), Some(WHITE));
        }
        c.line([f64::NAN, 0.0], [1.0, f64::INFINITY], 1.0, BLACK);
        c.fill_rect(Rect::new(-5, -5, 3, 3), BLACK);
        assert_eq!(c.get(-1, 0), None);
    }

    #[test]
    fn disc_area_matches_pi_r2() {
        let mut c = Canvas::new(100, 100, BLACK);
        c.disc([50.0, 50.0], 30.0, WHITE);
        let area: f64 = c.pixels().iter().map(|p| f64::from(p[0])).sum();
        let expect = std::f64::consts::PI * 900.0;
        assert!((area - expect).abs() / expect < 0.01, "{area} vs {expect}");
    }

    #[test]
    fn blit_scales_and_checks_buffers() {
        let mut src = Canvas::new(2, 2, BLACK);
        src.set(1, 0, WHITE);
        let mut dst = Canvas::new(8, 8, [0.5; 3]);
        dst.blit(&src, Rect::new(0, 0, 8, 8), Filter::Nearest);
        assert_eq!(dst.get(7, 0), Some(WHITE));
        assert_eq!(dst.get(0, 0), Some(BLACK));
        assert_eq!(dst.get(4, 3), Some(WHITE));
        assert_eq!(dst.get(3, 3), Some(BLACK));
        let mut small = Canvas::new(1, 1, BLACK);
        small.blit(&dst, Rect::new(0, 0, 1, 1), Filter::Area);
        assert!((small.get(0, 0).unwrap()[0] - 0.25).abs() < 1e-6);
        assert!(matches!(
            dst.blit_rgb8(&[0; 5], 2, 1, dst.rect(), Filter::Bilinear),
            Err(PlotError::BufferSize { .. })
        ));
        assert!(Canvas::from_rgb8(0, 3, &[]).is_err());
        assert!(Canvas::try_new(0, 3, WHITE).is_err());
    }
}
