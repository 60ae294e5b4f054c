//! Map format version 3 (`docs/map-format.md`): the pyramid's values quantised and stored as
//! deflate-compressed streams of byte planes (structure of arrays). Read (old files and
//! caches); written no longer: format 4 ([`super::v4`]) writes these streams per band.
//!
//! * Lobe axis: octahedral coordinates, 2 × 20 bits (the best of the four nearest codes;
//!   angular error ≤ 2.9·10⁻⁶ rad).
//! * Lobe weight: u16 share of the texel's total, the codes of a texel adding to exactly
//!   65 535 (largest remainders); read back as `q / Σq` (the texel's weights sum to 1; error
//!   < 1/65 535).
//! * Lobe exponent η: u16 of `log2(1 + η) / log2(1 + ETA_MAX)` (relative error
//!   ≤ 1.06·10⁻⁴·(1 + 1/η)).
//! * Horizon statistics: the weight as f32, the four mean angles as 12 bits over [0, π/2] and
//!   the four standard deviations as 12 bits over [0, π/4] (errors ≤ 1.92·10⁻⁴ and
//!   9.6·10⁻⁵ rad).
//!
//! Each stream is one column after another, each column predicted (or not, whichever
//! compresses smaller) from the same slot of the previous texel of its level, split into byte
//! planes and deflated. Reading bounds every stream's inflated size by the level table (and by
//! deflate's 1032:1 limit) before inflating anything, and the whole pyramid's memory by the
//! budget.
//!
//! The parts, one concern a file:
//!
//! * `table` — the level table: read back checked against the header, and the memory of the
//!   pyramid it describes;
//! * `codes` — the quantisation codes: lobe axes (octahedral), weights (shares of the
//!   texel), exponents, and horizon angles;
//! * `streams` — the streams' table, the lobe layout and its predictors, byte planes,
//!   deflate, and reading one stream with its header checked;
//! * `write` — what a pyramid must hold to be stored, its columns, the streams written (by
//!   format 4, per band);
//! * `read` — the levels read back (or checked without building them);
//! * `shading` — the optional shading-error trailer (read).

mod codes;
pub(crate) use codes::{
    angle_decode, angle_encode, eta_decode, eta_encode, oct_decode, oct_encode, MEAN_SPAN, SD_SPAN,
};
mod read;
mod shading;
mod streams;
mod table;
mod write;

pub use shading::SHADING_TAG;
pub use streams::MAX_DEFLATE_RATIO;

pub(in crate::format) use read::{
    build_level, check_levels, decode_columns, read_counts, read_levels,
};
pub(in crate::format) use shading::read_shading;
pub(in crate::format) use streams::{read_stream, stream_count, stream_header, Layout, STREAMS};
pub(in crate::format) use table::{pyramid_bytes, TableEntry};
pub(in crate::format) use write::{unstorable, unstorable_level, write_streams};

/// The format version of this module.
pub const VERSION_3: u32 = 3;
