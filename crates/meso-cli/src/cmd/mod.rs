//! One module per subcommand.
pub mod brdf;
pub mod export;
pub mod extract;
pub mod figures;
pub mod fit;
pub mod fit_nonparametric;
pub mod gonio;
pub mod map;
pub mod ndf;
pub mod ndf_plot;
pub mod render;
pub mod serve;
