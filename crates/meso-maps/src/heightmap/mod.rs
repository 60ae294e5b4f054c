//! Height maps: the [`HeightMap`] value (samples, texel size, border mode), its constructors and
//! accessors. Loading images, normal maps and 8-bit dequantisation live in the sub-modules:
//!
//! * `decode` — image headers, the size limits and decoding (shared by height and normal maps);
//! * `load` — a [`HeightMap`] from an image file or its bytes, and back to a 16-bit PNG;
//! * `terraces` — the terrace statistics of 8-bit maps and their dequantisation;
//! * `normal` — tangent-space [`NormalMap`]s and their green-channel convention.
//!
//! # Conventions
//! * Sample (row `i`, column `j`) lies at `x = j·S`, `y = i·S` with `S` the texel size; heights
//!   are along +z. φ is measured from +x towards +y (see `meso_core::frame`).
//! * **Images:** +x is to the right in the image and +y **up** it, +z out of the image towards
//!   the viewer (a right-handed frame; OpenGL / glTF tangent space, where a normal map's green
//!   is +y). Map row 0 (y = 0) is therefore the image's **bottom** row: loading reverses the
//!   image's rows, and [`HeightMap::encode_png16`] writes them back in image order. In texture
//!   coordinates: OpenGL / OBJ `v` (up) is `y / (rows·S)`, glTF's `v` (down, uv (0, 0) at the
//!   image's top-left) is `1 − y / (rows·S)`; meso's renderer takes OpenGL / OBJ `uv`, so a
//!   texture shows the right way up.
//! * 8-bit height images whose terraces make many cells exactly flat are dequantised on load
//!   ([`HeightMap::dequantize`]) and say so in [`HeightMap::warnings`].
//! * Integer images: `h = code / max_code · H` (`max_code` = 255 or 65535); float images (EXR):
//!   `h = value · H`, with `H` the height scale. Colour images are converted to luminance first
//!   (prefer grey images).
//! * Borders: [`Border::Wrap`] (the default) treats the map as one tile of a periodic surface;
//!   [`Border::Clamp`] uses only the samples inside the image (a W×H image then has
//!   (W−1)×(H−1) grid cells).
//! * Size limits, checked from the image header before anything is decoded or allocated:
//!   at most [`MAX_DIMENSION`] samples per side and [`MAX_TEXELS`] samples in all.

/// The `width()` / `height()` accessors of a row-major grid that keeps `width` and `height`
/// fields ([`HeightMap`], [`NormalMap`]), written once; `$unit` names what the grid holds.
macro_rules! grid_size_accessors {
    ($unit:literal) => {
        #[doc = concat!("Number of columns (", $unit, " along x).")]
        #[must_use]
        pub fn width(&self) -> usize {
            self.width
        }
        #[doc = concat!("Number of rows (", $unit, " along y).")]
        #[must_use]
        pub fn height(&self) -> usize {
            self.height
        }
    };
}

mod decode;
mod load;
mod normal;
mod terraces;

pub(crate) use decode::with_texel_limit;
use decode::{check_dims, check_dims_within};
pub use decode::{
    decode_image, probe, probe_bytes, ImageHeader, MAX_DIMENSION, MAX_STREAM_TEXELS, MAX_TEXELS,
};
pub use load::{check_scales, MAX_SLOPE_SCALE, SCALE_RANGE, SEAM_RATIO};
pub use normal::{NormalConvention, NormalMap, GREY_NOT_NORMALS, MIN_CODED_LENGTH, MIN_NORMAL_Z};
pub use terraces::{DEQUANTIZE_ITERATIONS, TERRACE_FRACTION};

use crate::error::{positive, MapError, Result};
use std::path::{Path, PathBuf};

/// How the surface continues beyond the image border.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Border {
    /// The map is one period of a tileable surface (default).
    #[default]
    Wrap,
    /// Only the samples inside the image exist; no cell crosses the border.
    Clamp,
}

/// A height field: `heights[i * width + j]` in length units at `(x, y) = (j·S, i·S)`.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightMap {
    width: usize,
    height: usize,
    texel_size: f64,
    border: Border,
    heights: Vec<f64>,
    warnings: Vec<String>,
}

impl HeightMap {
    /// A height map from heights in length units (row-major, `width × height`), validated:
    /// non-empty, within the size limits, finite heights, `texel_size > 0`.
    pub fn from_heights(
        width: usize,
        height: usize,
        heights: Vec<f64>,
        texel_size: f64,
        border: Border,
    ) -> Result<HeightMap> {
        let mem = PathBuf::from("<memory>");
        // The heights are already in memory: the streamed extraction's limit.
        check_dims_within(&mem, width as u64, height as u64, MAX_STREAM_TEXELS)?;
        positive("texel_size", texel_size)?;
        if heights.len() != width * height {
            return Err(MapError::InvalidParameter {
                name: "heights",
                value: format!("{} values", heights.len()),
                reason: "must hold width × height values",
            });
        }
        if let Some(k) = heights.iter().position(|h| !h.is_finite()) {
            return Err(MapError::NonFinite {
                what: "height",
                row: k / width,
                col: k % width,
            });
        }
        if border == Border::Clamp && (width < 2 || height < 2) {
            return Err(MapError::InvalidParameter {
                name: "border",
                value: "clamp".into(),
                reason: "a clamped map needs at least 2×2 samples (one grid cell)",
            });
        }
        Ok(HeightMap {
            width,
            height,
            texel_size,
            border,
            heights,
            warnings: Vec::new(),
        })
    }

    /// A height map built from `f(x, y)` sampled at `x = j·S`, `y = i·S` (fixtures, tests).
    pub fn from_fn(
        width: usize,
        height: usize,
        texel_size: f64,
        border: Border,
        f: impl Fn(f64, f64) -> f64,
    ) -> Result<HeightMap> {
        check_dims(Path::new("<memory>"), width as u64, height as u64)?;
        let mut h = Vec::with_capacity(width * height);
        for i in 0..height {
            for j in 0..width {
                h.push(f(j as f64 * texel_size, i as f64 * texel_size));
            }
        }
        HeightMap::from_heights(width, height, h, texel_size, border)
    }

    /// What loading noticed about the input and did about it (a colour image converted to
    /// luminance, an image that looks like a normal map, 8-bit terraces dequantised), one line
    /// each, for the user to read. Empty for maps built in memory.
    #[must_use]
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// How far the map's opposite edges are from meeting, along x and along y: the mean
    /// absolute step between the last and the first sample of each row (each column), over the
    /// mean absolute step between neighbours inside the rows (the columns). About 1 on a map
    /// that tiles; much more on a crop of a larger surface, whose seam a wrapped border reads
    /// as a cliff ([`SEAM_RATIO`]). Infinite when the inside is flat and the seam is not; 0
    /// for a map too small to tell (under 3 samples along the axis) or flat throughout.
    #[must_use]
    pub fn seam_ratios(&self) -> (f64, f64) {
        let (w, h) = (self.width, self.height);
        // One axis: `along` samples a line, `across` lines; `at(a, k)` the sample `a` along
        // line `k`.
        let ratio = |along: usize, across: usize, at: &dyn Fn(usize, usize) -> f64| {
            if along < 3 {
                return 0.0;
            }
            let seam = (0..across)
                .map(|k| (at(along - 1, k) - at(0, k)).abs())
                .sum::<f64>()
                / across as f64;
            let inside = (0..across)
                .flat_map(|k| (1..along).map(move |a| (a, k)))
                .map(|(a, k)| (at(a, k) - at(a - 1, k)).abs())
                .sum::<f64>()
                / (across * (along - 1)) as f64;
            if inside > 0.0 {
                seam / inside
            } else if seam > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        };
        (
            ratio(w, h, &|a, k| self.heights[k * w + a]),
            ratio(h, w, &|a, k| self.heights[a * w + k]),
        )
    }

    grid_size_accessors!("samples");
    /// Distance between samples S (length units).
    #[must_use]
    pub fn texel_size(&self) -> f64 {
        self.texel_size
    }
    /// Border mode.
    #[must_use]
    pub fn border(&self) -> Border {
        self.border
    }
    /// All heights, row-major (length units).
    #[must_use]
    pub fn heights(&self) -> &[f64] {
        &self.heights
    }
    /// Grid cells along x: `width` when wrapping, `width − 1` when clamped.
    #[must_use]
    pub fn cells_x(&self) -> usize {
        match self.border {
            Border::Wrap => self.width,
            Border::Clamp => self.width - 1,
        }
    }
    /// Grid cells along y: `height` when wrapping, `height − 1` when clamped.
    #[must_use]
    pub fn cells_y(&self) -> usize {
        match self.border {
            Border::Wrap => self.height,
            Border::Clamp => self.height - 1,
        }
    }
    /// Height at integer sample coordinates, wrapped or clamped by the border mode.
    #[inline]
    #[must_use]
    pub fn at(&self, row: isize, col: isize) -> f64 {
        let (w, h) = (self.width as isize, self.height as isize);
        let (r, c) = match self.border {
            Border::Wrap => (row.rem_euclid(h), col.rem_euclid(w)),
            Border::Clamp => (row.clamp(0, h - 1), col.clamp(0, w - 1)),
        };
        self.heights[(r * w + c) as usize]
    }
    /// Smallest and largest height.
    #[must_use]
    pub fn range(&self) -> (f64, f64) {
        self.heights
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &h| {
                (a.min(h), b.max(h))
            })
    }
    /// The same surface with heights negated (bumps become grooves, §3.1 of the paper).
    #[must_use]
    pub fn negated(&self) -> HeightMap {
        HeightMap {
            heights: self.heights.iter().map(|h| -h).collect(),
            ..self.clone()
        }
    }
}
