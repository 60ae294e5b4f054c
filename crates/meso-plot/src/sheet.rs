//! [`Sheet`]: a contact sheet of labelled tiles (images with a caption under each) in a grid
//! under a title.

use crate::canvas::{Canvas, Filter, Rect};
use crate::color;
use crate::font::{self, Anchor};
use crate::PlotError;

/// A contact sheet: tiles of `tile_width`×`tile_height` pixels in `columns` columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Sheet {
    /// Title at the top (empty: none).
    pub title: String,
    /// Number of columns (at least 1).
    pub columns: usize,
    /// Width of a tile's image box in pixels.
    pub tile_width: u32,
    /// Height of a tile's image box in pixels.
    pub tile_height: u32,
    /// Integer text scale; 0 chooses from the tile size (2 from 320 pixels wide).
    pub text_scale: u32,
    tiles: Vec<(Canvas, String)>,
}

impl Sheet {
    /// An empty sheet.
    #[must_use]
    pub fn new(
        title: impl Into<String>,
        columns: usize,
        tile_width: u32,
        tile_height: u32,
    ) -> Sheet {
        Sheet {
            title: title.into(),
            columns: columns.max(1),
            tile_width: tile_width.clamp(16, 4096),
            tile_height: tile_height.clamp(16, 4096),
            text_scale: 0,
            tiles: Vec::new(),
        }
    }

    /// Add an image with a caption. It is scaled to fit the tile, keeping its aspect ratio.
    pub fn add(&mut self, image: Canvas, caption: impl Into<String>) -> &mut Sheet {
        self.tiles.push((image, caption.into()));
        self
    }

    /// Add an 8-bit RGB image (`width * height * 3` bytes) with a caption.
    pub fn add_rgb8(
        &mut self,
        bytes: &[u8],
        width: u32,
        height: u32,
        caption: impl Into<String>,
    ) -> Result<&mut Sheet, PlotError> {
        let c = Canvas::from_rgb8(width, height, bytes)?;
        Ok(self.add(c, caption))
    }

    /// Number of tiles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.tiles.len()
    }

    /// Whether the sheet has no tiles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tiles.is_empty()
    }

    /// The rectangle of tile `i`'s image box in the rendered sheet.
    #[must_use]
    pub fn tile_rect(&self, i: usize) -> Rect {
        let l = self.layout();
        let (col, row) = ((i % self.columns) as i32, (i / self.columns) as i32);
        Rect::new(
            l.margin + col * (self.tile_width as i32 + l.gap),
            l.top + row * (self.tile_height as i32 + l.caption_h + l.gap),
            self.tile_width,
            self.tile_height,
        )
    }

    fn layout(&self) -> Layout {
        let ts = if self.text_scale > 0 {
            self.text_scale
        } else if self.tile_width >= 320 {
            2
        } else {
            1
        };
        let u = ts as i32;
        let margin = 16 * u;
        let gap = 12 * u;
        let caption_h = (font::CAP_HEIGHT * ts) as i32 + 8 * u;
        let title_scale = ts + 1;
        let top = if self.title.is_empty() {
            margin
        } else {
            margin + (font::CAP_HEIGHT * title_scale) as i32 + 2 * gap
        };
        Layout {
            ts,
            margin,
            gap,
            caption_h,
            top,
            title_scale,
        }
    }

    /// Render the sheet.
    pub fn render(&self) -> Result<Canvas, PlotError> {
        let l = self.layout();
        let cols = self.columns.min(self.tiles.len().max(1));
        let rows = self.tiles.len().div_ceil(self.columns).max(1);
        let width = 2 * l.margin + cols as i32 * self.tile_width as i32 + (cols as i32 - 1) * l.gap;
        let title_w = font::text_width(&self.title, l.title_scale) as i32 + 2 * l.margin;
        let width = width.max(title_w);
        let height = l.top
            + rows as i32 * (self.tile_height as i32 + l.caption_h)
            + (rows as i32 - 1) * l.gap
            + l.margin;
        let mut c = Canvas::try_new(width as u32, height as u32, color::SHEET)?;
        if !self.title.is_empty() {
            font::draw_text(
                &mut c,
                l.margin,
                l.margin,
                &self.title,
                l.title_scale,
                color::INK,
            );
            let y = l.margin + (font::CAP_HEIGHT * l.title_scale) as i32 + l.gap;
            c.fill_rect(
                Rect::new(l.margin, y, (width - 2 * l.margin) as u32, 1),
                color::hex(0xCFCFCA),
            );
        }
        for (i, (img, caption)) in self.tiles.iter().enumerate() {
            let r = self.tile_rect(i);
            c.fill_rect(r, color::WHITE);
            // Fit keeping the aspect ratio, centred.
            let s = (f64::from(r.w) / f64::from(img.width()))
                .min(f64::from(r.h) / f64::from(img.height()));
            let (w, h) = (
                ((f64::from(img.width()) * s).round() as u32).clamp(1, r.w),
                ((f64::from(img.height()) * s).round() as u32).clamp(1, r.h),
            );
            let dst = Rect::new(r.x + (r.w - w) as i32 / 2, r.y + (r.h - h) as i32 / 2, w, h);
            let filter = if s < 1.0 {
                Filter::Area
            } else {
                Filter::Bilinear
            };
            c.blit(img, dst, filter);
            c.stroke_rect(
                Rect::new(r.x - 1, r.y - 1, r.w + 2, r.h + 2),
                1,
                color::hex(0xD6D6D0),
            );
            let text = font::fit_text(caption, l.ts, r.w);
            font::draw_text_anchored(
                &mut c,
                r.x + r.w as i32 / 2,
                r.bottom() + 1 + 5 * l.ts as i32,
                &text,
                l.ts,
                color::INK,
                Anchor::TopCenter,
            );
        }
        Ok(c)
    }
}

struct Layout {
    ts: u32,
    margin: i32,
    gap: i32,
    caption_h: i32,
    top: i32,
    title_scale: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_land_in_their_cells() {
        let mut s = Sheet::new("Figures", 2, 60, 40);
        let red = color::hex(0xFF0000);
        let blue = color::hex(0x0000FF);
        s.add(Canvas::new(30, 20, red), "red");
        s.add(Canvas::new(120, 80, blue), "blue");
        s.add_rgb8(&[0, 255, 0].repeat(4), 2, 2, "green").unwrap();
        assert!(s.add_rgb8(&[0; 5], 2, 2, "bad").is_err());
        assert_eq!(s.len(), 3);
        let c = s.render().unwrap();
        for (i, col) in [(0, red), (1, blue), (2, color::hex(0x00FF00))] {
            let r = s.tile_rect(i);
            assert!(r.right() <= c.width() as i32 && r.bottom() <= c.height() as i32);
            assert_eq!(c.get(r.x + 30, r.y + 20), Some(col));
        }
        // Third tile starts a second row.
        assert!(s.tile_rect(2).y > s.tile_rect(0).bottom());
    }

    #[test]
    fn empty_sheet_renders() {
        let c = Sheet::new("", 3, 50, 50).render().unwrap();
        assert!(c.width() > 0 && c.height() > 0);
    }
}
