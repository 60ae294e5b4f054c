//! `meso figures [--out DIR]` — render the paper's figures from built-in data
//! (docs/figures.md).

use anyhow::Result;
use std::path::PathBuf;

/// Render the paper's figures (Fig. 2–4, a filtered zoom sequence, an NDF blend strip and a
/// labelled contact sheet) from data generated in code, with their material and scene files.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output directory (created if missing).
    #[arg(long, short, default_value = "out/figures")]
    pub out: PathBuf,
    /// Edge of the sphere pictures in pixels (32..=4096).
    #[arg(long, default_value_t = 320)]
    pub size: u32,
    /// Samples per pixel (1..=4096).
    #[arg(long, default_value_t = 4)]
    pub spp: u32,
    /// Frames of the zoom sequence (at least 6).
    #[arg(long, default_value_t = 8)]
    pub zoom_frames: usize,
}

/// Estimated peak memory (bytes) of `meso figures` at `--size size`: 64 MiB for the built-in
/// maps, pyramids and the fixed-size pictures, and 128 bytes per pixel of a `size²` picture
/// (renders, sheets). Measured peak RSS (1 spp): 36 MB at 32, 51 MB at 320, 83 MB at 640,
/// 237 MB at 1280 (estimated 67, 80, 120 and 277 MB); `--spp` and `--zoom-frames` change the
/// time, not the peak.
#[must_use]
pub fn figures_bytes(size: u32) -> u64 {
    (64 << 20) + 128 * u64::from(size) * u64::from(size)
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    if !(32..=4096).contains(&a.size) {
        anyhow::bail!("--size must be in 32..=4096 pixels, got {}", a.size);
    }
    if !(1..=4096).contains(&a.spp) {
        anyhow::bail!("--spp must be in 1..=4096, got {}", a.spp);
    }
    if !(6..=64).contains(&a.zoom_frames) {
        anyhow::bail!("--zoom-frames must be in 6..=64, got {}", a.zoom_frames);
    }
    meso_core::budget::check_named(
        "meso figures",
        &format!("rendering the figures at --size {}", a.size),
        figures_bytes(a.size),
    )?;
    let opts = meso_figures::Options {
        out: a.out.clone(),
        size: a.size,
        spp: a.spp,
        zoom_frames: a.zoom_frames,
    };
    let t = std::time::Instant::now();
    let report = meso_figures::run(&opts, &mut |line| note!("  {line}"))?;
    note!(
        "wrote {} files to {} in {:.1} s (contact sheet: {})",
        report.files.len(),
        a.out.display(),
        t.elapsed().as_secs_f64(),
        a.out.join("contact_sheet.png").display()
    );
    Ok(())
}
