//! The bounds of a fitted NDF pyramid that other crates rely on: how many lobes a texel may
//! hold and the range of a lobe's Phong exponent and axis.
//!
//! Every lobe written by the fitter ([`crate::fit`]), read from a map file ([`crate::format`])
//! or produced by a baseline ([`crate::baseline`]) satisfies them, so a reader (the renderer,
//! the CLI, the Python bindings) can size its buffers and validate its arguments against these
//! constants without depending on the fitter's internals.

/// Largest Phong exponent η on cos(α/2); footprints of identical normals get exactly this.
pub const ETA_MAX: f64 = 1.0e6;
/// Largest number of lobes per texel.
pub const MAX_LOBES: usize = 8;
/// Smallest Phong exponent η of a fitted lobe: a peak `((1 + a·m)/2)^(η/2)` puts
/// `2^−(η/2 + 1)` of its mass beyond 90° from its axis — at most 1/8 with this bound, where a
/// flat lobe (η → 0) would put half of it below the horizon.
pub const ETA_MIN: f64 = 4.0;
/// Smallest `z` of a fitted lobe's axis: lobes whose axis the fit left at or below the horizon
/// (steep normal maps) are tilted up to it, keeping their azimuth.
pub const AXIS_MIN_Z: f64 = 0.05;
