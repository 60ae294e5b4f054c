//! The error type of meso-maps: every bad input is reported as a [`MapError`] naming the problem.

use std::path::PathBuf;

/// Everything that can go wrong while reading height maps, extracting pyramids, reading map files
/// or evaluating BRDFs. Every variant names the offending file or parameter.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file could not be written (nothing is left behind).
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The image is corrupt, truncated, or in a format the image decoder does not read.
    #[error("cannot decode image {path}: {message}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// The file holds no bytes at all.
    #[error("{path} is an empty file (0 bytes), not an image")]
    EmptyFile {
        /// The file (or `<memory>`).
        path: PathBuf,
    },
    /// The image has no pixels.
    #[error("image {path} is empty ({width}×{height} pixels)")]
    Empty {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// Width in pixels.
        width: u64,
        /// Height in pixels.
        height: u64,
    },
    /// The image is larger than [`crate::heightmap::MAX_DIMENSION`] or
    /// [`crate::heightmap::MAX_TEXELS`]; refused from the header, before decoding.
    #[error("image {path} is too large: {width}×{height} (limit {max_dim} per side and {max_texels} texels)")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Width in pixels.
        width: u64,
        /// Height in pixels.
        height: u64,
        /// Per-side limit.
        max_dim: u64,
        /// Total-texel limit.
        max_texels: u64,
    },
    /// A height (or a normal-map component) is NaN or infinite.
    #[error("{what} at row {row}, column {col} is not finite")]
    NonFinite {
        /// What was not finite ("height", "normal").
        what: &'static str,
        /// Row index.
        row: usize,
        /// Column index.
        col: usize,
    },
    /// A parameter is out of its valid range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name as in the docs / CLI.
        name: &'static str,
        /// The value given.
        value: String,
        /// What is required.
        reason: &'static str,
    },
    /// A height map's texel size or height scale outside the range whose facets `f64` holds
    /// (`heightmap::load::SCALE_RANGE`, `MAX_SLOPE_SCALE`).
    #[error("{path}: {what}")]
    Scale {
        /// The height map.
        path: PathBuf,
        /// Which scale, its value and what is required.
        what: String,
    },
    /// A map file is malformed.
    #[error("map file {path}: {message}")]
    MapFormat {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A map file has a version this library does not read.
    #[error(
        "map file {path} has format version {found}; this build reads versions 2 to {expected} \
         (re-extract it with `meso extract`)"
    )]
    MapVersion {
        /// The file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// The newest version read (versions 2 and 3 are read too; 3 and 4 are written).
        expected: u32,
    },
    /// A pyramid level or texel index is out of range.
    #[error("no {what} {index} (there are {count})")]
    OutOfRange {
        /// "level", "row", "column".
        what: &'static str,
        /// The index requested.
        index: usize,
        /// How many exist.
        count: usize,
    },
    /// The operation needs heights but the source is a normal map.
    #[error("{0} needs a height map; a normal map has no heights")]
    NeedsHeights(&'static str),
    /// Refused before allocating: the work would need more memory than the budget
    /// (`meso_core::budget`); the message names the file, the estimate and the budget.
    #[error("{0}")]
    Budget(#[from] meso_core::budget::BudgetError),
    /// A big allocation failed (the memory was not there after all).
    #[error("{what}: {source}")]
    OutOfMemory {
        /// What was being allocated for (the file, or the step).
        what: String,
        /// The failed allocation.
        source: meso_core::budget::AllocError,
    },
}

/// Shorthand for `Result<T, MapError>`.
pub type Result<T> = std::result::Result<T, MapError>;

/// Check that a scale is finite and positive.
pub(crate) fn positive(name: &'static str, v: f64) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(MapError::InvalidParameter {
            name,
            value: format!("{v}"),
            reason: "must be a finite number > 0",
        })
    }
}
