//! `meso brdf MATERIAL --pairs PAIRS.csv [--out OUT.csv]` — evaluate a material's effective BRDF.

use anyhow::{Context, Result};
use meso_core::pairs::parse_pairs;
use std::io::Write;
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
    let material = crate::load_material(&a.material)?;
    let text = crate::read_text(&a.pairs, 1 << 30)?;
    let pairs = parse_pairs(&text).with_context(|| format!("{}", a.pairs.display()))?;
    let bar = crate::progress(pairs.len() as u64, "brdf");
    let values = crate::par_map_progress(&pairs, &bar, |p| material.brdf(p.i, p.o));
    bar.finish_and_clear();
    let write = |w: &mut dyn Write| -> std::io::Result<()> {
        writeln!(w, "theta_i,phi_i,theta_o,phi_o,r,g,b")?;
        for (p, v) in pairs.iter().zip(&values) {
            let d = p.degrees;
            writeln!(
                w,
                "{},{},{},{},{:.9e},{:.9e},{:.9e}",
                d[0], d[1], d[2], d[3], v[0], v[1], v[2]
            )?;
        }
        Ok(())
    };
    match &a.out {
        Some(path) => meso_core::io::write_atomic_with(path, write)
            .with_context(|| format!("{}: cannot write", path.display()))?,
        None => {
            let stdout = std::io::stdout();
            let mut lock = std::io::BufWriter::new(stdout.lock());
            write(&mut lock)?;
            lock.flush()?;
        }
    }
    Ok(())
}
