//! A [`HeightMap`] from an image (a file, or its bytes) and back: the codes scaled to heights,
//! colour images converted to luminance (with a warning, and a louder one when the image looks
//! like a normal map), 8-bit terraces dequantised, and the map written as a 16-bit grey PNG.
//!
//! # Conventions
//! * Integer images: `h = code / max_code · H` (`max_code` = 255 or 65535); float images (EXR):
//!   `h = value · H`, with `H` the height scale.
//! * Map row 0 (y = 0) is the image's **bottom** row: loading reverses the image's rows and
//!   [`HeightMap::encode_png16`] writes them back in image order (see the parent module).

use super::decode::{decode_bytes, decode_err, oom, open_image_budgeted, ImageHeader};
use super::terraces::TERRACE_FRACTION;
use super::{Border, HeightMap};
use crate::error::{positive, MapError, Result};
use std::path::Path;

/// A height image of a colour type is taken as colour (and warned about) only when some pixel's
/// channels differ by more than this (of full scale): 2.5 codes of 8 bits, above the chroma
/// noise of a grey image saved as a colour JPEG; a grey map stored as RGB is not colour.
const GREY_SPREAD: f32 = 2.5 / 255.0;

/// An error of loading the image `path` (`h` rows) as a height map, said of the file: memory
/// refused names it, and a texel is named by its image row (from the top), not by the map's row
/// (which counts from the bottom: +y is up in the image).
fn in_image_rows(path: &Path, h: usize, e: MapError) -> MapError {
    match e {
        MapError::OutOfMemory { source, .. } => oom(path, source),
        MapError::NonFinite { what, row, col } => decode_err(
            path,
            format!(
                "{what} at image row {} (from the top), column {col} is not finite",
                h - 1 - row
            ),
        ),
        e => e,
    }
}

impl HeightMap {
    /// Load a grey PNG (8/16-bit), 16-bit TIFF or float EXR height map with texel size `S` and
    /// height scale `H` (both in the same length unit, > 0). See the module docs for the scale.
    pub fn load(
        path: &Path,
        texel_size: f64,
        height_scale: f64,
        border: Border,
    ) -> Result<HeightMap> {
        check_scales(path, texel_size, height_scale)?;
        let img = open_image_budgeted(
            path,
            "loading the height map",
            ImageHeader::height_map_bytes,
        )?;
        let h = img.height() as usize;
        Self::from_image(img, texel_size, height_scale, border)
            .map_err(|e| in_image_rows(path, h, e))
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
        check_scales(name, texel_size, height_scale)?;
        let img = decode_bytes(name, bytes)?;
        let h = img.height() as usize;
        Self::from_image(img, texel_size, height_scale, border)
            .map_err(|e| in_image_rows(name, h, e))
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
        // A colour type with colour in it: some pixel whose channels differ by more than JPEG's
        // chroma noise (a grey map stored as RGB is not warned about).
        // (One conversion, as before this check, and only for colour types.)
        let rgb = img.color().has_color().then(|| img.to_rgb32f());
        let coloured = rgb.as_ref().is_some_and(|rgb| {
            rgb.pixels().any(|p| {
                let (lo, hi) =
                    p.0.iter()
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                            (a.min(v), b.max(v))
                        });
                hi - lo > GREY_SPREAD
            })
        });
        if let (true, Some(rgb)) = (coloured, &rgb) {
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
            } else if matches!(img, D::ImageRgb32F(_) | D::ImageRgba32F(_)) {
                warnings.push(
                    "colour image used as a height map: its first (red) channel is used (prefer \
                     a grey image)"
                        .into(),
                );
            } else {
                warnings.push(
                    "colour image used as a height map: converted to luminance (prefer a grey image)"
                        .into(),
                );
            }
        }
        drop(rgb);
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
        if border == Border::Wrap {
            let (x, y) = map.seam_ratios();
            if x.max(y) > SEAM_RATIO {
                let along = match (x > SEAM_RATIO, y > SEAM_RATIO) {
                    (true, true) => "left and right edges, and its top and bottom edges,",
                    (true, false) => "left and right edges",
                    _ => "top and bottom edges",
                };
                warnings.push(format!(
                    "the map does not tile: the steps across its {along} are {:.1}× its typical \
                     step between neighbours, and a wrapped border (the default) reads that seam \
                     as a cliff in the NDF; for a map that is not one tile of a periodic \
                     surface read only the samples inside it (meso extract --clamp, a material's \
                     border = \"clamp\", Python's border=\"clamp\")",
                    x.max(y)
                ));
            }
        }
        map.warnings = warnings;
        Ok(map)
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
}

/// A wrapped map whose opposite edges step more than this many times its typical step between
/// neighbours ([`HeightMap::seam_ratios`]) is warned about when loaded: a crop of a larger
/// surface, not one tile of a periodic one, whose seam the wrapped border turns into a cliff.
/// A map that tiles reads about 1: three real CC0 1K displacement maps read 0–1.4 whole
/// (ambientCG Facade005, WoodFloor064, Metal032); crops of the wood floor 6.7–7.2 (its boards
/// cut across), of the noisy metal about 1 (its seam a step like any other: nothing to warn of).
pub const SEAM_RATIO: f64 = 3.0;

/// Both scales of a height map file finite and > 0 (texel size first, as the error names it).
/// The range of a texel size or height scale (any length unit): beyond it the facets' cross
/// products underflow or overflow `f64`.
pub const SCALE_RANGE: (f64, f64) = (1e-12, 1e12);
/// The largest ratio `height_scale / texel_size`: the slope of a full-range step between two
/// neighbouring samples (10⁶, a wall within 6·10⁻⁵ ° of vertical; a one-code step of a 16-bit
/// map is then a slope of 15). Larger ratios give no usable normals.
pub const MAX_SLOPE_SCALE: f64 = 1e6;

/// Check the scales of the height map `path` (named in the error): each finite and positive,
/// within [`SCALE_RANGE`], and their ratio at most [`MAX_SLOPE_SCALE`]. The check of
/// `meso extract` and every loader, shared by the Python package's `extract` of an array.
///
/// # Errors
/// [`MapError::InvalidParameter`] or [`MapError::Scale`] naming `path` and the scale.
pub fn check_scales(path: &Path, texel_size: f64, height_scale: f64) -> Result<()> {
    positive("texel_size", texel_size)?;
    positive("height_scale", height_scale)?;
    let within = |v: f64| (SCALE_RANGE.0..=SCALE_RANGE.1).contains(&v);
    for (name, v) in [("texel_size", texel_size), ("height_scale", height_scale)] {
        if !within(v) {
            return Err(MapError::Scale {
                path: path.to_path_buf(),
                what: format!(
                    "{name} = {v:e} must be between 1e-12 and 1e12 (any length unit: choose one \
                     in which the map's scales are moderate)"
                ),
            });
        }
    }
    if height_scale / texel_size > MAX_SLOPE_SCALE {
        return Err(MapError::Scale {
            path: path.to_path_buf(),
            what: format!(
                "height_scale / texel_size = {:e} must be at most 1e6: a full-range step between \
                 neighbouring samples would be a wall steeper than 89.99994°",
                height_scale / texel_size
            ),
        });
    }
    Ok(())
}
