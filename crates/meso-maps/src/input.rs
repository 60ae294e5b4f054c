//! An input image for extraction, loaded as `meso extract` loads it: the memory budget checked from
//! the image header before anything is decoded, then the height map or normal map read, with the
//! warnings a user should see. The one loader of the `meso` CLI and the Python package, so both
//! write the same map file for the same input.

use crate::pyramid::{extract_bytes, extract_stream_bytes, ExtractParams, Source};
use crate::{Border, HeightMap, NormalConvention, NormalMap, NormalMode, Result};
use std::path::Path;

/// What an input image holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InputKind {
    /// Grey heights: `height_scale` (length units) spans the full code range; samples are
    /// `texel_size` apart (same unit).
    Heights {
        /// Distance between samples, length units (> 0).
        texel_size: f64,
        /// Height of the full code range, length units (> 0).
        height_scale: f64,
        /// Periodic or clamped border.
        border: Border,
    },
    /// A tangent-space RGB normal map in the given green-channel convention.
    Normals(NormalConvention),
}

/// A loaded input.
#[derive(Debug)]
pub enum Input {
    /// A height map.
    Heights(HeightMap),
    /// A normal map.
    Normals(NormalMap),
}

impl Input {
    /// The extraction source of this input.
    #[must_use]
    pub fn source(&self) -> Source<'_> {
        match self {
            Input::Heights(h) => Source::Heights(h),
            Input::Normals(n) => Source::Normals(n),
        }
    }
}

/// Refuse, from the image's header and before anything is decoded, an extraction whose estimated
/// peak memory (loading, the pyramid, writing the map) is above the memory budget
/// ([`meso_core::budget`]). A file whose header cannot be read passes: its loader reports it.
///
/// # Errors
/// [`crate::MapError::Budget`] naming the file.
pub fn check_budget(path: &Path, kind: InputKind, params: &ExtractParams) -> Result<()> {
    check_budget_with(path, kind, params, extract_bytes)
}

/// [`check_budget`] for the streamed extraction ([`crate::extract_to_file`]), whose estimate
/// counts no pyramid ([`extract_stream_bytes`]).
///
/// # Errors
/// [`crate::MapError::Budget`] naming the file.
pub fn check_budget_streamed(path: &Path, kind: InputKind, params: &ExtractParams) -> Result<()> {
    crate::heightmap::with_texel_limit(crate::heightmap::MAX_STREAM_TEXELS, || {
        check_budget_with(path, kind, params, extract_stream_bytes)
    })
}

fn check_budget_with(
    path: &Path,
    kind: InputKind,
    params: &ExtractParams,
    extract_bytes: fn(usize, usize, usize, usize) -> u64,
) -> Result<()> {
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return Ok(());
    }
    let Ok(h) = crate::probe(path) else {
        return Ok(());
    };
    let (w, hgt) = (h.width as usize, h.height as usize);
    let estimate = match kind {
        InputKind::Normals(_) => h.normal_map_bytes() + extract_bytes(w, hgt, 1, 0),
        InputKind::Heights { border, .. } => {
            let (cols, rows) = if border == Border::Clamp {
                (w.saturating_sub(1), hgt.saturating_sub(1))
            } else {
                (w, hgt)
            };
            let per_cell = match params.normal_mode {
                NormalMode::Triangles => 2,
                NormalMode::CentralDifferences => 1,
            };
            h.height_map_then(extract_bytes(cols, rows, per_cell, w * hgt))
        }
    };
    meso_core::budget::check(path, "extracting the NDF pyramid", estimate)?;
    Ok(())
}

/// Check the budget ([`check_budget`]) and load the input. The warnings (quantised heights, texels
/// at the horizon, …) are returned for the caller to show, each without the file name.
///
/// # Errors
/// Budget, unreadable or invalid images, a map file given as the image, invalid parameters;
/// messages name the file.
pub fn load(path: &Path, kind: InputKind, params: &ExtractParams) -> Result<(Input, Vec<String>)> {
    refuse_map_file(path)?;
    check_budget(path, kind, params)?;
    load_unchecked(path, kind)
}

/// [`load`] for the streamed extraction ([`crate::extract_to_file`]): the budget checked by
/// [`check_budget_streamed`], maps of up to [`crate::heightmap::MAX_STREAM_TEXELS`] samples
/// (8192²) accepted.
///
/// # Errors
/// As [`load`].
pub fn load_streamed(
    path: &Path,
    kind: InputKind,
    params: &ExtractParams,
) -> Result<(Input, Vec<String>)> {
    crate::heightmap::with_texel_limit(crate::heightmap::MAX_STREAM_TEXELS, || {
        refuse_map_file(path)?;
        check_budget_streamed(path, kind, params)?;
        load_unchecked(path, kind)
    })
}

/// Refuse a map file (opening with [`crate::format::MAGIC`]) given as the image to extract, saying
/// what to do instead (the decoder would only say that it is no PNG).
fn refuse_map_file(path: &Path) -> Result<()> {
    if crate::format::is_map_file(path) {
        return Err(crate::MapError::MapFormat {
            path: path.to_path_buf(),
            message: format!(
                "this is a meso map file (written by `meso extract`), not an image: extract from \
                 the image it was extracted from (`meso extract IMAGE …`); `meso map info {}` \
                 shows what the map holds",
                path.display()
            ),
        });
    }
    Ok(())
}

fn load_unchecked(path: &Path, kind: InputKind) -> Result<(Input, Vec<String>)> {
    match kind {
        InputKind::Heights {
            texel_size,
            height_scale,
            border,
        } => Ok(with_warnings(Input::Heights(HeightMap::load(
            path,
            texel_size,
            height_scale,
            border,
        )?))),
        InputKind::Normals(conv) => Ok(with_warnings(Input::Normals(NormalMap::load(path, conv)?))),
    }
}

/// Like [`load`], from the bytes of an image file (an upload): `name` chooses the format when the
/// content does not say and names the source in errors. The size limits are checked from the
/// header before decoding; the memory budget is the caller's (estimate it from
/// [`crate::heightmap::probe_bytes`] as [`check_budget`] does from the file).
///
/// # Errors
/// Unreadable or invalid images, invalid parameters; messages name `name`.
pub fn load_bytes(name: &Path, bytes: &[u8], kind: InputKind) -> Result<(Input, Vec<String>)> {
    Ok(with_warnings(match kind {
        InputKind::Heights {
            texel_size,
            height_scale,
            border,
        } => Input::Heights(HeightMap::from_bytes(
            name,
            bytes,
            texel_size,
            height_scale,
            border,
        )?),
        InputKind::Normals(conv) => Input::Normals(NormalMap::from_bytes(name, bytes, conv)?),
    }))
}

/// The input with the warnings a user should see (quantised heights, texels at the horizon, …).
fn with_warnings(input: Input) -> (Input, Vec<String>) {
    let warnings = match &input {
        Input::Heights(h) => h.warnings().iter().map(ToString::to_string).collect(),
        Input::Normals(n) => n.warnings(),
    };
    (input, warnings)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NormalConvention;

    /// An upload (`load_bytes`) loads exactly as the same file does (`load`): the same map and
    /// the same warnings, for a height map and a normal map in both conventions.
    #[test]
    fn bytes_load_as_the_file_does() {
        let dir = std::env::temp_dir().join(format!("meso-input-bytes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let map = crate::fixtures::gaussian(24, 0.1, 0.02, 3, 0.05).unwrap();
        let (png, scale) = map.encode_png16().unwrap();
        let path = dir.join("h.png");
        std::fs::write(&path, &png).unwrap();
        let kind = InputKind::Heights {
            texel_size: 0.05,
            height_scale: scale,
            border: Border::Wrap,
        };
        let (a, wa) = load(&path, kind, &ExtractParams::default()).unwrap();
        let (b, wb) = load_bytes(&path, &png, kind).unwrap();
        match (a, b) {
            (Input::Heights(a), Input::Heights(b)) => assert_eq!(a, b),
            _ => panic!("height maps expected"),
        }
        assert_eq!(wa, wb);
        let mut raw = Vec::new();
        for k in 0..16u32 * 8 {
            raw.extend_from_slice(&[(k * 7 % 256) as u8, (k * 13 % 256) as u8, 200]);
        }
        let mut png = Vec::new();
        {
            use image::ImageEncoder;
            image::codecs::png::PngEncoder::new(&mut png)
                .write_image(&raw, 16, 8, image::ExtendedColorType::Rgb8)
                .unwrap();
        }
        let path = dir.join("n.png");
        std::fs::write(&path, &png).unwrap();
        for conv in [NormalConvention::Gl, NormalConvention::Dx] {
            let kind = InputKind::Normals(conv);
            let (a, wa) = load(&path, kind, &ExtractParams::default()).unwrap();
            let (b, wb) = load_bytes(&path, &png, kind).unwrap();
            match (a, b) {
                (Input::Normals(a), Input::Normals(b)) => assert_eq!(a, b),
                _ => panic!("normal maps expected"),
            }
            assert_eq!(wa, wb);
        }
        let header = crate::heightmap::probe_bytes(&path, &png).unwrap();
        assert_eq!((header.width, header.height, header.color), (16, 8, true));
        assert_eq!(header, crate::probe(&path).unwrap());
        assert!(load_bytes(&path, &png[..png.len() / 2], kind_of_normals()).is_err());
        assert!(crate::heightmap::probe_bytes(&path, b"").is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn kind_of_normals() -> InputKind {
        InputKind::Normals(NormalConvention::Gl)
    }
}
