//! Colours: `[r, g, b]` in `[0, 1]` (sRGB-encoded, as stored in a PNG) and a consistent palette.

/// An RGB colour, each channel in `[0, 1]`, sRGB-encoded (display-referred).
pub type Rgb = [f32; 3];

/// A colour from 8-bit channels.
#[must_use]
pub const fn rgb8(r: u8, g: u8, b: u8) -> Rgb {
    [r as f32 / 255.0, g as f32 / 255.0, b as f32 / 255.0]
}

/// A colour from a `0xRRGGBB` literal.
#[must_use]
pub const fn hex(c: u32) -> Rgb {
    rgb8((c >> 16) as u8, (c >> 8) as u8, c as u8)
}

/// Linear interpolation between two colours, `t` in `[0, 1]`.
#[must_use]
pub fn lerp(a: Rgb, b: Rgb, t: f32) -> Rgb {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// Relative luminance (Rec. 709 weights on the encoded values; good enough to choose a text colour).
#[must_use]
pub fn luma(c: Rgb) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Pure white.
pub const WHITE: Rgb = [1.0, 1.0, 1.0];
/// Pure black.
pub const BLACK: Rgb = [0.0, 0.0, 0.0];
/// Text and axis ink: a near-black grey.
pub const INK: Rgb = hex(0x222222);
/// Secondary text (tick labels, captions).
pub const INK_SOFT: Rgb = hex(0x555555);
/// Axis frame lines.
pub const AXIS: Rgb = hex(0x444444);
/// Grid lines.
pub const GRID: Rgb = hex(0xE3E3E3);
/// Page background of plots and sheets.
pub const PAPER: Rgb = WHITE;
/// Background of a contact sheet.
pub const SHEET: Rgb = hex(0xF4F4F2);

/// The series palette (Tableau 10): distinct, colour-blind friendly enough, print-safe.
pub const PALETTE: [Rgb; 10] = [
    hex(0x4E79A7),
    hex(0xE15759),
    hex(0x59A14F),
    hex(0xF28E2B),
    hex(0xB07AA1),
    hex(0x76B7B2),
    hex(0xEDC948),
    hex(0xFF9DA7),
    hex(0x9C755F),
    hex(0xBAB0AC),
];

/// The `i`-th palette colour (cycling).
#[must_use]
pub fn palette(i: usize) -> Rgb {
    PALETTE[i % PALETTE.len()]
}
