//! Tangent-space normal maps: [`NormalMap`] (one unit normal per texel, local frame with the
//! normal +z), its loading from images under either green-channel [`NormalConvention`], and the
//! tilting of texels at or below the horizon up to [`MIN_NORMAL_Z`].
//!
//! # Conventions
//! * meso's +y is **up** in the image (map row 0 is the image's bottom row, see the parent
//!   module): a [`NormalConvention::Gl`] map's green is +y, a [`NormalConvention::Dx`] map's −y.
//! * Channels decode as `2·c/max − 1`; two-channel maps get `z` rebuilt.

use super::decode::{check_dims, decode_bytes, open_image_budgeted, ImageHeader};
use crate::error::{MapError, Result};
use glam::DVec3;
use std::path::Path;

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

/// Smallest `n_z` a normal-map texel keeps: texels at or below the horizon are tilted up to
/// this height (≈ 0.57° above the horizon) instead of refusing the map.
pub const MIN_NORMAL_Z: f64 = 0.01;

/// The shortest decoded vector an integer (8- or 16-bit) normal-map texel may hold: shorter,
/// it is no direction and the map is refused, naming the texel. The "no data" grey
/// (128, 128, 128) decodes to length 0.007; 0.25 is every channel within ≈ 18 codes of 128. Unit
/// normals decode to within a few codes of length 1; texels between 0.25 and 1 (odd but
/// directions) are renormalised.
pub const MIN_CODED_LENGTH: f64 = 0.25;

/// Why a single-channel grey image is refused as a normal map ([`NormalMap::load`]): the
/// message of its [`MapError::Decode`].
pub const GREY_NOT_NORMALS: &str = "a single-channel grey image cannot be a normal map (a \
     normal map holds red, green and blue, or red and green, channels); it looks like a height \
     map: read it as heights instead";

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
    /// counted ([`NormalMap::clamped`]); NaN or zero-length texels are an error naming the file,
    /// and so is a single-channel grey image ([`GREY_NOT_NORMALS`]: a height map most likely).
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
    /// [`probe_bytes`](super::probe_bytes)).
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
        // No normal map is one grey channel (a normal needs two components at least); such an
        // image read as one would decode every texel to the same tilted vector (grey g gives
        // (g, g, g) → a 55° tilt for white), a height map most likely.
        if matches!(img.color(), image::ColorType::L8 | image::ColorType::L16) {
            return Err(MapError::Decode {
                path: path.to_path_buf(),
                message: GREY_NOT_NORMALS.to_string(),
            });
        }
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
        // Integer codes cannot hold a zero vector: the nearest an 8-bit texel comes is the grey
        // (128, 128, 128) that tools write for "no data", length 0.007. A decoded vector shorter
        // than MIN_CODED_LENGTH is not a normal (a unit normal's codes are within a few codes of
        // length 1).
        let integer = !matches!(
            img.color(),
            image::ColorType::Rgb32F | image::ColorType::Rgba32F
        );
        // Green up in the image is meso's +y.
        let gsign = match convention {
            NormalConvention::Gl => 1.0,
            NormalConvention::Dx => -1.0,
        };
        let mut normals = Vec::with_capacity(w * h);
        // The texels that hold no direction: how many, and the first in reading order (image
        // row, column, colour, decoded length).
        let mut bad = 0usize;
        let mut first_bad: Option<(usize, usize, [f32; 3], f64)> = None;
        // Map row 0 (y = 0) is the image's bottom row: meso's +y is up in the image.
        for (r, c) in (0..h).rev().flat_map(|r| (0..w).map(move |c| (r, c))) {
            let p = rgb.get_pixel(c as u32, r as u32);
            let x = 2.0 * p.0[0] as f64 - 1.0;
            let y = gsign * (2.0 * p.0[1] as f64 - 1.0);
            let z = if rebuild_z {
                (1.0 - x * x - y * y).max(0.0).sqrt()
            } else {
                2.0 * p.0[2] as f64 - 1.0
            };
            let n = DVec3::new(x, y, z);
            if integer && !rebuild_z && n.length() < MIN_CODED_LENGTH {
                bad += 1;
                // Rows go bottom to top here: a later row is earlier in reading order.
                if first_bad.is_none_or(|f| r < f.0) {
                    first_bad = Some((r, c, p.0, n.length()));
                }
            }
            normals.push(n);
        }
        if let Some((r, c, col, len)) = first_bad {
            return Err(MapError::Decode {
                path: path.to_path_buf(),
                message: format!(
                    "the texel at image row {r} (from the top), column {c} is not a normal \
                     (the first of {bad} such texels of {}): its colour ({:.3}, {:.3}, {:.3}) of \
                     full scale decodes to a vector of length {len:.3} (a \"no data\" grey?); \
                     every texel must hold a direction",
                    w * h,
                    col[0],
                    col[1],
                    col[2],
                ),
            });
        }
        NormalMap::from_normals(w, h, normals).map_err(|e| match e {
            MapError::NonFinite { what, row, col } => MapError::Decode {
                path: path.to_path_buf(),
                message: format!(
                    "{what} at image row {} (from the top), column {col} is not a usable direction",
                    h - 1 - row
                ),
            },
            other => other,
        })
    }

    /// A normal map from (not necessarily unit) normals, row-major (row 0 at y = 0, the image's
    /// bottom); validated and renormalised.
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

    /// What a user should be told about the load: how many texels were tilted up to the
    /// horizon, or nothing (the one wording of `meso extract`, `meso export`, `meso render`, the
    /// editor and Python).
    #[must_use]
    pub fn warnings(&self) -> Vec<String> {
        (self.clamped > 0)
            .then(|| {
                format!(
                    "{} of {} texels point at or below the horizon (n_z ≤ {MIN_NORMAL_Z}); tilted \
                     up to it",
                    self.clamped,
                    self.width * self.height
                )
            })
            .into_iter()
            .collect()
    }

    grid_size_accessors!("texels");
    /// Unit normals, row-major.
    #[must_use]
    pub fn normals(&self) -> &[DVec3] {
        &self.normals
    }
}
