//! Engine-ready maps out of meso: a GGX roughness mip chain fitted so that each level keeps the
//! appearance of the level-0 texels it covers, the matching normal mip chain, both as KTX2
//! files with full mip chains (and one PNG per level), and a glTF 2.0 preview asset.
//!
//! See `docs/export.md` for the workflow and the measured per-level errors.
//!
//! # Conventions
//! * Tangent frame: x right, **y up in the image**, z out of the surface (OpenGL / glTF).
//! * Maps in memory are in meso's map order (row 0 = the image's bottom row); files are in image
//!   order (top row first) — image row `r` is map row `rows − 1 − r`.
//! * α is the GGX width; glTF's roughness is `r = √α` ([`ggx::alpha_to_roughness`]).
//!
//! The pipeline: [`export::Inputs`] → [`export::build`] (all files in memory) →
//! [`export::write`] (atomic, all or nothing).

mod batch;
pub mod export;
pub mod ggx;
pub mod gltf;
pub mod ktx2;
pub mod lobes;
pub mod mips;
pub mod prepare;
pub mod texture;

pub use export::{build, write, Export, Inputs, Roughness};
pub use mips::{AnisoLevel, AnisoStats, BaseMaps, LevelStats, MipLevel};

use std::path::PathBuf;

/// What can go wrong exporting.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// Inconsistent or unusable input (the message says what and where).
    #[error("{0}")]
    Invalid(String),
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A map could not be loaded.
    #[error(transparent)]
    Map(#[from] meso_maps::MapError),
    /// Work refused because its estimated memory is above the budget (`meso_core::budget`);
    /// the message names the file, the estimate and the budget.
    #[error(transparent)]
    Budget(#[from] meso_core::budget::BudgetError),
}
