//! `meso extract HEIGHTMAP --texel-size S --height-scale H [--max-lobes K] --out MAP` — build the
//! NDF pyramid of a height map (or normal map) and write it as a map file (docs/map-format.md):
//! streamed (`meso_maps::extract_to_file`), each row batch of each level written as it is
//! fitted (format 4), so memory never holds the pyramid.

use anyhow::{bail, Context, Result};
use meso_maps::fit::MergeLevels;
use meso_maps::{
    extract_to_file, Baseline, Border, ExtractParams, InputKind, Method, NormalConvention,
    NormalMode,
};
use std::path::PathBuf;

/// Green-channel convention of a normal map.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Convention {
    /// OpenGL: green is +y.
    Gl,
    /// DirectX: green is −y.
    Dx,
}

/// What to store per texel.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodArg {
    /// Up to K fitted Phong peaks (the multiple surface).
    Lobes,
    /// Toksvig: one Phong peak about the mean normal.
    Toksvig,
    /// LEAN (five moments), isotropised to one Phong peak.
    Lean,
    /// One von Mises–Fisher lobe, as a Phong peak.
    Vmf,
    /// The mip-mapped (averaged) normal: one delta-like lobe.
    Mip,
}

/// Which pyramid levels are fitted by merging their children's lobes
/// (`meso_maps::fit::MergeLevels`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MergeLevelsArg {
    /// Every level fitted from its own normals.
    None,
    /// The levels without the smoothed refinement (the big ones).
    Plain,
    /// Every level above level 0.
    All,
}

/// Normals from the height map.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum NormalsArg {
    /// Two flat triangles per grid cell (exact for the displaced surface).
    Triangles,
    /// Central differences, one normal per cell (smooth data).
    Central,
}

/// How `meso extract` chooses each texel's number of lobes.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum KChoiceArg {
    /// By the likelihood gain of one more lobe (the default).
    Likelihood,
    /// By the shading error under the facet's kernel (`meso_maps::fit::KChoice::Shading`).
    Shading,
}

/// Extract the NDF pyramid of a height map (docs/heightmaps.md) and write a map file.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Height map (8/16-bit grey PNG, JPEG, TGA, 16-bit TIFF, float EXR) or, with --normal-map,
    /// an RGB (or two-channel) tangent-space normal map in the same formats.
    pub heightmap: PathBuf,
    /// Distance between samples S (length units, > 0); required for height maps.
    #[arg(long)]
    pub texel_size: Option<f64>,
    /// Height of the full code range H (same unit, > 0); required for height maps.
    #[arg(long)]
    pub height_scale: Option<f64>,
    /// Largest number of lobes per texel (1–8), on every map. Default: 4, or 6 on a map of
    /// faces and walls (at least a tenth of its projected area within 10° of the normal and a
    /// tenth more than 45° from it; the report says so).
    #[arg(long)]
    pub max_lobes: Option<usize>,
    /// The input is a tangent-space normal map (no heights: no horizon statistics).
    #[arg(long)]
    pub normal_map: bool,
    /// Green-channel convention of the normal map.
    #[arg(long, value_enum, default_value = "gl", requires = "normal_map")]
    pub convention: Convention,
    /// The map is one tile of a periodic surface (the default).
    #[arg(long, conflicts_with = "clamp")]
    pub wrap: bool,
    /// Only the samples inside the image exist.
    #[arg(long)]
    pub clamp: bool,
    /// Normals from two triangles per cell (default) or central differences.
    #[arg(long, value_enum, default_value = "triangles")]
    pub normals: NormalsArg,
    /// Fitted lobes (default) or a single-lobe baseline.
    #[arg(long, value_enum, default_value = "lobes")]
    pub method: MethodArg,
    /// Roughness α in (0, 1] of the facet BRDF (GGX or Beckmann) the map will be shaded with:
    /// the shading error per level is then reported under that facet's kernel
    /// `exp(λ(h·m − 1))`, λ = 2/α² (default λ = 40, about α = 0.22), `--k-choice shading`
    /// picks the lobes by it, and the merged levels (`--merge-levels`) keep lobes apart down
    /// to 1/250 of its variance.
    #[arg(long)]
    pub facet_alpha: Option<f64>,
    /// How each texel's number of lobes (up to --max-lobes) is chosen: `likelihood` (the
    /// default: more lobes while they raise the likelihood of the normals), or `shading` (the
    /// fewest lobes with the least shading error under the facet's kernel, among the fits at
    /// every K). `shading` rendered a steep test map worse than the default
    /// (docs/heightmaps.md, "Lobe fits that cannot go wrong") and costs ≈ 2× the time.
    #[arg(long, value_enum, default_value = "likelihood")]
    pub k_choice: KChoiceArg,
    /// Which levels are fitted by merging their children's lobes instead of fitting their
    /// own normals: `plain` (the default: the big levels, which otherwise get EM alone; the
    /// small ones keep their own smoothed fit), `none` (every level its own fit: the fit before
    /// 2026-12-06, ≈ 1.5× the time of `plain` on a 1024² map), or `all` (the fast fit: ≈ 0.5×
    /// the time of `plain`, with the coarse levels' shading error up to 1.4× theirs)
    /// (docs/heightmaps.md, "Levels merged from their children"). Ignored with --k-chain and
    /// --k-choice shading, which choose among each texel's own fits.
    #[arg(long, value_enum, default_value = "plain")]
    pub merge_levels: MergeLevelsArg,
    /// Fit K = 1, 2, … up to --max-lobes, each from the fit before, and keep the end of the
    /// chain: the fit's own objective never rises with --max-lobes (the default single fit at
    /// --max-lobes can rise). Opt-in: it rendered a steep test map worse (docs/heightmaps.md,
    /// "Lobe fits that cannot go wrong"); costs ≈ 2× the time.
    #[arg(long)]
    pub k_chain: bool,
    /// Output map file (written atomically).
    #[arg(long, short)]
    pub out: PathBuf,
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    if let Some(k) = a.max_lobes {
        if !(1..=meso_maps::limits::MAX_LOBES).contains(&k) {
            bail!(
                "--max-lobes {k}: must be between 1 and {}",
                meso_maps::limits::MAX_LOBES
            );
        }
    }
    crate::util::check_outputs(&[&a.out], &[&a.heightmap])?;
    let border = if a.clamp { Border::Clamp } else { Border::Wrap };
    let mut params = ExtractParams {
        normal_mode: match a.normals {
            NormalsArg::Triangles => NormalMode::Triangles,
            NormalsArg::Central => NormalMode::CentralDifferences,
        },
        method: match a.method {
            MethodArg::Lobes => Method::Lobes,
            MethodArg::Toksvig => Method::Baseline(Baseline::Toksvig),
            MethodArg::Lean => Method::Baseline(Baseline::Lean),
            MethodArg::Vmf => Method::Baseline(Baseline::Vmf),
            MethodArg::Mip => Method::Baseline(Baseline::MipNormal),
        },
        ..ExtractParams::default()
    };
    if let Some(k) = a.max_lobes {
        params = params.with_max_lobes(k);
    }
    if let Some(alpha) = a.facet_alpha {
        if !(alpha.is_finite() && alpha > 0.0 && alpha <= 1.0) {
            bail!("--facet-alpha {alpha}: must be a roughness in (0, 1]");
        }
        params.fit.facet_exponent = (2.0 / (alpha * alpha)).clamp(1.0, 1e4);
    }
    params.fit.k_chain = a.k_chain;
    params.fit.merge_levels = match a.merge_levels {
        MergeLevelsArg::None => MergeLevels::None,
        MergeLevelsArg::Plain => MergeLevels::Plain,
        MergeLevelsArg::All => MergeLevels::All,
    };
    if a.k_choice == KChoiceArg::Shading {
        params.fit.k_choice = meso_maps::fit::KChoice::Shading { tolerance: 0.0 };
    }
    let kind = if a.normal_map {
        if a.texel_size.is_some() || a.height_scale.is_some() {
            bail!("--texel-size and --height-scale do not apply to a normal map (--normal-map)");
        }
        InputKind::Normals(match a.convention {
            Convention::Gl => NormalConvention::Gl,
            Convention::Dx => NormalConvention::Dx,
        })
    } else {
        let (Some(texel_size), Some(height_scale)) = (a.texel_size, a.height_scale) else {
            bail!("a height map needs --texel-size S and --height-scale H");
        };
        InputKind::Heights {
            texel_size,
            height_scale,
            border,
        }
    };
    let mut phases = crate::util::Phases::default();
    let t = std::time::Instant::now();
    let (input, warnings) = meso_maps::input::load_streamed(&a.heightmap, kind, &params)?;
    for w in warnings {
        note!("{}: warning: {w}", a.heightmap.display());
    }
    let source = input.source();
    phases.add("load", t.elapsed().as_secs_f64());
    // A map of faces and walls gets more lobes a texel unless --max-lobes was given: say so.
    let asked = params.fit.max_lobes;
    let params = params.for_source(source);
    let k = params.fit.max_lobes;
    if k > asked {
        let (faces, walls) = meso_maps::relief_shares(source, params.normal_mode);
        note!(
            "{}: faces and walls ({:.0} % of the projected area within 10° of the normal, {:.0} % more than 45° from it): up to {k} lobes a texel (--max-lobes sets it)",
            a.heightmap.display(),
            100.0 * faces,
            100.0 * walls
        );
    }
    let bar = crate::util::progress_work(1, "pyramid");
    // The pyramid's levels are fitted and written band by band: one phase, "pyramid" (the
    // writing included).
    let levels = phases
        .time("pyramid", || {
            extract_to_file(source, &params, &a.out, &mut |p| {
                bar.set_length(p.work_total);
                bar.set_position(p.work_done);
            })
        })
        .with_context(|| format!("{}", a.heightmap.display()))?;
    bar.finish_and_clear();
    let top = levels.last().expect("a pyramid has at least one level");
    note!(
        "{}: {} levels, top level {} lobes (NDF residual {:.4}, shading error {:.2} % of peak); {}",
        a.out.display(),
        levels.len(),
        top.lobes,
        top.residual.mean,
        100.0 * top.residual.shading_mean.unwrap_or(0.0),
        phases.summary()
    );
    // Per level: the shading error (mean/max over the sampled texels, % of each texel's peak;
    // `meso map info` prints it too, with the NDF residual) and the mean lobes per texel (K is
    // chosen per texel).
    let per_level: Vec<String> = levels
        .iter()
        .enumerate()
        .map(|(k, l)| {
            format!(
                "{k}: {:.2}/{:.2} ({:.2})",
                100.0 * l.residual.shading_mean.unwrap_or(0.0),
                100.0 * l.residual.shading_max.unwrap_or(0.0),
                l.lobes as f64 / (l.cols * l.rows) as f64
            )
        })
        .collect();
    // Which levels were fitted by merging their children's lobes (`--merge-levels`).
    let (cols, rows) = (levels[0].cols, levels[0].rows);
    let merged = meso_maps::merged_levels(cols, rows, &params);
    note!(
        "levels fitted by merging their children's lobes (--merge-levels {}): {}",
        params.fit.merge_levels.name(),
        match (merged.first(), merged.last()) {
            (Some(a), Some(b)) if a == b => a.to_string(),
            (Some(a), Some(b)) => format!("{a}–{b}"),
            _ => "none".to_owned(),
        }
    );
    note!(
        "shading error per level, mean/max % of peak (facet kernel exp({}(h·m − 1))) \
         (mean lobes per texel): {}",
        // λ to six decimals (2/α² is rarely a round number in binary).
        (params.fit.shading_exponent() * 1e6).round() / 1e6,
        per_level.join(", ")
    );
    Ok(())
}
