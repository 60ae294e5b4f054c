//! Colour maps (viridis, magma, diverging blue–white–red, grey) and colour bars.

use crate::canvas::{Canvas, Rect};
use crate::color::{self, Rgb};
use crate::font::{self, Anchor};
use crate::ticks;

/// A colour map from `t ∈ [0, 1]` to a colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorMap {
    /// Viridis (van der Walt & Smith 2015): perceptually uniform, dark blue → yellow.
    Viridis,
    /// Magma (van der Walt & Smith 2015): perceptually uniform, black → purple → cream.
    Magma,
    /// Diverging blue → white → red (ColorBrewer RdBu, reversed); white at `t = 0.5`.
    BlueWhiteRed,
    /// Linear grey ramp, black → white.
    Gray,
}

/// How data values map onto `[0, 1]` before the colour map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueScale {
    /// `t = (v − min)/(max − min)`.
    Linear,
    /// `t = (log v − log min)/(log max − log min)`; non-positive values map to 0.
    Log,
}

impl ValueScale {
    /// Normalise `v` to `[0, 1]` within `[min, max]` (clamped; 0 for NaN or degenerate ranges).
    #[must_use]
    pub fn normalize(self, v: f64, min: f64, max: f64) -> f64 {
        let t = match self {
            ValueScale::Linear => (v - min) / (max - min),
            ValueScale::Log => {
                if v <= 0.0 || min <= 0.0 || max <= 0.0 {
                    0.0
                } else {
                    (v / min).ln() / (max / min).ln()
                }
            }
        };
        if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else if t == f64::INFINITY {
            1.0
        } else {
            0.0
        }
    }

    /// The value at normalised position `t` (inverse of [`ValueScale::normalize`]).
    #[must_use]
    pub fn denormalize(self, t: f64, min: f64, max: f64) -> f64 {
        match self {
            ValueScale::Linear => min + t * (max - min),
            ValueScale::Log => min * (max / min).powf(t),
        }
    }
}

// Control points: every 8th entry of the published 256-entry tables (van der Walt & Smith,
// BIDS/colormap, CC0), plus the last; entry i sits at t = min(8i, 255)/255.
const VIRIDIS: [[f32; 3]; 33] = [
    [0.267004, 0.004874, 0.329415],
    [0.277018, 0.050344, 0.375715],
    [0.282327, 0.094955, 0.417331],
    [0.282884, 0.135920, 0.453427],
    [0.278826, 0.175490, 0.483397],
    [0.270595, 0.214069, 0.507052],
    [0.258965, 0.251537, 0.524736],
    [0.244972, 0.287675, 0.537260],
    [0.229739, 0.322361, 0.545706],
    [0.214298, 0.355619, 0.551184],
    [0.199430, 0.387607, 0.554642],
    [0.185556, 0.418570, 0.556753],
    [0.172719, 0.448791, 0.557885],
    [0.160665, 0.478540, 0.558115],
    [0.149039, 0.508051, 0.557250],
    [0.137770, 0.537492, 0.554906],
    [0.127568, 0.566949, 0.550556],
    [0.120565, 0.596422, 0.543611],
    [0.120638, 0.625828, 0.533488],
    [0.132268, 0.655014, 0.519661],
    [0.157851, 0.683765, 0.501686],
    [0.196571, 0.711827, 0.479221],
    [0.246070, 0.738910, 0.452024],
    [0.304148, 0.764704, 0.419943],
    [0.369214, 0.788888, 0.382914],
    [0.440137, 0.811138, 0.340967],
    [0.515992, 0.831158, 0.294279],
    [0.595839, 0.848717, 0.243329],
    [0.678489, 0.863742, 0.189503],
    [0.762373, 0.876424, 0.137064],
    [0.845561, 0.887322, 0.099702],
    [0.926106, 0.897330, 0.104071],
    [0.993248, 0.906157, 0.143936],
];

const MAGMA: [[f32; 3]; 33] = [
    [0.001462, 0.000466, 0.013866],
    [0.013708, 0.011771, 0.068667],
    [0.039608, 0.031090, 0.133515],
    [0.074257, 0.052017, 0.202660],
    [0.113094, 0.065492, 0.276784],
    [0.159018, 0.068354, 0.352688],
    [0.211718, 0.061992, 0.418647],
    [0.265447, 0.060237, 0.461840],
    [0.316654, 0.071690, 0.485380],
    [0.366012, 0.090314, 0.497960],
    [0.414709, 0.110431, 0.504662],
    [0.463508, 0.129893, 0.507652],
    [0.512831, 0.148179, 0.507648],
    [0.562866, 0.165368, 0.504692],
    [0.613617, 0.181811, 0.498536],
    [0.664915, 0.198075, 0.488836],
    [0.716387, 0.214982, 0.475290],
    [0.767398, 0.233705, 0.457755],
    [0.816914, 0.255895, 0.436461],
    [0.863320, 0.283729, 0.412403],
    [0.904281, 0.319610, 0.388137],
    [0.937221, 0.364929, 0.368567],
    [0.960949, 0.418323, 0.359630],
    [0.976690, 0.476226, 0.364466],
    [0.986700, 0.535582, 0.382210],
    [0.992785, 0.594891, 0.410283],
    [0.996096, 0.653659, 0.446213],
    [0.997325, 0.711848, 0.488154],
    [0.996898, 0.769591, 0.534892],
    [0.995131, 0.827052, 0.585701],
    [0.992440, 0.884330, 0.640099],
    [0.989434, 0.941470, 0.697519],
    [0.987053, 0.991438, 0.749504],
];

/// ColorBrewer RdBu (11 classes), reversed so that low is blue and high is red.
const BLUE_WHITE_RED: [Rgb; 11] = [
    color::hex(0x053061),
    color::hex(0x2166AC),
    color::hex(0x4393C3),
    color::hex(0x92C5DE),
    color::hex(0xD1E5F0),
    color::hex(0xF7F7F7),
    color::hex(0xFDDBC7),
    color::hex(0xF4A582),
    color::hex(0xD6604D),
    color::hex(0xB2182B),
    color::hex(0x67001F),
];

fn sample_table(table: &[[f32; 3]], pos: impl Fn(usize) -> f64, t: f64) -> Rgb {
    let n = table.len();
    // Find the interval [pos(k), pos(k+1)] containing t.
    let mut k = 0;
    while k + 2 < n && pos(k + 1) < t {
        k += 1;
    }
    let (a, b) = (pos(k), pos(k + 1));
    let f = ((t - a) / (b - a)).clamp(0.0, 1.0) as f32;
    color::lerp(table[k], table[k + 1], f)
}

impl ColorMap {
    /// All maps, for menus and galleries.
    pub const ALL: [ColorMap; 4] = [
        ColorMap::Viridis,
        ColorMap::Magma,
        ColorMap::BlueWhiteRed,
        ColorMap::Gray,
    ];

    /// The colour at `t` (clamped to `[0, 1]`; NaN maps to 0).
    #[must_use]
    pub fn eval(self, t: f64) -> Rgb {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        match self {
            ColorMap::Viridis => sample_table(&VIRIDIS, |i| (8 * i).min(255) as f64 / 255.0, t),
            ColorMap::Magma => sample_table(&MAGMA, |i| (8 * i).min(255) as f64 / 255.0, t),
            ColorMap::BlueWhiteRed => sample_table(&BLUE_WHITE_RED, |i| i as f64 / 10.0, t),
            ColorMap::Gray => [t as f32; 3],
        }
    }

    /// The colour of value `v` in `[min, max]` under `scale`.
    #[must_use]
    pub fn map(self, v: f64, min: f64, max: f64, scale: ValueScale) -> Rgb {
        self.eval(scale.normalize(v, min, max))
    }

    /// Whether the map is diverging (its middle is neutral, meant for signed data around 0).
    #[must_use]
    pub fn is_diverging(self) -> bool {
        matches!(self, ColorMap::BlueWhiteRed)
    }

    /// The map's name as used on the command line (`viridis`, `magma`, `bwr`, `gray`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ColorMap::Viridis => "viridis",
            ColorMap::Magma => "magma",
            ColorMap::BlueWhiteRed => "bwr",
            ColorMap::Gray => "gray",
        }
    }

    /// Parse a name from [`ColorMap::name`] (also accepts `grey` and `blue-white-red`).
    #[must_use]
    pub fn from_name(s: &str) -> Option<ColorMap> {
        match s.to_ascii_lowercase().as_str() {
            "viridis" => Some(ColorMap::Viridis),
            "magma" => Some(ColorMap::Magma),
            "bwr" | "blue-white-red" | "rdbu" => Some(ColorMap::BlueWhiteRed),
            "gray" | "grey" => Some(ColorMap::Gray),
            _ => None,
        }
    }
}

/// A linear colour bar in `rect` with about `ticks` labelled ticks and a `label`.
///
/// Vertical if `rect` is taller than wide (low values at the bottom; ticks and labels to the
/// right of `rect`, the label rotated beyond them), else horizontal (low on the left; ticks and
/// labels below). Leave room outside `rect` for the labels (see [`colorbar_extent`]).
#[allow(clippy::too_many_arguments)]
pub fn colorbar(
    canvas: &mut Canvas,
    rect: Rect,
    map: ColorMap,
    min: f64,
    max: f64,
    ticks: usize,
    label: &str,
) {
    colorbar_scaled(
        canvas,
        rect,
        map,
        min,
        max,
        ValueScale::Linear,
        ticks,
        label,
        1,
    );
}

/// The space a colour bar's ticks and labels need outside its rectangle, in pixels
/// (to the right of a vertical bar, below a horizontal one), for labels at `text_scale`.
#[must_use]
pub fn colorbar_extent(text_scale: u32, label: &str) -> u32 {
    let s = text_scale.max(1);
    let labels = font::text_width("\u{2212}0.000", s) + 4 * s + 2;
    let lab = if label.is_empty() {
        0
    } else {
        font::text_height(s) + 4 * s
    };
    labels + lab
}

/// [`colorbar`] with a value scale (log bars get decade ticks) and a text scale.
#[allow(clippy::too_many_arguments)]
pub fn colorbar_scaled(
    canvas: &mut Canvas,
    rect: Rect,
    map: ColorMap,
    min: f64,
    max: f64,
    scale: ValueScale,
    ticks: usize,
    label: &str,
    text_scale: u32,
) {
    if rect.w == 0 || rect.h == 0 {
        return;
    }
    let ts = text_scale.max(1);
    let vertical = rect.h >= rect.w;
    let n = if vertical { rect.h } else { rect.w };
    for k in 0..n {
        let t = (f64::from(k) + 0.5) / f64::from(n);
        let c = map.eval(t);
        if vertical {
            canvas.fill_rect(
                Rect::new(rect.x, rect.bottom() - 1 - k as i32, rect.w, 1),
                c,
            );
        } else {
            canvas.fill_rect(Rect::new(rect.x + k as i32, rect.y, 1, rect.h), c);
        }
    }
    canvas.stroke_rect(
        Rect::new(rect.x - 1, rect.y - 1, rect.w + 2, rect.h + 2),
        1,
        color::AXIS,
    );
    // Tick positions as (t, label).
    let marks: Vec<(f64, String)> = match scale {
        ValueScale::Log if min > 0.0 && max > min => ticks::log_decades(min, max)
            .into_iter()
            .map(|k| (scale.normalize(10f64.powi(k), min, max), 10f64.powi(k), k))
            .filter(|(_, v, _)| *v >= min * (1.0 - 1e-9) && *v <= max * (1.0 + 1e-9))
            .map(|(t, _, k)| (t, ticks::format_decade(k)))
            .collect(),
        _ => {
            let step = ticks::nice_ticks(min, max, ticks.max(2)).step;
            ticks::ticks_within(min, max, ticks.max(2))
                .into_iter()
                .map(|v| {
                    (
                        ValueScale::Linear.normalize(v, min, max),
                        ticks::format_tick(v, step),
                    )
                })
                .collect()
        }
    };
    let tick_len = 3 * ts as i32;
    let mut extent = 0i32;
    for (t, text) in &marks {
        if vertical {
            let y = rect.bottom() - 1 - (t * f64::from(rect.h - 1)).round() as i32;
            canvas.fill_rect(
                Rect::new(rect.right() + 1, y, tick_len as u32, 1),
                color::AXIS,
            );
            let (x0, _) = font::draw_text_anchored(
                canvas,
                rect.right() + 3 + tick_len,
                y,
                text,
                ts,
                color::INK_SOFT,
                Anchor::MiddleLeft,
            );
            extent = extent.max(x0 + font::text_width(text, ts) as i32 - rect.right());
        } else {
            let x = rect.x + (t * f64::from(rect.w - 1)).round() as i32;
            canvas.fill_rect(
                Rect::new(x, rect.bottom() + 1, 1, tick_len as u32),
                color::AXIS,
            );
            font::draw_text_anchored(
                canvas,
                x,
                rect.bottom() + 3 + tick_len,
                text,
                ts,
                color::INK_SOFT,
                Anchor::TopCenter,
            );
        }
    }
    if !label.is_empty() {
        if vertical {
            let w = font::text_width(label, ts) as i32;
            let x = rect.right() + extent + 4 * ts as i32;
            let y = rect.y + rect.h as i32 / 2 - w / 2;
            font::draw_text_vertical(canvas, x, y, label, ts, color::INK);
        } else {
            let y = rect.bottom() + 3 + tick_len + (font::LINE_HEIGHT * ts) as i32;
            font::draw_text_anchored(
                canvas,
                rect.x + rect.w as i32 / 2,
                y,
                label,
                ts,
                color::INK,
                Anchor::TopCenter,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn near(a: Rgb, b: [f32; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5)
    }

    #[test]
    fn maps_hit_their_endpoints() {
        assert!(near(
            ColorMap::Viridis.eval(0.0),
            [0.267004, 0.004874, 0.329415]
        ));
        assert!(near(
            ColorMap::Viridis.eval(1.0),
            [0.993248, 0.906157, 0.143936]
        ));
        assert!(near(
            ColorMap::Magma.eval(0.0),
            [0.001462, 0.000466, 0.013866]
        ));
        assert!(near(
            ColorMap::Magma.eval(1.0),
            [0.987053, 0.991438, 0.749504]
        ));
        assert!(near(ColorMap::BlueWhiteRed.eval(0.0), color::hex(0x053061)));
        assert!(near(ColorMap::BlueWhiteRed.eval(1.0), color::hex(0x67001F)));
        assert!(near(ColorMap::BlueWhiteRed.eval(0.5), color::hex(0xF7F7F7)));
        assert!(near(ColorMap::Gray.eval(1.0), [1.0; 3]));
        // Clamping and NaN.
        assert_eq!(ColorMap::Viridis.eval(-3.0), ColorMap::Viridis.eval(0.0));
        assert_eq!(ColorMap::Magma.eval(7.0), ColorMap::Magma.eval(1.0));
        assert_eq!(ColorMap::Magma.eval(f64::NAN), ColorMap::Magma.eval(0.0));
    }

    #[test]
    fn interpolation_matches_published_table_between_control_points() {
        // viridis entry 128 = t 128/255 is a control point (i = 16); entry 100 is not:
        // published value [0.163625, 0.471133, 0.558148].
        assert!(near(
            ColorMap::Viridis.eval(128.0 / 255.0),
            [0.127568, 0.566949, 0.550556]
        ));
        let c = ColorMap::Viridis.eval(100.0 / 255.0);
        for (x, y) in c.iter().zip([0.163625f32, 0.471133, 0.558148]) {
            assert!((x - y).abs() < 2.0 / 255.0, "{c:?}");
        }
    }

    #[test]
    fn perceptual_maps_brighten_monotonically() {
        for m in [ColorMap::Viridis, ColorMap::Magma, ColorMap::Gray] {
            let mut last = -1.0;
            for k in 0..=64 {
                let l = color::luma(m.eval(f64::from(k) / 64.0));
                assert!(l > last, "{m:?} at {k}");
                last = l;
            }
        }
    }

    #[test]
    fn value_scales() {
        assert_eq!(ValueScale::Log.normalize(10.0, 1.0, 100.0), 0.5);
        assert_eq!(ValueScale::Log.normalize(-1.0, 1.0, 100.0), 0.0);
        assert_eq!(ValueScale::Linear.normalize(f64::NAN, 0.0, 1.0), 0.0);
        assert!((ValueScale::Log.denormalize(0.5, 1.0, 100.0) - 10.0).abs() < 1e-12);
        assert_eq!(ColorMap::from_name("Magma"), Some(ColorMap::Magma));
        for m in ColorMap::ALL {
            assert_eq!(ColorMap::from_name(m.name()), Some(m));
        }
    }

    #[test]
    fn colorbar_draws_gradient_inside_rect() {
        let mut c = Canvas::new(120, 220, color::WHITE);
        let r = Rect::new(10, 10, 16, 200);
        colorbar(&mut c, r, ColorMap::Viridis, 0.0, 1.0, 5, "D(m)");
        let bottom = c.get(18, 209).unwrap();
        let top = c.get(18, 10).unwrap();
        assert!(near(bottom, ColorMap::Viridis.eval(0.5 / 200.0)));
        assert!(near(top, ColorMap::Viridis.eval(199.5 / 200.0)));
    }
}
