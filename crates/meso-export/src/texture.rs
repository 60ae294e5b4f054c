//! Encoding mip levels as 8-bit texels in image order, and PNG files.
//!
//! # Conventions
//! * Image row `r` (0 = top) is map row `rows − 1 − r` (map row 0 is the image's bottom row).
//! * Normals: OpenGL / glTF tangent space, `c = round(255 · (n · 0.5 + 0.5))` per channel
//!   (green = +y = up in the image), alpha 255.
//! * Roughness, in glTF's metallicRoughness layout: R = 255 (unused by glTF), G = perceptual
//!   roughness `r = √α`, B = metallic, A = 255, each `round(255 · value)`.

use crate::ggx::alpha_to_roughness;
use crate::ExportError;
use glam::DVec3;

/// Quantise `v ∈ [0, 1]` to 8 bits (`round(255 v)`, clamped).
#[must_use]
pub fn to_u8(v: f64) -> u8 {
    (v * 255.0).round().clamp(0.0, 255.0) as u8
}

/// RGBA8 texels of unit normals in image order (top row first).
#[must_use]
pub fn normals_rgba8(width: usize, height: usize, normals: &[DVec3]) -> Vec<u8> {
    let mut out = Vec::with_capacity(width * height * 4);
    for r in (0..height).rev() {
        for n in &normals[r * width..(r + 1) * width] {
            out.extend_from_slice(&[
                to_u8(n.x * 0.5 + 0.5),
                to_u8(n.y * 0.5 + 0.5),
                to_u8(n.z * 0.5 + 0.5),
                255,
            ]);
        }
    }
    out
}

/// RGBA8 texels in glTF's metallicRoughness layout (R 255, G `√α`, B metallic, A 255) in image
/// order, from GGX widths α in map order and one metallic value in `[0, 1]`.
#[must_use]
pub fn metallic_roughness_rgba8(
    width: usize,
    height: usize,
    alphas: &[f64],
    metallic: f64,
) -> Vec<u8> {
    let m = to_u8(metallic);
    let mut out = Vec::with_capacity(width * height * 4);
    for r in (0..height).rev() {
        for &a in &alphas[r * width..(r + 1) * width] {
            out.extend_from_slice(&[255, to_u8(alpha_to_roughness(a)), m, 255]);
        }
    }
    out
}

/// Encode RGBA8 (or, with `channels = 1`, grey) texels in image order as a PNG.
///
/// # Errors
/// [`ExportError::Invalid`] for a size mismatch or an encoder failure.
pub fn encode_png(
    width: usize,
    height: usize,
    channels: usize,
    data: &[u8],
) -> Result<Vec<u8>, ExportError> {
    use image::ImageEncoder;
    let color = match channels {
        1 => image::ExtendedColorType::L8,
        3 => image::ExtendedColorType::Rgb8,
        4 => image::ExtendedColorType::Rgba8,
        c => {
            return Err(ExportError::Invalid(format!(
                "{c} channels: cannot encode a PNG"
            )))
        }
    };
    if data.len() != width * height * channels {
        return Err(ExportError::Invalid(format!(
            "{} bytes for a {width} × {height} × {channels} PNG",
            data.len()
        )));
    }
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(data, width as u32, height as u32, color)
        .map_err(|e| ExportError::Invalid(format!("PNG encoder: {e}")))?;
    Ok(out)
}

/// Drop the alpha channel of RGBA8 texels (for inspection PNGs of always-opaque data).
#[must_use]
pub fn rgba_to_rgb(data: &[u8]) -> Vec<u8> {
    data.chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Map row 0 lands in the image's last row; a +y normal has green 255.
    #[test]
    fn rows_flip_and_green_is_up() {
        let n = [DVec3::Y, DVec3::Z]; // map row 0: +y; map row 1: +z
        let px = normals_rgba8(1, 2, &n);
        assert_eq!(&px[..4], &[128, 128, 255, 255]); // image top row = map row 1
        assert_eq!(&px[4..], &[128, 255, 128, 255]);
    }

    #[test]
    fn roughness_layout() {
        let px = metallic_roughness_rgba8(2, 1, &[0.25, 1.0], 1.0);
        assert_eq!(px, vec![255, 128, 255, 255, 255, 255, 255, 255]);
    }
}
