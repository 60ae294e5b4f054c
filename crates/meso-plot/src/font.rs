//! An embedded 5×7 bitmap font with integer scaling.
//!
//! Cell: 7 rows above the baseline (cap height 7, x-height 5) and 2 descender rows. Letters and
//! punctuation are proportional (trimmed to their ink, one pixel of spacing); digits are tabular
//! (all 5 pixels wide) so that tick labels line up. Covers ASCII 32..126 and
//! `° θ φ · µ σ α π ² ³ × − – ∈` (U+2212 minus, the same width as `+`). Unknown characters draw as `?`.
//!
//! The glyphs are drawn in `font_data.txt` as `#`/`.` rows, one block per character after an
//! `@` line, so they can be read and fixed by eye.

use crate::canvas::Canvas;
use crate::color::Rgb;
use std::sync::OnceLock;

/// Rows of ink above the baseline (cap height), in font pixels.
pub const CAP_HEIGHT: u32 = 7;
/// Total rows of a glyph cell including descenders, in font pixels.
pub const CELL_HEIGHT: u32 = 9;
/// Recommended distance between baselines, in font pixels.
pub const LINE_HEIGHT: u32 = 12;

const DATA: &str = include_str!("font_data.txt");

/// One glyph: rows as bitmasks (bit `k` = column `k` from the left), and its advance width.
#[derive(Debug, Clone, Copy)]
struct Glyph {
    rows: [u8; CELL_HEIGHT as usize],
    width: u32,
}

fn table() -> &'static Vec<(char, Glyph)> {
    static TABLE: OnceLock<Vec<(char, Glyph)>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut out = Vec::new();
        let mut lines = DATA.lines().peekable();
        while let Some(line) = lines.next() {
            let Some(ch) = line.strip_prefix('@').and_then(|s| s.chars().next()) else {
                continue;
            };
            let mut raw: Vec<&str> = Vec::new();
            while let Some(l) = lines.peek() {
                if l.starts_with('@') {
                    break;
                }
                raw.push(lines.next().unwrap_or_default());
            }
            let cols = raw.iter().map(|r| r.chars().count()).max().unwrap_or(0);
            let mut rows = [0u8; CELL_HEIGHT as usize];
            for (r, l) in raw.iter().take(CELL_HEIGHT as usize).enumerate() {
                for (c, p) in l.chars().enumerate() {
                    if p == '#' {
                        rows[r] |= 1 << c;
                    }
                }
            }
            let tabular = ch.is_ascii_digit();
            let any = rows.iter().fold(0u8, |a, r| a | r);
            let (shift, width) = if tabular || any == 0 {
                (0, cols as u32)
            } else {
                let lo = any.trailing_zeros();
                let hi = 7 - any.leading_zeros();
                (lo, hi - lo + 1)
            };
            for r in &mut rows {
                *r >>= shift;
            }
            out.push((ch, Glyph { rows, width }));
        }
        out
    })
}

fn glyph(c: char) -> Glyph {
    let t = table();
    let find = |c: char| t.iter().find(|(k, _)| *k == c).map(|(_, g)| *g);
    find(c).or_else(|| find('?')).unwrap_or(Glyph {
        rows: [0; CELL_HEIGHT as usize],
        width: 3,
    })
}

/// Whether the font has a glyph of its own for `c` (others draw as `?`).
#[must_use]
pub fn has_glyph(c: char) -> bool {
    table().iter().any(|(k, _)| *k == c)
}

/// Width in pixels of `s` drawn at integer `scale` (no trailing spacing).
#[must_use]
pub fn text_width(s: &str, scale: u32) -> u32 {
    let scale = scale.max(1);
    let mut w = 0u32;
    for (i, c) in s.chars().enumerate() {
        if i > 0 {
            w += 1;
        }
        w += glyph(c).width;
    }
    w.saturating_mul(scale)
}

/// Height in pixels of a line of text at `scale` from its top to the bottom of the descenders.
#[must_use]
pub fn text_height(scale: u32) -> u32 {
    CELL_HEIGHT * scale.max(1)
}

/// Draw `s` with its top-left corner (top of the capitals) at `(x, y)`, each font pixel a
/// `scale`×`scale` square. Returns the drawn width ([`text_width`]).
pub fn draw_text(canvas: &mut Canvas, x: i32, y: i32, s: &str, scale: u32, colour: Rgb) -> u32 {
    let scale = scale.max(1);
    let mut pen = x;
    for (i, c) in s.chars().enumerate() {
        if i > 0 {
            pen += scale as i32;
        }
        let g = glyph(c);
        for (r, bits) in g.rows.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0 {
                    let px = pen + (col * scale) as i32;
                    let py = y + (r as u32 * scale) as i32;
                    for dy in 0..scale as i32 {
                        for dx in 0..scale as i32 {
                            canvas.set(px + dx, py + dy, colour);
                        }
                    }
                }
            }
        }
        pen += (g.width * scale) as i32;
    }
    (pen - x).max(0) as u32
}

/// Draw `s` rotated 90° counter-clockwise (reading bottom to top), with the top-left corner of
/// its rotated bounding box at `(x, y)`; the box is [`text_height`] wide and [`text_width`] tall.
pub fn draw_text_vertical(
    canvas: &mut Canvas,
    x: i32,
    y: i32,
    s: &str,
    scale: u32,
    colour: Rgb,
) -> u32 {
    let scale = scale.max(1);
    let w = text_width(s, scale);
    let h = text_height(scale);
    let mut tmp = Canvas::new(w.max(1), h, [0.0; 3]);
    draw_text(&mut tmp, 0, 0, s, scale, [1.0; 3]);
    for ty in 0..h as i32 {
        for tx in 0..w as i32 {
            if tmp.get(tx, ty).is_some_and(|p| p[0] > 0.5) {
                // (tx, ty) → (ty, w - 1 - tx)
                canvas.set(x + ty, y + w as i32 - 1 - tx, colour);
            }
        }
    }
    w
}

/// Where the anchor point of [`draw_text_anchored`] lies on the text's box
/// (vertically the box spans the capitals, [`CAP_HEIGHT`] font pixels).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Anchor {
    /// Top-left corner.
    TopLeft,
    /// Middle of the top edge.
    TopCenter,
    /// Top-right corner.
    TopRight,
    /// Middle of the left edge.
    MiddleLeft,
    /// Centre.
    Center,
    /// Middle of the right edge.
    MiddleRight,
    /// Bottom-left corner (the baseline).
    BottomLeft,
    /// Middle of the bottom edge (the baseline).
    BottomCenter,
    /// Bottom-right corner (the baseline).
    BottomRight,
}

/// Draw `s` so that `anchor` of its box lands on `(x, y)`. Returns the top-left corner used.
pub fn draw_text_anchored(
    canvas: &mut Canvas,
    x: i32,
    y: i32,
    s: &str,
    scale: u32,
    colour: Rgb,
    anchor: Anchor,
) -> (i32, i32) {
    let (x0, y0) = anchored_origin(x, y, s, scale, anchor);
    draw_text(canvas, x0, y0, s, scale, colour);
    (x0, y0)
}

/// The top-left corner at which [`draw_text`] must start so that `anchor` lands on `(x, y)`.
#[must_use]
pub fn anchored_origin(x: i32, y: i32, s: &str, scale: u32, anchor: Anchor) -> (i32, i32) {
    let w = text_width(s, scale) as i32;
    let h = (CAP_HEIGHT * scale.max(1)) as i32;
    let (fx, fy) = match anchor {
        Anchor::TopLeft => (0, 0),
        Anchor::TopCenter => (1, 0),
        Anchor::TopRight => (2, 0),
        Anchor::MiddleLeft => (0, 1),
        Anchor::Center => (1, 1),
        Anchor::MiddleRight => (2, 1),
        Anchor::BottomLeft => (0, 2),
        Anchor::BottomCenter => (1, 2),
        Anchor::BottomRight => (2, 2),
    };
    (x - fx * w / 2, y - fy * h / 2)
}

/// Shorten `s` with a trailing `...` so that it fits `max_width` pixels at `scale`.
#[must_use]
pub fn fit_text(s: &str, scale: u32, max_width: u32) -> String {
    if text_width(s, scale) <= max_width {
        return s.to_string();
    }
    let chars: Vec<char> = s.chars().collect();
    for n in (0..chars.len()).rev() {
        let t: String = chars[..n].iter().collect::<String>() + "...";
        if text_width(&t, scale) <= max_width {
            return t;
        }
    }
    String::new()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::{BLACK, WHITE};

    fn ink_bbox(c: &Canvas) -> Option<(i32, i32, i32, i32)> {
        let mut bb: Option<(i32, i32, i32, i32)> = None;
        for y in 0..c.height() as i32 {
            for x in 0..c.width() as i32 {
                if c.get(x, y) != Some(WHITE) {
                    bb = Some(match bb {
                        None => (x, y, x, y),
                        Some((a, b, cc, d)) => (a.min(x), b.min(y), cc.max(x), d.max(y)),
                    });
                }
            }
        }
        bb
    }

    #[test]
    fn full_ascii_coverage() {
        for b in 32u8..=126 {
            assert!(has_glyph(b as char), "missing glyph for {:?}", b as char);
        }
        for c in ['°', 'θ', 'φ', '−'] {
            assert!(has_glyph(c));
        }
        // Every printable non-space glyph has ink.
        for b in 33u8..=126 {
            let mut c = Canvas::new(20, 20, WHITE);
            draw_text(&mut c, 2, 2, &(b as char).to_string(), 1, BLACK);
            assert!(ink_bbox(&c).is_some(), "{:?} draws nothing", b as char);
        }
    }

    #[test]
    fn text_renders_within_text_width() {
        let samples = [
            "Hello, World!",
            "θ = 30°, φ ∈ [0, 360)",
            "jgpqy_|",
            "0.125 -1e-3 +42%",
            "W",
            "i",
            "",
        ];
        for scale in 1..=3 {
            for s in samples {
                let mut c = Canvas::new(400, 60, WHITE);
                let w = draw_text(&mut c, 10, 10, s, scale, BLACK);
                assert_eq!(w, text_width(s, scale), "{s:?}");
                match ink_bbox(&c) {
                    None => assert!(s.is_empty()),
                    Some((x0, y0, x1, y1)) => {
                        assert!(x0 >= 10 && x1 < 10 + w as i32, "{s:?} scale {scale}");
                        assert!(y0 >= 10 && y1 < 10 + text_height(scale) as i32);
                        // Ink reaches both ends of the advertised width.
                        assert_eq!(x0, 10, "{s:?}");
                        assert_eq!(x1, 10 + w as i32 - 1, "{s:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn digits_are_tabular_and_scaling_is_exact() {
        let w = text_width("0", 1);
        for d in '0'..='9' {
            assert_eq!(text_width(&d.to_string(), 1), w);
        }
        assert_eq!(text_width("1.5", 3), 3 * text_width("1.5", 1));
        assert!(text_width("i", 1) < text_width("m", 1));
    }

    #[test]
    fn vertical_text_fits_its_box() {
        let mut c = Canvas::new(40, 100, WHITE);
        let w = draw_text_vertical(&mut c, 5, 5, "Value", 2, BLACK);
        let (x0, y0, x1, y1) = ink_bbox(&c).unwrap();
        assert!(x0 >= 5 && x1 < 5 + text_height(2) as i32);
        assert!(y0 >= 5 && y1 < 5 + w as i32);
    }

    #[test]
    fn fit_text_truncates() {
        let t = fit_text("a rather long caption for a tile", 1, 60);
        assert!(t.ends_with("...") && text_width(&t, 1) <= 60);
        assert_eq!(fit_text("ok", 1, 60), "ok");
    }
}
