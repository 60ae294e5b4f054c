//! Height maps and normal maps: loading (PNG, TIFF, EXR), validation and the physical scale.
//!
//! # Conventions
//! * Sample (row `i`, column `j`) lies at `x = j·S`, `y = i·S` with `S` the texel size; heights
//!   are along +z. φ is measured from +x towards +y (see `meso_core::frame`).
//! * Integer images: `h = code / max_code · H` (`max_code` = 255 or 65535); float images (EXR):
//!   `h = value · H`, with `H` the height scale. Colour images are converted to luminance first
//!   (prefer grey images).
//! * Borders: [`Border::Wrap`] (the default) treats the map as one tile of a periodic surface;
//!   [`Border::Clamp`] uses only the samples inside the image (a W×H image then has
//!   (W−1)×(H−1) grid cells).
//! * Size limits, checked from the image header before anything is decoded or allocated:
//!   at most [`MAX_DIMENSION`] samples per side and [`MAX_TEXELS`] samples in all.

use crate::error::{positive, MapError, Result};
use glam::DVec3;
use std::path::{Path, PathBuf};

/// Largest accepted width or height of an image, in samples.
pub const MAX_DIMENSION: u64 = 65_536;
/// Largest accepted number of samples (width × height) of an image: 4096².
pub const MAX_TEXELS: u64 = 16_777_216;

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
}

/// Green-channel convention of a tangent-space normal map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NormalConvention {
    /// OpenGL: green is +y (the default).
    #[default]
    Gl,
    /// DirectX: green is −y.
    Dx,
}

/// A tangent-space normal map: one unit normal per texel (local frame, normal +z).
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    width: usize,
    height: usize,
    normals: Vec<DVec3>,
}

fn check_dims(path: &Path, w: u64, h: u64) -> Result<()> {
    if w == 0 || h == 0 {
        return Err(MapError::Empty {
            path: path.to_path_buf(),
            width: w,
            height: h,
        });
    }
    if w > MAX_DIMENSION || h > MAX_DIMENSION || w.saturating_mul(h) > MAX_TEXELS {
        return Err(MapError::TooLarge {
            path: path.to_path_buf(),
            width: w,
            height: h,
            max_dim: MAX_DIMENSION,
            max_texels: MAX_TEXELS,
        });
    }
    Ok(())
}

fn decode_err(path: &Path, e: impl std::fmt::Display) -> MapError {
    MapError::Decode {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Read the header, check the size limits, then decode (with decoder limits set as well).
fn open_image(path: &Path) -> Result<image::DynamicImage> {
    let io = |e: std::io::Error| MapError::Io {
        path: path.to_path_buf(),
        source: e,
    };
    let bytes = std::fs::read(path).map_err(io)?;
    decode_bytes(path, &bytes)
}

fn decode_bytes(path: &Path, bytes: &[u8]) -> Result<image::DynamicImage> {
    if bytes.is_empty() {
        return Err(MapError::Empty {
            path: path.to_path_buf(),
            width: 0,
            height: 0,
        });
    }
    // PNG: the size is in the IHDR chunk at a fixed offset; check it before the decoder reads on.
    if bytes.len() >= 24 && bytes[..8] == [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A] {
        let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap_or([0; 4]));
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap_or([0; 4]));
        check_dims(path, w as u64, h as u64)?;
    }
    let reader = || {
        let mut r = image::ImageReader::new(std::io::Cursor::new(bytes));
        r.set_format(image::ImageFormat::from_path(path).unwrap_or(image::ImageFormat::Png));
        let r = r.with_guessed_format().map_err(|e| decode_err(path, e))?;
        if r.format().is_none() {
            return Err(decode_err(path, "unknown image format"));
        }
        Ok(r)
    };
    let (w, h) = reader()?
        .into_dimensions()
        .map_err(|e| decode_err(path, e))?;
    check_dims(path, w as u64, h as u64)?;
    let mut r = reader()?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_DIMENSION as u32);
    limits.max_image_height = Some(MAX_DIMENSION as u32);
    limits.max_alloc = Some(MAX_TEXELS * 16 + (1 << 20));
    r.limits(limits);
    let img = r.decode().map_err(|e| decode_err(path, e))?;
    check_dims(path, img.width() as u64, img.height() as u64)?;
    Ok(img)
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
        check_dims(&mem, width as u64, height as u64)?;
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

    /// Load a grey PNG (8/16-bit), 16-bit TIFF or float EXR height map with texel size `S` and
    /// height scale `H` (both in the same length unit, > 0). See the module docs for the scale.
    pub fn load(
        path: &Path,
        texel_size: f64,
        height_scale: f64,
        border: Border,
    ) -> Result<HeightMap> {
        positive("texel_size", texel_size)?;
        positive("height_scale", height_scale)?;
        let img = open_image(path)?;
        Self::from_image(img, texel_size, height_scale, border)
    }

    /// Like [`HeightMap::load`], from the bytes of an image file (`name` chooses the format
    /// when the content does not say).
    pub fn from_bytes(
        name: &Path,
        bytes: &[u8],
        texel_size: f64,
        height_scale: f64,
        border: Border,
    ) -> Result<HeightMap> {
        positive("texel_size", texel_size)?;
        positive("height_scale", height_scale)?;
        let img = decode_bytes(name, bytes)?;
        Self::from_image(img, texel_size, height_scale, border)
    }

    fn from_image(
        img: image::DynamicImage,
        texel_size: f64,
        height_scale: f64,
        border: Border,
    ) -> Result<HeightMap> {
        use image::DynamicImage as D;
        let (w, h) = (img.width() as usize, img.height() as usize);
        let heights: Vec<f64> = match img {
            D::ImageLuma8(b) => b.pixels().map(|p| p.0[0] as f64 / 255.0).collect(),
            D::ImageLumaA8(b) => b.pixels().map(|p| p.0[0] as f64 / 255.0).collect(),
            D::ImageLuma16(b) => b.pixels().map(|p| p.0[0] as f64 / 65535.0).collect(),
            D::ImageLumaA16(b) => b.pixels().map(|p| p.0[0] as f64 / 65535.0).collect(),
            D::ImageRgb32F(b) => b.pixels().map(|p| p.0[0] as f64).collect(),
            D::ImageRgba32F(b) => b.pixels().map(|p| p.0[0] as f64).collect(),
            D::ImageRgb16(_) | D::ImageRgba16(_) => img
                .to_luma16()
                .pixels()
                .map(|p| p.0[0] as f64 / 65535.0)
                .collect(),
            other => other
                .to_luma8()
                .pixels()
                .map(|p| p.0[0] as f64 / 255.0)
                .collect(),
        };
        let heights = heights.into_iter().map(|v| v * height_scale).collect();
        HeightMap::from_heights(w, h, heights, texel_size, border)
    }

    /// Number of columns (samples along x).
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }
    /// Number of rows (samples along y).
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }
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

impl NormalMap {
    /// Load a tangent-space RGB normal map (`n = 2·c/max − 1` per channel, green flipped for
    /// [`NormalConvention::Dx`]); each normal is renormalised, and one of (near) zero length or
    /// pointing below the surface (z ≤ 0) is an error.
    pub fn load(path: &Path, convention: NormalConvention) -> Result<NormalMap> {
        let img = open_image(path)?;
        let (w, h) = (img.width() as usize, img.height() as usize);
        let rgb = img.to_rgb32f();
        let mut normals = Vec::with_capacity(w * h);
        for p in rgb.pixels() {
            let g = 2.0 * p.0[1] as f64 - 1.0;
            let g = if convention == NormalConvention::Dx {
                -g
            } else {
                g
            };
            normals.push(DVec3::new(
                2.0 * p.0[0] as f64 - 1.0,
                g,
                2.0 * p.0[2] as f64 - 1.0,
            ));
        }
        NormalMap::from_normals(w, h, normals)
    }

    /// A normal map from (not necessarily unit) normals, row-major; validated and renormalised.
    pub fn from_normals(width: usize, height: usize, normals: Vec<DVec3>) -> Result<NormalMap> {
        check_dims(Path::new("<memory>"), width as u64, height as u64)?;
        if normals.len() != width * height {
            return Err(MapError::InvalidParameter {
                name: "normals",
                value: format!("{} values", normals.len()),
                reason: "must hold width × height values",
            });
        }
        let mut out = Vec::with_capacity(normals.len());
        for (k, n) in normals.into_iter().enumerate() {
            if !n.is_finite() || n.length() < 1e-6 || n.z <= 0.0 {
                return Err(MapError::NonFinite {
                    what: "normal (NaN, zero length or z ≤ 0)",
                    row: k / width,
                    col: k % width,
                });
            }
            out.push(n.normalize());
        }
        Ok(NormalMap {
            width,
            height,
            normals: out,
        })
    }

    /// Width in texels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in texels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }
    /// Unit normals, row-major.
    #[must_use]
    pub fn normals(&self) -> &[DVec3] {
        &self.normals
    }
}
