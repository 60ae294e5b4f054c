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
            // Reading checks every band (≈ 20 s for an 8192² map): a bar on a terminal.
            let bar = std::cell::OnceCell::new();
            let pyr = Pyramid::read_compact_reporting(&a.map, &mut |p| {
                let b = bar.get_or_init(|| crate::util::progress_work(p.work_total, "map file"));
                b.set_position(p.work_done);
            });
            if let Some(b) = bar.get() {
                b.finish_and_clear();
            }
            let pyr = pyr?;
            crate::util::print_stdout(&pyr.info().to_string())
        }
    }
}
