//! `meso export MAP --out DIR [--alpha A | --roughness-map R] [--base-color C] [--anisotropic]`
//! — engine-ready maps: fitted GGX roughness and normal mip chains as KTX2 (plus a PNG per level)
//! and a glTF 2.0 preview asset (docs/export.md); `--anisotropic` fits anisotropic GGX lobes
//! and writes them as a KHR_materials_anisotropy chain. `--lobes PYRAMID.map` adds the pyramid's lobes as
//! textures with the WGSL and GLSL functions that evaluate them (`meso_export::lobes`).

use anyhow::{bail, Context, Result};
use meso_export::export::{self, Inputs, Roughness};
use meso_export::prepare;
use meso_maps::{Border, HeightMap, NormalConvention};
use std::path::PathBuf;

/// `--alpha`'s default: the base GGX width of a map export (a material file gives its own).
const DEFAULT_ALPHA: f64 = 0.1;

/// Green-channel convention of the input normal map.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Convention {
    /// OpenGL / glTF: green is +y (up in the image).
    Gl,
    /// DirectX: green is −y.
    Dx,
}

/// Export a normal map (or height map) and its roughness as engine-ready textures; or a material
/// file (`.toml`, e.g. one `meso fit` wrote) as its engine parameters: the best single GGX +
/// Lambert of its BRDF as glTF metallic–roughness, on a flat map.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Tangent-space normal map (RGB) or, with --texel-size and --height-scale, a height map; or
    /// a material file (`.toml`): its engine parameters (GGX α, metallic, base colour) fitted to
    /// its BRDF as `meso fit` reports them, exported as a uniform material (no other option
    /// applies).
    pub map: PathBuf,
    /// Output folder (created; every file written atomically, all or nothing).
    #[arg(long, short)]
    pub out: PathBuf,
    /// The input is a height map: distance between samples S (length units, > 0).
    #[arg(long, requires = "height_scale")]
    pub texel_size: Option<f64>,
    /// The input is a height map: height of the full code range H (same unit, > 0).
    #[arg(long, requires = "texel_size")]
    pub height_scale: Option<f64>,
    /// Green-channel convention of a normal-map input [default: gl].
    #[arg(long, value_enum)]
    pub convention: Option<Convention>,
    /// Constant base GGX width α in (0, 1] (glTF roughness is √α) [default: 0.1].
    #[arg(long, conflicts_with = "roughness_map")]
    pub alpha: Option<f64>,
    /// Per-texel roughness image holding glTF perceptual roughness r (α = r²): grey, or a
    /// metallicRoughness image (G is used). Same size as the map.
    #[arg(long)]
    pub roughness_map: Option<PathBuf>,
    /// Metallic value written to the B channel, in [0, 1] [default: 0].
    #[arg(long)]
    pub metallic: Option<f64>,
    /// Base colour image (sRGB) for the glTF material; a constant grey without it.
    #[arg(long)]
    pub base_color: Option<PathBuf>,
    /// Fit anisotropic GGX lobes (α_t, α_b and the direction of α_t per texel) instead of one
    /// α, and write them the KHR_materials_anisotropy way: metallicRoughness G = √α_b,
    /// `anisotropy.ktx2` / `anisotropy_mip<k>.png` with RG = direction, B = strength, and the
    /// extension in scene.gltf (docs/export.md). The lobes assume an anisotropy frame
    /// orthogonal to the normal-mapped normal; three.js r187 builds it from the geometric
    /// tangents and loses the normal map's tilt (docs/engine.md): there, use the isotropic export.
    #[arg(long)]
    pub anisotropic: bool,
    /// A lobe pyramid (`.map` file of `meso extract`) of the same map: also write its lobes
    /// as `lobes<k>_mip<l>.png` (RGBA16, one per lobe slot and level) and the shader functions
    /// `meso_lobes.wgsl` and `meso_lobes.glsl` that evaluate them (docs/export.md). Lobe level
    /// l must be mip level l: the pyramid of a wrapped extraction (no --clamp) of a map whose
    /// sizes halve evenly (e.g. powers of two); others are refused before the fit.
    #[arg(long)]
    pub lobes: Option<PathBuf>,
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    prepare::check_out_dir(&a.out)?;
    let inputs = if prepare::is_material_file(&a.map) {
        material_inputs(&a)?
    } else {
        maps_inputs(&a)?
    };
    export_inputs(&a, &inputs)
}

/// The map options given with `a` (by their flags), which a material file refuses.
fn given_map_options(a: &Args) -> Vec<&'static str> {
    [
        ("--texel-size", a.texel_size.is_some()),
        ("--height-scale", a.height_scale.is_some()),
        ("--convention", a.convention.is_some()),
        ("--alpha", a.alpha.is_some()),
        ("--roughness-map", a.roughness_map.is_some()),
        ("--metallic", a.metallic.is_some()),
        ("--base-color", a.base_color.is_some()),
        ("--anisotropic", a.anisotropic),
        ("--lobes", a.lobes.is_some()),
    ]
    .into_iter()
    .filter_map(|(name, given)| given.then_some(name))
    .collect()
}

/// The inputs of a material file's export: its engine parameters on a flat map
/// ([`prepare::material_inputs`]); every map option refused.
fn material_inputs(a: &Args) -> Result<Inputs> {
    prepare::refuse_material_options(&a.map, &given_map_options(a))?;
    // The engine fit evaluates the material's BRDF at 50 000 MERL cells: seconds for a closed
    // form, minutes for a quadrature per evaluation (a tilted Phong-peaks NDF, say).
    let bar = crate::progress(
        meso_measured::engine::ENGINE_CELLS,
        "engine fit: BRDF at MERL cells",
    );
    let result = prepare::material_inputs_with(&a.map, &|done, _| bar.set_position(done));
    bar.finish_and_clear();
    let (inputs, line) = result?;
    eprintln!("{line}");
    Ok(inputs)
}

/// The inputs of a normal-map or height-map export, with the roughness map and base colour.
fn maps_inputs(a: &Args) -> Result<Inputs> {
    prepare::check_export(
        &a.map,
        a.texel_size.is_some(),
        a.roughness_map.as_deref(),
        a.base_color.as_deref(),
        a.anisotropic,
        a.lobes.as_deref(),
    )?;
    if a.texel_size.is_some() && a.convention == Some(Convention::Dx) {
        bail!(
            "{}: --convention applies to a normal-map input; a height map has no green channel to \
             read (the exported normal map is always OpenGL / glTF: green = +Y = up)",
            a.map.display()
        );
    }
    let alpha = a.alpha.unwrap_or(DEFAULT_ALPHA);
    let mut inputs = match (a.texel_size, a.height_scale) {
        (Some(s), Some(h)) => {
            let map = HeightMap::load(&a.map, s, h, Border::Wrap)?;
            for w in map.warnings() {
                eprintln!("{}: warning: {w}", a.map.display());
            }
            Inputs::from_heightmap(&map, alpha)
        }
        (None, None) => {
            let conv = match a.convention.unwrap_or(Convention::Gl) {
                Convention::Gl => NormalConvention::Gl,
                Convention::Dx => NormalConvention::Dx,
            };
            let map = prepare::load_normal_map(&a.map, conv)?;
            for w in map.warnings() {
                eprintln!("{}: warning: {w}", a.map.display());
            }
            Inputs::from_normal_map(&map, alpha)
        }
        _ => bail!("a height map needs both --texel-size and --height-scale"),
    };
    if let Some(r) = &a.roughness_map {
        let (alphas, warnings) = export::load_roughness(r, inputs.width, inputs.height)?;
        for w in warnings {
            eprintln!("warning: {w}");
        }
        inputs.roughness = Roughness::Map(alphas);
    }
    if let Some(c) = &a.base_color {
        let (bc, warnings) = export::load_base_color(c)?;
        for w in warnings {
            eprintln!("warning: {w}");
        }
        inputs.base_color = Some(bc);
    }
    inputs.metallic = a.metallic.unwrap_or(0.0);
    inputs.anisotropic = a.anisotropic;
    Ok(inputs)
}

/// Build the export of `inputs` (and the lobe textures of `--lobes`), write it, print the levels.
fn export_inputs(a: &Args, inputs: &Inputs) -> Result<()> {
    // The lobe pyramid is read, checked and packed before the (slow) fit: a bad map file fails
    // at once, and only its encoded textures are held while fitting.
    let lobes = a
        .lobes
        .as_ref()
        .map(|p| prepare::lobe_files(p, inputs.width, inputs.height))
        .transpose()?;
    let mut ex = export::build(inputs).with_context(|| a.map.display().to_string())?;
    if let Some((files, line)) = lobes {
        ex.files.extend(files);
        eprintln!("{line}");
    }
    let inputs: Vec<&std::path::Path> = [
        Some(&a.map),
        a.base_color.as_ref(),
        a.roughness_map.as_ref(),
        a.lobes.as_ref(),
    ]
    .into_iter()
    .flatten()
    .map(std::path::PathBuf::as_path)
    .collect();
    let files = export::write(&ex, &a.out, &inputs)?;
    if let Some(w) = export::stale_warning(&ex, &a.out) {
        eprintln!("{}: warning: {w}", a.out.display());
    }
    use std::fmt::Write as _;
    let mut table = String::new();
    if a.anisotropic {
        writeln!(
            table,
            "level  size        mean α_b  mean α_t  strength   aniso fit error % (mean / max)   \
             iso fit %   standard mip %"
        )
        .ok();
    } else {
        writeln!(
            table,
            "level  size        mean α   fit error % of peak (mean / max)   standard mip %"
        )
        .ok();
    }
    for s in &ex.stats {
        if let Some(an) = &s.aniso {
            writeln!(
                table,
                "{:>5}  {:>4} × {:<4}  {:.4}    {:.4}    {:.4}    {:>8.3} / {:<8.3}              \
                 {:>8.3}    {:>8.3}",
                s.level,
                s.width,
                s.height,
                s.mean_alpha,
                an.mean_alpha_t,
                an.mean_strength,
                s.mean_error_pct,
                s.max_error_pct,
                an.mean_iso_error_pct,
                s.mean_plain_error_pct
            )
            .ok();
        } else {
            writeln!(
                table,
                "{:>5}  {:>4} × {:<4}  {:.4}   {:>8.3} / {:<8.3}                {:>8.3}",
                s.level,
                s.width,
                s.height,
                s.mean_alpha,
                s.mean_error_pct,
                s.max_error_pct,
                s.mean_plain_error_pct
            )
            .ok();
        }
    }
    crate::util::print_stdout(&table)?;
    eprintln!("{}: {} files", a.out.display(), files.len());
    Ok(())
}
