//! Special functions shared by meso-core and its test harness: the one `ln Γ` of the workspace.
//!
//! [`ln_gamma`] is libm's `lgamma` (the Student-t slope constants in [`crate::ndf::student_t`]
//! and the chi-square p-values of meso-testkit both take it from here), so no crate carries a
//! Lanczos series of its own.

/// `ln |Γ(x)|`: for `x > 0` the log-gamma function, for `x < 0` the log of the modulus (the
/// reflection formula), libm's `lgamma` (relative error of a few ulp).
///
/// Returns `+∞` at the poles `x = 0, −1, −2, …`.
///
/// ```
/// use meso_core::special::ln_gamma;
/// assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-14);
/// assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-14);
/// assert!(ln_gamma(0.0).is_infinite());
/// ```
#[inline]
#[must_use]
pub fn ln_gamma(x: f64) -> f64 {
    libm::lgamma(x)
}
