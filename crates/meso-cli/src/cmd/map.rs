//! `meso map info MAP` — inspect a map file written by `meso extract`.

use anyhow::Result;
use meso_maps::Pyramid;
use std::path::PathBuf;

/// Inspect map files (NDF pyramids).
#[derive(clap::Subcommand, Debug)]
pub enum MapCommand {
    /// Print the levels of a map file: sizes, lobe counts and fit residuals.
    Info(InfoArgs),
}

/// Arguments of `meso map info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// Map file (docs/map-format.md).
    pub map: PathBuf,
}

/// Run the command.
pub fn run(c: MapCommand) -> Result<()> {
    match c {
        MapCommand::Info(a) => {
            // Only the lobe counts and residuals are printed: the pyramid held as compactly as
            // the budget asks (an 8192² map's level 0 by band), its values never decoded.
            let pyr = Pyramid::read_compact(&a.map)?;
            crate::util::print_stdout(&pyr.info().to_string())
        }
    }
}
