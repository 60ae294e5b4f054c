//! # meso-core
//!
//! The numeric core of meso: normal distribution functions (NDFs) as first-class objects,
//! facet transfer functions, and the convolution of the two into an effective BRDF
//! (Fournier 1992, "Normal Distribution Functions and Multiple Surfaces", Eq. 1–13).
//!
//! * [`frame`] — the conventions (directions, the local frame with the normal on +z, spherical
//!   coordinates), written once;
//! * [`ndf`] — the NDF representations, each normalised as Eq. 1, evaluated and sampled;
//! * [`transfer`] — facet BRDFs (Phong, Lambert, mirror, rough microfacet) with Fresnel;
//! * [`convolution`] — Eq. 2/8 by quadrature, Eq. 4 exactly, and a closed form; [`integrate`] —
//!   the lobe-adapted quadrature of `∫ n(m) g(m) dω` it and the NDF statistics use;
//! * [`material`] — the TOML material format; [`importance`] — importance sampling of its BRDF;
//!   [`catalogue`] — the paper's materials (Fig. 2a–d, velvet, silk), defined once;
//! * [`grid`], [`quadrature`], [`sh`] — numerical building blocks; [`io`] — atomic file output;
//! * [`linalg`], [`lm`] — small dense linear algebra and the one Levenberg–Marquardt solver
//!   (generic over the parameter space, with box bounds or a retraction), used by every fitter;
//! * [`budget`] — the memory budget and fallible allocation; [`fastmath`] — `pow`, `exp`, `ln`
//!   without libm for every inner loop; [`special`] — `ln Γ`, the one copy in the workspace.
//!
//! ```
//! use meso_core::{frame::spherical_direction_deg, material::Material};
//! let m = Material::from_toml_str(r#"
//!     [ndf]
//!     kind = "phong-peaks"
//!     lobes = [{ axis = [0.0, 0.0], weight = 1.0, exponent = 40.0 }]
//!     [transfer]
//!     kind = "phong"
//!     exponent = 50.0
//!     specular = [1.0, 1.0, 1.0]
//! "#).unwrap();
//! let f = m.brdf(spherical_direction_deg(30.0, 0.0), spherical_direction_deg(30.0, 180.0));
//! assert!(f[0] > 0.0);
//! ```
#![warn(missing_docs)]

pub mod budget;
pub mod catalogue;
pub mod convolution;
pub mod display;
pub mod fastmath;
pub mod frame;
pub mod grid;
pub mod importance;
pub mod integrate;
pub mod io;
pub mod linalg;
pub mod lm;
pub mod material;
pub mod ndf;
pub mod pairs;
pub mod quadrature;
pub mod sg;
pub mod sh;
pub mod shading;
pub mod special;
pub mod transfer;
pub mod visibility;

/// An invalid NDF description.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NdfError {
    /// The parameters do not describe a valid NDF; the message says which and why.
    #[error("{0}")]
    Invalid(String),
}
