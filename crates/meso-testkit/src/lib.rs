//! # meso-testkit
//!
//! Reusable statistical and numerical checks for meso's samplers and BRDFs, in the manner of
//! Mitsuba 3's and pbrt-v4's test suites, with no statistics dependency:
//!
//! * [`ChiSquareTest`] — chi-square goodness of fit of a direction sampler against the pdf it
//!   claims (θφ histogram over the whole sphere, cell-integrated pdf, pooling, Šidák correction).
//! * [`check_normalization`] — `∫ pdf dω` by the same cell-wise quadrature.
//! * [`gamma`] — `ln Γ`, the regularised incomplete gamma functions, chi-square p-values.
//! * [`white_furnace`], [`white_furnace_sweep`] — directional albedo `∫ f cos θ_o dω_o`;
//!   [`reciprocity_error`] — Helmholtz symmetry `f(i, o) = f(o, i)`.
//! * [`reference`](mod@reference) — samplers with known densities (uniform sphere / hemisphere, cosine).
//! * [`rng`] — the seeded generator handed to samplers.
//! * [`lobes`] — fine reference quadratures over sums of Phong peaks.
//! * [`alloc`] — a counting global allocator for memory tests.
//! * [`png`] — PNG headers of any size built byte by byte, for image readers' size checks.
//!
//! ```
//! use meso_testkit::{reference, ChiSquareTest};
//! use rand::RngExt;
//!
//! let test = ChiSquareTest { samples: 100_000, n_theta: 20, n_phi: 40, ..Default::default() };
//! let report = test
//!     .run(
//!         |rng| Some(reference::cosine_hemisphere([rng.random(), rng.random()])),
//!         reference::cosine_hemisphere_pdf,
//!     )
//!     .expect("a cosine sampler matches its pdf");
//! assert!(report.p_value > 0.01 && (report.pdf_integral - 1.0).abs() < 1e-9);
//! ```
#![warn(missing_docs)]

pub mod alloc;
pub mod chi2;
pub mod furnace;
pub mod gamma;
pub mod lobes;
pub mod png;
pub mod reference;

pub use chi2::{check_normalization, CellResidual, ChiSquareReport, ChiSquareTest};
pub use furnace::{random_hemisphere_pairs, reciprocity_error, white_furnace, white_furnace_sweep};

/// The random-number generator handed to samplers under test (PCG 128/64 MCG: fast, small state,
/// reproducible from a seed).
pub type Rng = rand_pcg::Pcg64Mcg;

/// A [`Rng`] seeded from `seed`.
#[must_use]
pub fn rng(seed: u64) -> Rng {
    use rand::SeedableRng;
    Rng::seed_from_u64(seed)
}

/// Two uniform numbers in `[0, 1)`, the usual sampler input.
pub fn uniform2(rng: &mut Rng) -> [f64; 2] {
    use rand::RngExt;
    [rng.random(), rng.random()]
}
