//! Helpers shared by the subcommands: reading inputs with limits, progress bars, parallel maps.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Read a UTF-8 text file of at most `limit` bytes, naming the file in every error.
pub fn read_text(path: &Path, limit: u64) -> Result<String> {
    let bytes = read_bytes(path, limit)?;
    String::from_utf8(bytes).with_context(|| format!("{}: not UTF-8 text", path.display()))
}

/// Read at most `limit` bytes of a file, counting the bytes actually read
/// ([`meso_core::io::read_limited`]: `/dev/zero` and FIFOs too); errors name the file.
pub fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>> {
    meso_core::io::read_limited(path, limit).map_err(|e| {
        if e.kind() == std::io::ErrorKind::FileTooLarge {
            anyhow::anyhow!("{}: {e}", path.display())
        } else {
            anyhow::anyhow!("{}: cannot read: {e}", path.display())
        }
    })
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

/// A progress bar for work measured in estimated cost units (not items): a percentage, the
/// elapsed time ticking every 200 ms even while the position does not move, and the estimate of
/// the time left. Hidden when stderr is not a terminal. `len` is the total work (> 0); set it
/// again with `set_length` once known, never to a placeholder.
pub fn progress_work(len: u64, what: &str) -> ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len.max(1));
    bar.set_style(
        ProgressStyle::with_template("{prefix:>8} [{bar:40}] {percent:>3}% ({elapsed}, eta {eta})")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.set_prefix(what.to_owned());
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

/// The times of a command's phases, for the closing line: `load 0.10 s, pyramid 11.80 s`.
#[derive(Debug, Default)]
pub struct Phases(Vec<(String, f64)>);

impl Phases {
    /// Record that phase `name` took `seconds` (a phase named twice adds up).
    pub fn add(&mut self, name: &str, seconds: f64) {
        match self.0.iter_mut().find(|(n, _)| n == name) {
            Some((_, s)) => *s += seconds,
            None => self.0.push((name.to_owned(), seconds)),
        }
    }

    /// Run `f` as phase `name`, recording its time.
    pub fn time<R>(&mut self, name: &str, f: impl FnOnce() -> R) -> R {
        let t = std::time::Instant::now();
        let r = f();
        self.add(name, t.elapsed().as_secs_f64());
        r
    }

    /// The seconds of phase `name` (0 if it did not run).
    pub fn seconds(&self, name: &str) -> f64 {
        self.0
            .iter()
            .find(|(n, _)| n == name)
            .map_or(0.0, |(_, s)| *s)
    }

    /// The seconds of every phase together.
    pub fn total(&self) -> f64 {
        self.0.iter().map(|(_, s)| s).sum()
    }

    /// `load 0.10 s, pyramid 11.80 s, render 0.05 s`.
    pub fn summary(&self) -> String {
        self.0
            .iter()
            .map(|(n, s)| format!("{n} {s:.2} s"))
            .collect::<Vec<_>>()
            .join(", ")
    }
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

/// The input and output of `meso brdf` and `meso gonio`: direction pairs in, BRDF values out.
#[derive(clap::Args, Debug)]
pub struct BrdfTable {
    /// Direction pairs (CSV with header theta_i,phi_i,theta_o,phi_o; degrees).
    #[arg(long)]
    pub pairs: PathBuf,
    /// Output CSV; standard output when absent.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
}

impl BrdfTable {
    /// The direction pairs of `--pairs` (errors name the file).
    pub fn read_pairs(&self) -> Result<Vec<meso_core::pairs::DirectionPair>> {
        let text = read_text(&self.pairs, 1 << 30)?;
        meso_core::pairs::parse_pairs(&text).with_context(|| format!("{}", self.pairs.display()))
    }

    /// Write `values` at `pairs` as the CSV of `write_brdf_table`: to `--out` atomically, or to
    /// standard output.
    pub fn write(
        &self,
        pairs: &[meso_core::pairs::DirectionPair],
        values: &[[f64; 3]],
    ) -> Result<()> {
        write_brdf_table(self.out.as_deref(), pairs, values)
    }
}

/// Write BRDF values as the CSV of `meso brdf` and `meso gonio`: the pair's four angles as read
/// (degrees; very large or small ones in exponent notation, `meso_core::display::Num`, the same
/// value) and `r,g,b` in 1/sr. To `out` atomically, or to standard output.
fn write_brdf_table(
    out: Option<&Path>,
    pairs: &[meso_core::pairs::DirectionPair],
    values: &[[f64; 3]],
) -> Result<()> {
    use meso_core::display::Num;
    use std::io::Write;
    let write = |w: &mut dyn Write| -> std::io::Result<()> {
        writeln!(w, "theta_i,phi_i,theta_o,phi_o,r,g,b")?;
        for (p, v) in pairs.iter().zip(values) {
            let d = p.degrees;
            writeln!(
                w,
                "{},{},{},{},{:.9e},{:.9e},{:.9e}",
                Num(d[0]),
                Num(d[1]),
                Num(d[2]),
                Num(d[3]),
                v[0],
                v[1],
                v[2]
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
            write(&mut lock)
                .and_then(|()| lock.flush())
                .map_err(stdout_error)?;
        }
    }
    Ok(())
}

/// The reader of standard output went away (`EPIPE`, e.g. `meso map info MAP | head -1`): the
/// command stops writing and exits quietly with status 141 (128 + SIGPIPE), the status a Unix
/// tool killed by SIGPIPE reports, so `set -o pipefail` scripts see what they see for `cat`.
#[derive(Debug)]
pub struct StdoutClosed;

impl std::fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("standard output closed")
    }
}

impl std::error::Error for StdoutClosed {}

/// The exit status of a command whose standard output was closed by its reader.
pub const EXIT_STDOUT_CLOSED: u8 = 141;

/// An error writing standard output: [`StdoutClosed`] for a broken pipe, otherwise a one-line
/// error ("cannot write to standard output: No space left on device (os error 28)").
pub fn stdout_error(e: std::io::Error) -> anyhow::Error {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        anyhow::Error::new(StdoutClosed)
    } else {
        anyhow::anyhow!("cannot write to standard output: {e}")
    }
}

/// Write `text` to standard output and flush it, turning write errors into errors
/// ([`stdout_error`]) instead of the panic of `print!`.
pub fn print_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(stdout_error)
}

/// Write a diagnostic line to standard error. A failure to write it (stderr on a full disk or a
/// closed pipe) is ignored: there is nowhere left to report it, and the exit status still tells
/// whether the command succeeded.
pub fn note(args: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.write_all(b"\n"));
}

/// Whether `e` (or any error in its chain) is a closed standard output or a broken pipe.
pub fn is_stdout_closed(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.is::<StdoutClosed>()
            || c.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// The one-line message of an error chain: each cause appended once. Causes whose text the
/// message already contains (errors that print their source themselves) are not repeated, so an
/// OS error appears once.
pub fn error_message(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if text.is_empty() || msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    msg
}

/// The file a path names, for comparing outputs that may not exist yet: the canonical parent
/// directory joined with the file name (the path itself when the parent cannot be resolved).
fn output_identity(p: &Path) -> std::path::PathBuf {
    if let Ok(c) = std::fs::canonicalize(p) {
        return c;
    }
    let parent = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (std::fs::canonicalize(parent), p.file_name()) {
        (Ok(d), Some(n)) => d.join(n),
        _ => p.to_path_buf(),
    }
}

/// Refuse outputs that would overwrite one of the command's inputs
/// ([`meso_core::io::check_not_input`]: those given, and every file read so far, the input
/// log), that are existing directories, whose directory does not exist, or that name the same
/// file twice.
pub fn check_outputs(outputs: &[&Path], inputs: &[&Path]) -> Result<()> {
    for (j, out) in outputs.iter().enumerate() {
        meso_core::io::check_not_input(out, inputs)?;
        // And every file read so far (a scene's materials, their height maps, …).
        meso_core::io::check_not_recorded_input(out)?;
        // A folder where a file is asked for: said before the work, naming the output (not the
        // input the work was on, as the write's own error did).
        if out.is_dir() {
            bail!(
                "{}: cannot write: it is a directory (the output is a file: give its name)",
                out.display()
            );
        }
        if std::fs::symlink_metadata(out).is_err() {
            // Fail before the work, not after it: the output's directory must exist.
            let dir = match out.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            if !dir.is_dir() {
                bail!(
                    "{}: cannot write: the directory {} does not exist",
                    out.display(),
                    dir.display()
                );
            }
        }
        let id = output_identity(out);
        if let Some(first) = outputs[..j].iter().find(|o| output_identity(o) == id) {
            let regular = std::fs::metadata(out).map_or(true, |m| m.is_file());
            if regular {
                bail!(
                    "{} and {} are the same output file; choose two different files",
                    first.display(),
                    out.display()
                );
            }
        }
    }
    Ok(())
}
