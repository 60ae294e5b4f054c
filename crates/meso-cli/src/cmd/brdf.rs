//! `meso brdf MATERIAL --pairs PAIRS.csv [--out OUT.csv]` — evaluate a material's effective BRDF.

use anyhow::{Context, Result};
use meso_core::pairs::parse_pairs;
use std::path::PathBuf;

/// Evaluate the effective BRDF of a material at direction pairs.
///
/// PAIRS.csv has the header `theta_i,phi_i,theta_o,phi_o` (degrees, material's local frame, both
/// directions above the surface). The output repeats these columns and adds `r,g,b`: BRDF values in
/// 1/sr, without the cosine factor.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Material file (TOML, see docs/material-format.md).
    pub material: PathBuf,
    /// Direction pairs (CSV with header theta_i,phi_i,theta_o,phi_o; degrees).
    #[arg(long)]
    pub pairs: PathBuf,
    /// Output CSV; standard output when absent.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    if let Some(out) = &a.out {
        crate::util::check_outputs(&[out], &[&a.material, &a.pairs])?;
    }
    let material = crate::load_material(&a.material)?;
    let text = crate::read_text(&a.pairs, 1 << 30)?;
    let pairs = parse_pairs(&text).with_context(|| format!("{}", a.pairs.display()))?;
    let bar = crate::progress(pairs.len() as u64, "brdf");
    let values = crate::par_map_progress(&pairs, &bar, |p| material.brdf(p.i, p.o));
    bar.finish_and_clear();
    crate::util::write_brdf_table(a.out.as_deref(), &pairs, &values)
}
