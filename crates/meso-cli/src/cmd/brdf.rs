//! `meso brdf MATERIAL --pairs PAIRS.csv [--out OUT.csv] [--exact]` — evaluate a material's
//! effective BRDF (its compiled plan, [`meso_core::shading::Policy::Accurate`], or with `--exact`
//! the quadrature of every pair).

use anyhow::Result;
use meso_core::shading::{FastBrdf, Policy};
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
    #[command(flatten)]
    pub table: crate::util::BrdfTable,
    /// Evaluate every pair by the material's own quadrature (Eq. 2/8) instead of its compiled
    /// plan. The plan differs only where it tabulates Smith Λ (mirror facets under an NDF
    /// without a closed form, e.g. fitted lobe sums): < 2e-4 relative for isotropic NDFs,
    /// < 1e-2 otherwise (docs/benchmarks.md "meso brdf").
    #[arg(long)]
    pub exact: bool,
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    if let Some(out) = &a.table.out {
        crate::util::check_outputs(&[out], &[&a.material, &a.table.pairs])?;
    }
    let material = crate::load_material(&a.material)?;
    let pairs = a.table.read_pairs()?;
    if let Some(out) = &a.table.out {
        // Again, now that the files the material names (a height map, a map file) are read.
        crate::util::check_outputs(&[out], &[])?;
    }
    let bar = crate::progress(pairs.len() as u64, "brdf");
    let values = if a.exact {
        crate::par_map_progress(&pairs, &bar, |p| material.brdf(p.i, p.o))
    } else {
        let plan = FastBrdf::with_policy(&material, Policy::Accurate);
        crate::par_map_progress(&pairs, &bar, |p| plan.eval(p.i, p.o))
    };
    bar.finish_and_clear();
    a.table.write(&pairs, &values)
}
