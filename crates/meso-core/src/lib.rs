//! # meso-core
//!
//! The numeric core of meso: normal distribution functions (NDFs) as first-class objects,
//! facet transfer functions, and the convolution of the two into an effective BRDF
//! (Fournier 1992, "Normal Distribution Functions and Multiple Surfaces", Eq. 1–13).
//!
//! Conventions (directions, the local frame with the normal on +z, spherical coordinates) are
//! written once in [`frame`]; every other module uses them.
#![warn(missing_docs)]

pub mod frame;
pub mod grid;
pub mod ndf;
pub mod quadrature;
pub mod sh;
