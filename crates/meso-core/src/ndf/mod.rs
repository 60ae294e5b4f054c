//! Normal distribution functions, normalised as in Eq. 1: ∫ n(m) dω = 1 over the whole sphere.
pub mod phong;
pub use phong::PhongLobe;
