//! The rendered image: linear RGB radiance (f32), written as OpenEXR (linear) or as an 8-bit
//! sRGB PNG after exposure and clamping. Every file goes through
//! `meso_core::io::write_atomic_with`, so a failed write leaves no partial file.

use crate::error::ImageError;
use image::ImageEncoder;
use std::path::Path;

/// A `width × height` image of linear RGB radiance, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    width: u32,
    height: u32,
    pixels: Vec<[f32; 3]>,
}

/// The sRGB transfer function (IEC 61966-2-1): linear `[0,1]` → encoded `[0,1]`.
#[inline]
#[must_use]
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse sRGB transfer function: encoded `[0,1]` → linear `[0,1]`.
#[inline]
#[must_use]
pub fn srgb_to_linear(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// Write the bytes of an image encoded in memory to `path` (atomically); an encoding error names
/// `path` as its file.
fn write_encoded(path: &Path, encoded: Result<Vec<u8>, ImageError>) -> Result<(), ImageError> {
    let bytes = encoded.map_err(|e| match e {
        ImageError::Encode { message, .. } => ImageError::Encode {
            file: path.to_path_buf(),
            message,
        },
        e => e,
    })?;
    meso_core::io::write_atomic_with(path, |w| w.write_all(&bytes)).map_err(|source| {
        ImageError::Write {
            file: path.to_path_buf(),
            source,
        }
    })
}

impl Image {
    /// A black image.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
        }
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
    /// All pixels, row-major.
    #[must_use]
    pub fn pixels(&self) -> &[[f32; 3]] {
        &self.pixels
    }
    /// Mutable pixels, row-major.
    pub fn pixels_mut(&mut self) -> &mut [[f32; 3]] {
        &mut self.pixels
    }

    /// Radiance of pixel `(x, y)` (`y = 0` at the top). Panics if out of range.
    #[inline]
    #[must_use]
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Set pixel `(x, y)`. Panics if out of range.
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, v: [f32; 3]) {
        self.pixels[y as usize * self.width as usize + x as usize] = v;
    }

    /// 8-bit sRGB RGB bytes: each channel is multiplied by `2^exposure_stops`, clamped to
    /// `[0, 1]` and encoded with the sRGB transfer function (rounded to nearest).
    #[must_use]
    pub fn to_srgb8(&self, exposure_stops: f32) -> Vec<u8> {
        let k = exposure_stops.exp2();
        self.pixels
            .iter()
            .flat_map(|p| p.map(|c| (linear_to_srgb(c * k) * 255.0 + 0.5) as u8))
            .collect()
    }

    /// Encode as a PNG in memory (see [`Image::to_srgb8`]); for the editor's HTTP responses.
    pub fn encode_png(&self, exposure_stops: f32) -> Result<Vec<u8>, ImageError> {
        let mut out = Vec::new();
        self.encode_png_into(&mut out, exposure_stops)
            .map_err(|message| ImageError::Encode {
                file: "<memory>".into(),
                message,
            })?;
        Ok(out)
    }

    fn encode_png_into(
        &self,
        w: &mut dyn std::io::Write,
        exposure_stops: f32,
    ) -> Result<(), String> {
        image::codecs::png::PngEncoder::new(w)
            .write_image(
                &self.to_srgb8(exposure_stops),
                self.width,
                self.height,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|e| e.to_string())
    }

    /// Write a tone-mapped sRGB PNG (see [`Image::to_srgb8`]).
    pub fn write_png(&self, path: &Path, exposure_stops: f32) -> Result<(), ImageError> {
        write_encoded(path, self.encode_png(exposure_stops))
    }

    /// Write linear radiance as a 32-bit float RGB OpenEXR file.
    pub fn write_exr(&self, path: &Path) -> Result<(), ImageError> {
        write_encoded(path, self.encode_exr())
    }

    /// Encode linear radiance as a 32-bit float RGB OpenEXR file in memory.
    pub fn encode_exr(&self) -> Result<Vec<u8>, ImageError> {
        let raw: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|p| p.iter().flat_map(|c| c.to_ne_bytes()))
            .collect();
        let mut cursor = std::io::Cursor::new(Vec::new());
        image::codecs::openexr::OpenExrEncoder::new(&mut cursor)
            .write_image(
                &raw,
                self.width,
                self.height,
                image::ExtendedColorType::Rgb32F,
            )
            .map_err(|e| ImageError::Encode {
                file: "<memory>".into(),
                message: e.to_string(),
            })?;
        Ok(cursor.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_and_known_values() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        // 18% grey encodes to about 0.4613.
        assert!((linear_to_srgb(0.18) - 0.4613).abs() < 1e-3);
        for k in 0..=100 {
            let x = k as f32 / 100.0;
            assert!((srgb_to_linear(linear_to_srgb(x)) - x).abs() < 1e-5);
        }
    }

    #[test]
    fn exr_round_trip_and_png_output() {
        let dir = std::env::temp_dir().join(format!("meso-render-img-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut im = Image::new(5, 3);
        im.set(1, 2, [0.25, 3.5, 1e-3]);
        im.set(4, 0, [100.0, 0.0, 0.5]);
        let p = dir.join("x.exr");
        im.write_exr(&p).unwrap();
        let back = image::open(&p).unwrap().into_rgb32f();
        assert_eq!((back.width(), back.height()), (5, 3));
        assert_eq!(back.get_pixel(1, 2).0, [0.25, 3.5, 1e-3]);
        assert_eq!(back.get_pixel(4, 0).0, [100.0, 0.0, 0.5]);
        let q = dir.join("x.png");
        im.write_png(&q, 0.0).unwrap();
        let png = image::open(&q).unwrap().into_rgb8();
        assert_eq!(png.get_pixel(4, 0).0, [255, 0, 188]);
        // A directory that does not exist: error naming the file, nothing written.
        let bad = dir.join("no/such/dir/y.png");
        let e = im.write_png(&bad, 0.0).unwrap_err();
        assert!(e.to_string().contains("y.png"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
