//! Helpers shared by the subcommands: reading inputs with limits, progress bars, parallel maps.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::path::Path;

/// Read a UTF-8 text file of at most `limit` bytes, naming the file in every error.
pub fn read_text(path: &Path, limit: u64) -> Result<String> {
    let meta =
        std::fs::metadata(path).with_context(|| format!("{}: cannot read", path.display()))?;
    if meta.len() > limit {
        bail!(
            "{}: {} bytes is larger than the limit of {limit} bytes",
            path.display(),
            meta.len()
        );
    }
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    String::from_utf8(bytes).with_context(|| format!("{}: not UTF-8 text", path.display()))
}

/// A progress bar on standard error, hidden when stderr is not a terminal or the job is small.
pub fn progress(len: u64, what: &str) -> ProgressBar {
    use std::io::IsTerminal;
    if len < 2000 || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{prefix:>8} [{bar:40}] {pos}/{len} ({eta})")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.set_prefix(what.to_owned());
    bar
}

/// Map `f` over `items` in parallel (rayon), ticking `bar` in chunks.
pub fn par_map_progress<T: Sync, R: Send>(
    items: &[T],
    bar: &ProgressBar,
    f: impl Fn(&T) -> R + Sync,
) -> Vec<R> {
    items
        .par_chunks(256)
        .flat_map_iter(|chunk| {
            let v: Vec<R> = chunk.iter().map(&f).collect();
            bar.inc(chunk.len() as u64);
            v
        })
        .collect()
}

/// Write BRDF values as the CSV of `meso brdf` and `meso gonio`: the pair's four angles as read
/// (degrees) and `r,g,b` in 1/sr. To `out` atomically, or to standard output.
pub fn write_brdf_table(
    out: Option<&Path>,
    pairs: &[meso_core::pairs::DirectionPair],
    values: &[[f64; 3]],
) -> Result<()> {
    use std::io::Write;
    let write = |w: &mut dyn Write| -> std::io::Result<()> {
        writeln!(w, "theta_i,phi_i,theta_o,phi_o,r,g,b")?;
        for (p, v) in pairs.iter().zip(values) {
            let d = p.degrees;
            writeln!(
                w,
                "{},{},{},{},{:.9e},{:.9e},{:.9e}",
                d[0], d[1], d[2], d[3], v[0], v[1], v[2]
            )?;
        }
        Ok(())
    };
    match out {
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
