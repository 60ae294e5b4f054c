//! Height maps and normal maps: loading (PNG, JPEG, TGA, TIFF, EXR), validation and the physical
//! scale.
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
    warnings: Vec<String>,
}

/// Fraction of exactly flat grid cells, and of cells one code high, above which an 8-bit height
/// map is dequantised on load ([`HeightMap::dequantize`], [`HeightMap::terrace_stats`]).
pub const TERRACE_FRACTION: f64 = 0.02;
/// Smoothing-and-projection rounds of [`HeightMap::dequantize`].
pub const DEQUANTIZE_ITERATIONS: usize = 24;

/// Green-channel convention of a tangent-space normal map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NormalConvention {
    /// OpenGL / glTF / Blender / ambientCG "NormalGL": green is +Y **up in the image** (towards
    /// the image's top row), meso's +y (the default).
    #[default]
    Gl,
    /// DirectX: green points down the image, meso's −y.
    Dx,
}

/// A tangent-space normal map: one unit normal per texel (local frame, normal +z).
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    width: usize,
    height: usize,
    normals: Vec<DVec3>,
    clamped: usize,
}

/// `n` (unit) tilted in its azimuthal plane so that `n_z = MIN_NORMAL_Z`; straight down becomes +x.
fn clamp_above_horizon(n: DVec3) -> DVec3 {
    let r = (n.x * n.x + n.y * n.y).sqrt();
    let (cx, cy) = if r > 1e-12 {
        (n.x / r, n.y / r)
    } else {
        (1.0, 0.0)
    };
    let s = (1.0 - MIN_NORMAL_Z * MIN_NORMAL_Z).sqrt();
    DVec3::new(cx * s, cy * s, MIN_NORMAL_Z)
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

/// What an image file's header says, read without decoding the pixels: enough to budget the
/// memory of loading it ([`ImageHeader::height_map_bytes`], [`ImageHeader::normal_map_bytes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageHeader {
    /// Width in pixels.
    pub width: u64,
    /// Height in pixels.
    pub height: u64,
    /// Bytes per decoded pixel (1 for 8-bit grey, 6 for 16-bit RGB, 16 for float RGBA, …).
    pub bytes_per_pixel: u64,
    /// Whether the image has colour channels.
    pub color: bool,
    /// Whether the samples are 8-bit.
    pub eight_bit: bool,
    /// Size of the file in bytes.
    pub file_bytes: u64,
}

impl ImageHeader {
    /// Number of pixels.
    #[must_use]
    pub fn pixels(&self) -> u64 {
        self.width.saturating_mul(self.height)
    }

    /// Peak memory (bytes) of loading the image as a height map ([`HeightMap::load`]): the file,
    /// the decoded image, the codes and heights (f64), a colour image's float conversion, and
    /// the four buffers of 8-bit dequantisation.
    #[must_use]
    pub fn height_map_bytes(&self) -> u64 {
        let per_pixel = self.bytes_per_pixel
            + 16
            + if self.color { 12 } else { 0 }
            + if self.eight_bit { 32 } else { 0 };
        self.file_bytes + self.pixels().saturating_mul(per_pixel)
    }

    /// Peak memory (bytes) of loading the image as a normal map ([`NormalMap::load`]): the file,
    /// the decoded image, its float RGB conversion and two arrays of normals (f64).
    #[must_use]
    pub fn normal_map_bytes(&self) -> u64 {
        self.file_bytes + self.pixels().saturating_mul(self.bytes_per_pixel + 12 + 48)
    }
}

/// Read an image file's header (size, sample format) without decoding its pixels, and check the
/// size limits ([`MAX_DIMENSION`], [`MAX_TEXELS`]).
///
/// # Errors
/// The file cannot be read, is not an image meso reads, or is too large.
pub fn probe(path: &Path) -> Result<ImageHeader> {
    let io = |e: std::io::Error| MapError::Io {
        path: path.to_path_buf(),
        source: e,
    };
    let file_bytes = std::fs::metadata(path).map_err(io)?.len();
    let mut r = image::ImageReader::open(path).map_err(io)?;
    if r.format().is_none() {
        r.set_format(image::ImageFormat::Png);
    }
    let r = r.with_guessed_format().map_err(io)?;
    if r.format().is_none() {
        return Err(decode_err(path, "unknown image format"));
    }
    let d = r.into_decoder().map_err(|e| decode_err(path, e))?;
    header_of(path, &d, file_bytes)
}

/// The [`ImageHeader`] of an opened decoder (the size limits checked), for [`probe`] and
/// [`probe_bytes`].
fn header_of(path: &Path, d: &impl image::ImageDecoder, file_bytes: u64) -> Result<ImageHeader> {
    let (w, h) = d.dimensions();
    check_dims(path, w as u64, h as u64)?;
    let ct = d.color_type();
    Ok(ImageHeader {
        width: w as u64,
        height: h as u64,
        bytes_per_pixel: ct.bytes_per_pixel() as u64,
        color: ct.has_color(),
        eight_bit: ct.bytes_per_pixel() / ct.channel_count().max(1) == 1,
        file_bytes,
    })
}

/// [`probe`] for the bytes of an image file (`name` chooses the format when the content does not
/// say, and names the source in errors): the header read without decoding the pixels, the size
/// limits checked.
///
/// # Errors
/// Empty bytes, an unknown or broken header, an image above the size limits.
pub fn probe_bytes(name: &Path, bytes: &[u8]) -> Result<ImageHeader> {
    if bytes.is_empty() {
        return Err(MapError::Empty {
            path: name.to_path_buf(),
            width: 0,
            height: 0,
        });
    }
    let mut r = image::ImageReader::new(std::io::Cursor::new(bytes));
    r.set_format(image::ImageFormat::from_path(name).unwrap_or(image::ImageFormat::Png));
    let r = r.with_guessed_format().map_err(|e| decode_err(name, e))?;
    let d = r.into_decoder().map_err(|e| decode_err(name, e))?;
    header_of(name, &d, bytes.len() as u64)
}

/// An allocation error of loading `path`.
fn oom(path: &Path, e: meso_core::budget::AllocError) -> MapError {
    MapError::OutOfMemory {
        what: path.display().to_string(),
        source: e,
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

/// [`open_image`] after checking the memory of loading it (`estimate` from its header) against
/// the budget (`meso_core::budget`).
fn open_image_budgeted(
    path: &Path,
    task: &str,
    estimate: impl Fn(&ImageHeader) -> u64,
) -> Result<image::DynamicImage> {
    // Regular files only (a FIFO cannot be read twice); a header the probe cannot read is left
    // to the decoder, whose errors say more.
    if std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        if let Ok(header) = probe(path) {
            meso_core::budget::check(path, task, estimate(&header))?;
        }
    }
    open_image(path)
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
        let img = open_image_budgeted(
            path,
            "loading the height map",
            ImageHeader::height_map_bytes,
        )?;
        Self::from_image(img, texel_size, height_scale, border).map_err(|e| match e {
            MapError::OutOfMemory { source, .. } => oom(path, source),
            e => e,
        })
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
        let mut warnings = Vec::new();
        if img.color().has_color() {
            let rgb = img.to_rgb32f();
            let n = (w * h) as f64;
            let mean = rgb.pixels().fold([0.0f64; 3], |a, p| {
                [
                    a[0] + p.0[0] as f64,
                    a[1] + p.0[1] as f64,
                    a[2] + p.0[2] as f64,
                ]
            });
            let mean = mean.map(|c| c / n);
            if (mean[0] - 0.5).abs() < 0.1 && (mean[1] - 0.5).abs() < 0.1 && mean[2] > 0.7 {
                warnings.push(format!(
                    "this looks like a tangent-space normal map (mean colour {:.2}, {:.2}, {:.2}), \
                     not a height map: give it as a normal map instead",
                    mean[0], mean[1], mean[2]
                ));
            } else {
                warnings.push(
                    "colour image used as a height map: converted to luminance (prefer a grey image)"
                        .into(),
                );
            }
        }
        let eight_bit = matches!(
            img.color(),
            image::ColorType::L8
                | image::ColorType::La8
                | image::ColorType::Rgb8
                | image::ColorType::Rgba8
        );
        let codes: Vec<f64> = match img {
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
        // Image row 0 is the top; meso's +y is up in the image, so row 0 of the map (y = 0) is
        // the image's bottom row.
        let mut heights = meso_core::budget::try_with_capacity(codes.len()).map_err(|e| {
            MapError::OutOfMemory {
                what: "<image>".into(),
                source: e,
            }
        })?;
        for r in (0..h).rev() {
            heights.extend(codes[r * w..(r + 1) * w].iter().map(|v| v * height_scale));
        }
        let mut map = HeightMap::from_heights(w, h, heights, texel_size, border)?;
        if eight_bit {
            let step = height_scale / 255.0;
            let (flat, one_code) = map.terrace_stats(step);
            // Terraces: plateaus joined by one-code steps. Genuinely flat ground (tiles, a
            // plinth) has plateaus without the steps and is left alone.
            if flat > TERRACE_FRACTION && one_code > TERRACE_FRACTION {
                map.dequantize(step);
                warnings.push(format!(
                    "8-bit heights: {:.1}% of the grid cells were exactly flat and {:.1}% one code \
                     high (quantisation terraces); dequantised by smoothing within ±½ code \
                     ({:.1}% flat now)",
                    100.0 * flat,
                    100.0 * one_code,
                    100.0 * map.flat_cell_fraction()
                ));
            }
        }
        map.warnings = warnings;
        Ok(map)
    }

    /// Fraction of grid cells whose four corner heights are exactly equal (a flat facet pair).
    /// 8-bit height maps show many more than the surface has: the terraces of quantisation.
    #[must_use]
    pub fn flat_cell_fraction(&self) -> f64 {
        let (cx, cy) = (self.cells_x(), self.cells_y());
        let mut flat = 0usize;
        for i in 0..cy as isize {
            for j in 0..cx as isize {
                let h = self.at(i, j);
                if self.at(i, j + 1) == h && self.at(i + 1, j) == h && self.at(i + 1, j + 1) == h {
                    flat += 1;
                }
            }
        }
        flat as f64 / (cx * cy).max(1) as f64
    }

    /// The fractions of grid cells whose four corners are exactly equal and whose corners span
    /// exactly one quantisation `step` (within 1%): together, the signature of terraces.
    #[must_use]
    pub fn terrace_stats(&self, step: f64) -> (f64, f64) {
        let (cx, cy) = (self.cells_x(), self.cells_y());
        let (mut flat, mut one) = (0usize, 0usize);
        for i in 0..cy as isize {
            for j in 0..cx as isize {
                let c = [
                    self.at(i, j),
                    self.at(i, j + 1),
                    self.at(i + 1, j),
                    self.at(i + 1, j + 1),
                ];
                let lo = c.iter().cloned().fold(f64::INFINITY, f64::min);
                let hi = c.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                if hi == lo {
                    flat += 1;
                } else if ((hi - lo) - step).abs() < 0.01 * step {
                    one += 1;
                }
            }
        }
        let n = (cx * cy).max(1) as f64;
        (flat as f64 / n, one as f64 / n)
    }

    /// Remove quantisation terraces from heights known to lie within `±step/2` of their stored
    /// values (an 8-bit image: `step = H/255`): alternate a 3×3 binomial smoothing with a
    /// projection back into each sample's quantisation interval ([`DEQUANTIZE_ITERATIONS`]
    /// rounds). The result is the smooth surface consistent with the codes: terraces become
    /// slopes, real edges (more than a step high) stay, and no height moves by more than half a
    /// step.
    pub fn dequantize(&mut self, step: f64) {
        let (w, h) = (self.width, self.height);
        let lo: Vec<f64> = self.heights.iter().map(|v| v - 0.5 * step).collect();
        let hi: Vec<f64> = self.heights.iter().map(|v| v + 0.5 * step).collect();
        let mut cur = self.heights.clone();
        let mut tmp = vec![0.0; cur.len()];
        let (wi, hi_) = (w as isize, h as isize);
        let border = self.border;
        let idx = move |r: isize, c: isize| -> usize {
            let (r, c) = match border {
                Border::Wrap => (r.rem_euclid(hi_), c.rem_euclid(wi)),
                Border::Clamp => (r.clamp(0, hi_ - 1), c.clamp(0, wi - 1)),
            };
            r as usize * w + c as usize
        };
        for _ in 0..DEQUANTIZE_ITERATIONS {
            use rayon::prelude::*;
            let src = &cur;
            tmp.par_chunks_mut(w).enumerate().for_each(|(i, row)| {
                let i = i as isize;
                for (j, out) in row.iter_mut().enumerate() {
                    let j = j as isize;
                    let mut acc = 0.0;
                    for (di, a) in [(-1isize, 1.0), (0, 2.0), (1, 1.0)] {
                        for (dj, b) in [(-1isize, 1.0), (0, 2.0), (1, 1.0)] {
                            acc += a * b * src[idx(i + di, j + dj)];
                        }
                    }
                    let k = i as usize * w + j as usize;
                    *out = (acc / 16.0).clamp(lo[k], hi[k]);
                }
            });
            std::mem::swap(&mut cur, &mut tmp);
        }
        self.heights = cur;
    }

    /// What loading noticed about the input and did about it (a colour image converted to
    /// luminance, an image that looks like a normal map, 8-bit terraces dequantised), one line
    /// each, for the user to read. Empty for maps built in memory.
    #[must_use]
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The map as a 16-bit grey PNG in image orientation (the last row of the map, largest y, is
    /// the image's top row), heights mapped linearly from `[min, max]` onto `[0, 65535]`.
    /// Returns the bytes and the height scale `max − min` to load it back with
    /// ([`HeightMap::load`]; heights come back shifted by `−min`).
    ///
    /// # Errors
    /// An encoder failure (none is expected for a valid map).
    pub fn encode_png16(&self) -> Result<(Vec<u8>, f64)> {
        use image::ImageEncoder;
        let (lo, hi) = self.range();
        let scale = (hi - lo).max(1e-12);
        let mut raw = Vec::with_capacity(self.heights.len() * 2);
        for r in (0..self.height).rev() {
            for h in &self.heights[r * self.width..(r + 1) * self.width] {
                let c = (((h - lo) / scale) * 65535.0).round().clamp(0.0, 65535.0) as u16;
                // `write_image` takes 16-bit samples in native byte order.
                raw.extend_from_slice(&c.to_ne_bytes());
            }
        }
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(
                &raw,
                self.width as u32,
                self.height as u32,
                image::ExtendedColorType::L16,
            )
            .map_err(|e| decode_err(Path::new("<memory>"), e))?;
        Ok((out, scale))
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

/// Smallest `n_z` a normal-map texel keeps: texels at or below the horizon are tilted up to
/// this height (≈ 0.57° above the horizon) instead of refusing the map.
pub const MIN_NORMAL_Z: f64 = 0.01;

impl NormalMap {
    /// Load a tangent-space normal map (PNG 8/16-bit, JPEG, TGA, TIFF, EXR).
    ///
    /// Each channel decodes as `2·c/max − 1`. Red is +x (the image's columns, the direction of
    /// increasing `u`); green is the image's **up** for [`NormalConvention::Gl`] (OpenGL / glTF /
    /// Blender: towards the image's row 0) and its **down** for [`NormalConvention::Dx`]. meso's +y
    /// is up in the image (map row 0 is the image's bottom row, see the module docs), so a `gl`
    /// map's green is +y and a `dx` map's −y. Two-channel maps (grey + alpha, or RGB whose blue channel is all zero:
    /// BC5-style RG maps) get `z = √(1 − x² − y²)` rebuilt. Each normal is renormalised; texels at or
    /// below the horizon (`n_z ≤ 0`, common in real maps) are tilted up to [`MIN_NORMAL_Z`] and
    /// counted ([`NormalMap::clamped`]); NaN or zero-length texels are an error naming the file.
    pub fn load(path: &Path, convention: NormalConvention) -> Result<NormalMap> {
        let img = open_image_budgeted(
            path,
            "loading the normal map",
            ImageHeader::normal_map_bytes,
        )?;
        Self::from_image(path, img, convention)
    }

    /// Like [`NormalMap::load`], from the bytes of an image file (`name` chooses the format when
    /// the content does not say, and names the source in errors). The size limits are checked
    /// from the header before decoding; the memory budget is the caller's (see
    /// [`probe_bytes`]).
    pub fn from_bytes(
        name: &Path,
        bytes: &[u8],
        convention: NormalConvention,
    ) -> Result<NormalMap> {
        let img = decode_bytes(name, bytes)?;
        Self::from_image(name, img, convention)
    }

    fn from_image(
        path: &Path,
        img: image::DynamicImage,
        convention: NormalConvention,
    ) -> Result<NormalMap> {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let two_channel = matches!(img.color(), image::ColorType::La8 | image::ColorType::La16);
        let rgb = if two_channel {
            let la = img.to_luma_alpha32f();
            image::Rgb32FImage::from_fn(w as u32, h as u32, |x, y| {
                let p = la.get_pixel(x, y).0;
                image::Rgb([p[0], p[1], 0.0])
            })
        } else {
            img.to_rgb32f()
        };
        let rebuild_z = two_channel || rgb.pixels().all(|p| p.0[2] == 0.0);
        // Green up in the image is meso's +y.
        let gsign = match convention {
            NormalConvention::Gl => 1.0,
            NormalConvention::Dx => -1.0,
        };
        let mut normals = Vec::with_capacity(w * h);
        // Map row 0 (y = 0) is the image's bottom row: meso's +y is up in the image.
        for p in (0..h as u32)
            .rev()
            .flat_map(|r| (0..w as u32).map(move |c| (c, r)))
        {
            let p = rgb.get_pixel(p.0, p.1);
            let x = 2.0 * p.0[0] as f64 - 1.0;
            let y = gsign * (2.0 * p.0[1] as f64 - 1.0);
            let z = if rebuild_z {
                (1.0 - x * x - y * y).max(0.0).sqrt()
            } else {
                2.0 * p.0[2] as f64 - 1.0
            };
            normals.push(DVec3::new(x, y, z));
        }
        NormalMap::from_normals(w, h, normals).map_err(|e| match e {
            MapError::NonFinite { what, row, col } => MapError::Decode {
                path: path.to_path_buf(),
                message: format!("{what} at row {row}, column {col} is not a usable direction"),
            },
            other => other,
        })
    }

    /// A normal map from (not necessarily unit) normals, row-major; validated and renormalised.
    /// Normals at or below the horizon are tilted up to `n_z =` [`MIN_NORMAL_Z`] (keeping their
    /// azimuth) and counted; a NaN, infinite or (near) zero-length normal is an error.
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
        let mut clamped = 0usize;
        for (k, n) in normals.into_iter().enumerate() {
            if !n.is_finite() || n.length() < 1e-6 {
                return Err(MapError::NonFinite {
                    what: "normal (NaN, infinite or zero length)",
                    row: k / width,
                    col: k % width,
                });
            }
            let n = n.normalize();
            if n.z < MIN_NORMAL_Z {
                clamped += 1;
                out.push(clamp_above_horizon(n));
            } else {
                out.push(n);
            }
        }
        Ok(NormalMap {
            width,
            height,
            normals: out,
            clamped,
        })
    }

    /// How many texels pointed at or below the horizon and were tilted up to [`MIN_NORMAL_Z`].
    #[must_use]
    pub fn clamped(&self) -> usize {
        self.clamped
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
