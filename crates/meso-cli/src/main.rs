//! `meso` — the command line over the meso libraries. Each subcommand lives in `cmd/<name>.rs`
//! with a clap `Args` struct and a `run` function; this file only dispatches.

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

/// `eprintln!` that cannot panic: a diagnostic line on standard error ([`util::note`]).
macro_rules! note {
    ($($t:tt)*) => {
        $crate::util::note(format_args!($($t)*))
    };
}

mod alloc;
mod cmd;
mod util;

/// The process's allocator: the system's, with an allocation failure turned into a one-line
/// error and exit status 1 instead of an abort ([`alloc::ExitOnOom`]).
#[global_allocator]
static ALLOCATOR: alloc::ExitOnOom = alloc::ExitOnOom;

pub(crate) use util::{par_map_progress, progress, read_text};

/// Load a material file, resolving height-map NDFs.
pub(crate) fn load_material(
    path: &std::path::Path,
) -> anyhow::Result<meso_core::material::Material> {
    let maps = meso_maps::MapsResolver::new().with_warnings(print_warning());
    let m = meso_core::material::Material::from_file(path, &maps)?;
    maps.warn_estimated_interreflection(path, &m, false);
    Ok(m)
}

/// What loading an input found and corrected, printed on standard error as
/// `FILE: warning: …` (the form of `meso extract`'s warnings).
pub(crate) fn print_warning() -> meso_maps::resolver::Warnings {
    std::sync::Arc::new(|file: &std::path::Path, w: &str| {
        eprintln!("{}: warning: {w}", file.display());
    })
}

/// meso: normal distribution functions and multiple surfaces (Fournier 1992).
#[derive(Parser)]
#[command(name = "meso", version, about, long_about = None)]
struct Cli {
    /// Memory budget: refuse work whose estimated peak memory is larger (bytes, or with a K, M,
    /// G or T suffix: 8G, 512M). Default: 4G, or ¾ of the physical memory or of the
    /// address-space limit when smaller; also set by the MESO_MEMORY_BUDGET environment
    /// variable (docs/limits.md).
    #[arg(long, global = true, value_name = "SIZE", value_parser = parse_budget)]
    memory_budget: Option<u64>,
    #[command(subcommand)]
    command: Command,
}

/// `--memory-budget`'s value parser.
fn parse_budget(s: &str) -> Result<u64, String> {
    meso_core::budget::parse_size(s)
}

#[derive(Subcommand)]
enum Command {
    /// Evaluate a material's effective BRDF at direction pairs (CSV in, CSV out).
    Brdf(cmd::brdf::Args),
    /// Inspect an NDF: plot it or print its statistics.
    #[command(subcommand)]
    Ndf(cmd::ndf::NdfCommand),
    /// Fit a measured BRDF (MERL binary or sample CSV) with a sum of K lobes (Phong peaks,
    /// microfacet Phong peaks or GGX lobes; the best on held-out data), or a tabulated NDF
    /// (`--nonparametric`); write a material.
    Fit(cmd::fit::Args),
    /// Extract the NDF pyramid of a height map (or normal map) into a map file.
    Extract(cmd::extract::Args),
    /// Export a normal/height map as engine-ready textures: fitted GGX roughness and normal mip
    /// chains (KTX2 + PNG) and a glTF 2.0 preview asset.
    Export(cmd::export::Args),
    /// Inspect map files (NDF pyramids).
    #[command(subcommand)]
    Map(cmd::map::MapCommand),
    /// Measure a height-map material's BRDF by ray tracing (virtual gonioreflectometer).
    Gonio(cmd::gonio::Args),
    /// Render a scene file (TOML) to an EXR or PNG image.
    Render(cmd::render::Args),
    /// Serve the interactive NDF editor in the browser (127.0.0.1:7878 by default).
    Serve(cmd::serve::Args),
    /// Render the paper's figures from built-in data (docs/figures.md).
    Figures(cmd::figures::Args),
}

/// `cmd` and its subcommands with every option that takes a value accepting a negative number
/// (`--texel-size -1`, `--phi -30`), so that the option's own range check answers instead of
/// clap's "unexpected argument '-1'".
fn allow_negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| {
        if a.get_action().takes_values() {
            a.allow_negative_numbers(true)
        } else {
            a
        }
    })
    .mut_subcommands(allow_negative_numbers)
}

fn main() -> ExitCode {
    let matches = allow_negative_numbers(Cli::command()).get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // No output of a command may replace a file it read (a scene's material, a material's
    // height map, …): meso_core::io's input log. (The editor's server writes no files and runs
    // for long: it keeps no log.)
    if !matches!(cli.command, Command::Serve(_)) {
        meso_core::io::record_inputs();
    }
    if let Some(b) = cli.memory_budget {
        meso_core::budget::set_budget(b);
    } else if let Some(Err(e)) = meso_core::budget::env_budget() {
        note!("meso: error: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Brdf(a) => cmd::brdf::run(a),
        Command::Ndf(a) => cmd::ndf::run(a),
        Command::Fit(a) if a.nonparametric => cmd::fit_nonparametric::run(&a),
        Command::Fit(a) => cmd::fit::run(a),
        Command::Extract(a) => cmd::extract::run(a),
        Command::Export(a) => cmd::export::run(a),
        Command::Map(a) => cmd::map::run(a),
        Command::Gonio(a) => cmd::gonio::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Serve(a) => cmd::serve::run(a),
        Command::Figures(a) => cmd::figures::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if util::is_stdout_closed(&e) => ExitCode::from(util::EXIT_STDOUT_CLOSED),
        Err(e) => {
            note!("meso: error: {}", util::error_message(&e));
            ExitCode::FAILURE
        }
    }
}
