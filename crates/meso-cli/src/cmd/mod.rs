//! One module per subcommand.
pub mod brdf;
pub mod fit;
pub mod ndf;
pub mod ndf_plot;
