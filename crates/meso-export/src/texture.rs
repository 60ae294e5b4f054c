//! Encoding mip levels as 8-bit texels in image order, and PNG files.
//!
//! # Conventions
//! * Image row `r` (0 = top) is map row `rows − 1 − r` (map row 0 is the image's bottom row).
//! * Normals: OpenGL / glTF tangent space, `c = round(255 · (n · 0.5 + 0.5))` per channel
//!   (green = +y = up in the image), alpha 255.
//! * Roughness, in glTF's metallicRoughness layout: R = 255 (unused by glTF), G = perceptual
//!   roughness `r = √α`, B = metallic, A = 255, each `round(255 · value)`.
//! * Anisotropy, in KHR_materials_anisotropy's layout: R, G = the direction `(cos ψ, sin ψ)` of
//!   the larger width in the tangent frame (x right, y up the image), each `round(255 ·
//!   (c · 0.5 + 0.5))`; B = `round(255 s)` for the strength `s` with `α_t = mix(α_b, 1, s²)`
//!   (of the fitted, unquantised widths, so an isotropic texel has strength exactly 0); A = 255.

use crate::ggx::alpha_to_roughness;
use crate::mips::anisotropy_strength;
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

/// RGBA8 texels in KHR_materials_anisotropy's layout (module conventions) in image order, from
/// map-order widths `alpha_b` (as written to the metallicRoughness G channel), `alpha_t ≥
/// alpha_b` and directions `angles` (radians, counter-clockwise from +x towards +y).
#[must_use]
pub fn anisotropy_rgba8(
    width: usize,
    height: usize,
    alpha_b: &[f64],
    alpha_t: &[f64],
    angles: &[f64],
) -> Vec<u8> {
    let mut out = Vec::with_capacity(width * height * 4);
    for r in (0..height).rev() {
        for k in r * width..(r + 1) * width {
            let s = anisotropy_strength(alpha_t[k], alpha_b[k]);
            let (sin, cos) = angles[k].sin_cos();
            out.extend_from_slice(&[
                to_u8(cos * 0.5 + 0.5),
                to_u8(sin * 0.5 + 0.5),
                to_u8(s),
                255,
            ]);
        }
    }
    out
}

/// What an engine decodes from one texel (KHR_materials_anisotropy, `anisotropyStrength = 1`,
/// `anisotropyRotation = 0`): `(α_t, α_b, ψ)` from the metallicRoughness G code and the
/// anisotropy R, G, B codes; `α_b = (G/255)²`, `α_t = mix(α_b, 1, (B/255)²)`, `ψ = atan2(y, x)`
/// of `(R, G)/255 · 2 − 1` (radians in `(−π, π]`).
#[must_use]
pub fn decode_anisotropy(roughness_code: u8, aniso: [u8; 3]) -> (f64, f64, f64) {
    let r = roughness_code as f64 / 255.0;
    let ab = r * r;
    let s = aniso[2] as f64 / 255.0;
    let at = ab * (1.0 - s * s) + s * s;
    let x = aniso[0] as f64 / 255.0 * 2.0 - 1.0;
    let y = aniso[1] as f64 / 255.0 * 2.0 - 1.0;
    (at, ab, y.atan2(x))
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

    /// Anisotropy texels decode to the widths and direction they were made from, within 8-bit
    /// quantisation; rows flip like the other maps.
    #[test]
    fn anisotropy_layout_round_trip() {
        let (ab, at, ang) = ([0.1, 0.04], [0.5, 0.04], [0.3, 2.5]);
        let px = anisotropy_rgba8(1, 2, &ab, &at, &ang);
        let mr = metallic_roughness_rgba8(1, 2, &ab, 0.0);
        // Image row 0 is map row 1 (isotropic: strength 0).
        assert_eq!(px[2], 0);
        let (dt, db, dpsi) = decode_anisotropy(mr[4 + 1], [px[4], px[5], px[6]]);
        assert!(
            (db - 0.1).abs() < 0.004 && (dt - 0.5).abs() < 0.01,
            "{dt} {db}"
        );
        assert!((dpsi - 0.3).abs() < 0.01, "{dpsi}");
        let (dt, db, dpsi) = decode_anisotropy(mr[1], [px[0], px[1], px[2]]);
        assert!((dt - db).abs() < 1e-12 && (db - 0.04).abs() < 0.002);
        assert!((dpsi - 2.5).abs() < 0.01, "{dpsi}");
    }

    #[test]
    fn roughness_layout() {
        let px = metallic_roughness_rgba8(2, 1, &[0.25, 1.0], 1.0);
        assert_eq!(px, vec![255, 128, 255, 255, 255, 255, 255, 255]);
    }
}
