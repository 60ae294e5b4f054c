//! # meso-maps
//!
//! Bump maps to multiple surfaces (Fournier 1992, §3.2, and "Filtering Normal Maps and Creating
//! Multiple Surfaces", UBC TR-92-41): height maps → meso-normals → a pyramid of per-texel NDFs
//! fitted as sums of Phong peaks, with filtered horizon angles for masking and self-shadowing;
//! a map file; a virtual gonioreflectometer that ray-traces the height field to check all of it;
//! baselines (mip normal, Toksvig, LEAN, vMF). Every NDF here is handed to the core as a
//! `meso_core::ndf::Ndf` (fitted lobes `Ndf::PhongPeaks`, raw facets `Ndf::Deltas`), and its
//! effective BRDF is `meso_core::convolution::effective_brdf_with`, with the masking of this
//! crate's [`HorizonVisibility`] / [`FacetVisibility`] or the core's Smith: one convolution
//! engine for `meso brdf`, the renderer and the gonioreflectometer's comparisons.
//!
//! Conventions are those of `meso_core::frame`: the macro surface has its normal on +z, x along
//! the map's columns, y along its rows; directions are unit vectors pointing away from the
//! surface; radians in code.
//!
//! ```
//! use meso_maps::{extract, fixtures, ExtractParams, Source};
//! let map = fixtures::v_grooves(16, 8, 0.1, 0.05).unwrap();
//! let pyr = extract(Source::Heights(&map), &ExtractParams::default(), &mut |_| {}).unwrap();
//! assert_eq!(pyr.top().texels(), 1);
//! assert_eq!(pyr.top().lobes.len(), 2); // the two walls of the grooves
//! ```
#![warn(missing_docs)]

pub mod baseline;
pub mod compact;
pub mod disk_cache;
pub mod error;
pub mod facet_cache;
pub mod facet_ndf;
pub mod facets;
pub mod fit;
pub mod fixtures;
pub mod format;
pub mod gonio;
pub mod heightmap;
pub mod horizon;
pub mod input;
pub mod limits;
pub mod pyramid;
pub mod pyramid_cache;
pub mod radiosity;
pub mod read;
pub mod resolver;
pub mod sphgrid;
pub mod visibility;

pub use baseline::{baseline_lobes, fit_baseline, Baseline, Lean};
pub use compact::{
    Horizon32, HorizonCode, HorizonIter, Horizons, Lobe32, LobeCode, LobeIter, Lobes,
    COMPACT_TEXELS,
};
pub use error::{MapError, Result};
pub use facet_ndf::{
    facets_bytes, facets_with_visibility, facets_with_visibility_progress, FacetVisibility,
};
pub use facets::{FacetNormals, NormalMode};
pub use fit::FitParams;
pub use format::{LazyLevel, LazyLobes};
pub use gonio::{Gonio, GonioParams};
pub use heightmap::{probe, Border, HeightMap, ImageHeader, NormalConvention, NormalMap};
pub use horizon::HorizonVisibility;
pub use horizon::{
    diagonal_angles, frechet_dependence, with_frechet_dependence, CellHorizon, HorizonCdf,
    HorizonCdfSum, HorizonDirection, HorizonJoint, HorizonJointSum, HorizonMap, HorizonPair,
    HorizonStats, HorizonToward, HorizonTowardSum, TowardReading, ANGLE_STEP, CDF_ELEVATIONS_DEG,
    CDF_NODES, DIAGONAL_AZIMUTHS_DEG, HORIZON_AZIMUTHS_DEG, HORIZON_DIRECTIONS,
    JOINT_ELEVATIONS_DEG, JOINT_NODES, JOINT_PAIRS, TOWARD_TILT,
};
pub use input::{Input, InputKind};
pub use pyramid::{
    extract, extract_bytes, extract_stream_bytes, extract_to_file, extract_to_writer, extract_work,
    lobe_stats, lobe_stats_by_cell, lobe_stats_by_cell_reporting, merged_levels,
    peak_projected_area, rect_lobe_stats_by_cell, relief_shares, texel_lobe_stats, ExtractParams,
    Level, LevelStats, LobeStat, LobeStats, Method, Progress, ProgressTask, Pyramid, PyramidInfo,
    Source, StreamedLevel, FACE_SHARE, JOINT_CELLS_SIDE, JOINT_FROM_LEVEL, WALLS_MAX_LOBES,
    WALL_SHARE,
};
pub use radiosity::FacetRadiosity;
pub use resolver::{ExtractProgress, MapsResolver};
pub use visibility::BinnedVisibility;
