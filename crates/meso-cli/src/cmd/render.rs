//! `meso render SCENE.toml -o IMAGE [--spp N] [--width W --height H] [--exposure STOPS]` —
//! render a scene file (docs/scene-format.md) with meso-core materials.

use anyhow::{bail, Context, Result};
use meso_render::{render, MaterialShader, RenderOptions, ResolveError, Scene, Shader};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Render a scene file.
///
/// Materials referenced by the scene (`material = "x.toml"`, relative to the scene file) are
/// meso material files (docs/material-format.md), including height-map NDFs. The output format
/// follows the extension: `.exr` holds linear radiance (W/(m²·sr), f32 RGB), `.png` tone-mapped
/// sRGB (exposure, clamp, sRGB transfer). Nothing is written when anything fails.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output image, `.exr` or `.png`.
    #[arg(long, short)]
    pub out: PathBuf,
    /// A second output image (e.g. the PNG next to the EXR).
    #[arg(long)]
    pub also: Option<PathBuf>,
    /// Samples per pixel (overrides the scene's `image.spp`; 1..=65536).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Image width in pixels (overrides the scene).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (overrides the scene).
    #[arg(long)]
    pub height: Option<u32>,
    /// PNG exposure in stops (radiance × 2^STOPS before the sRGB transfer).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Seed of the sample scrambling.
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Exr,
    Png,
}

fn format_of(path: &Path) -> Result<Format> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("exr") => Ok(Format::Exr),
        Some("png") => Ok(Format::Png),
        _ => bail!(
            "{}: unknown image format (use a .exr or .png extension)",
            path.display()
        ),
    }
}

/// The scene's material resolver: meso material files as [`MaterialShader`]s, and material
/// files with a `[texture]` table as bump- or NDF-mapped materials
/// ([`meso_render::load_textured`]).
pub fn resolve_material(path: &Path) -> std::result::Result<Arc<dyn Shader>, ResolveError> {
    // NDF-mapped materials extract their height map's pyramid at load: a progress bar on a
    // terminal for the big ones.
    let bar = crate::progress(u64::MAX, "pyramid");
    let shown = bar.clone();
    let maps = meso_maps::MapsResolver::new().with_progress(Arc::new(move |_, p| {
        shown.set_length(p.texels_total);
        shown.set_position(p.texels_done);
    }));
    let textured = meso_render::load_textured(path, &maps);
    bar.finish_and_clear();
    if let Some(s) = textured? {
        return Ok(s);
    }
    let m = crate::load_material(path).map_err(|e| -> ResolveError { format!("{e:#}").into() })?;
    Ok(Arc::new(MaterialShader::new(&m)))
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    let mut outputs = vec![(a.out.clone(), format_of(&a.out)?)];
    if let Some(p) = &a.also {
        outputs.push((p.clone(), format_of(p)?));
    }
    for (name, v) in [("--width", a.width), ("--height", a.height)] {
        if let Some(v) = v {
            if !(1..=16384).contains(&v) {
                bail!("{name} must be in 1..=16384 pixels, got {v}");
            }
        }
    }
    if let Some(s) = a.spp {
        if !(1..=65536).contains(&s) {
            bail!("--spp must be in 1..=65536, got {s}");
        }
    }
    if !a.exposure.is_finite() {
        bail!("--exposure must be a finite number of stops");
    }
    let out_paths: Vec<&Path> = outputs.iter().map(|(p, _)| p.as_path()).collect();
    crate::util::check_outputs(&out_paths, &[&a.scene])?;
    // The material files the scene loads are inputs too.
    let loaded = std::sync::Mutex::new(Vec::<PathBuf>::new());
    let resolver = |p: &Path| {
        loaded
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .push(p.to_path_buf());
        resolve_material(p)
    };
    let scene = Scene::from_toml_file(&a.scene, &resolver)
        .with_context(|| format!("cannot load the scene {}", a.scene.display()))?;
    let loaded = loaded
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut inputs: Vec<&Path> = vec![&a.scene];
    inputs.extend(loaded.iter().map(PathBuf::as_path));
    crate::util::check_outputs(&out_paths, &inputs)?;
    let opts = RenderOptions {
        width: a.width,
        height: a.height,
        spp: a.spp,
        seed: a.seed,
        ..RenderOptions::default()
    };
    let w = a.width.unwrap_or(scene.image.width);
    let h = a.height.unwrap_or(scene.image.height);
    let ts = opts.tile_size.max(1);
    let tiles = u64::from(w.div_ceil(ts) * h.div_ceil(ts));
    let spp = u64::from(a.spp.unwrap_or(scene.image.spp));
    // The bar's threshold is in work units: show it for renders of more than ~2000 tile·spp.
    let bar = crate::progress(tiles * spp.max(1), "render");
    let step = spp.max(1);
    let tick = |_: usize, _: usize| bar.inc(step);
    let t = std::time::Instant::now();
    let img = render(&scene, &opts, Some(&tick));
    bar.finish_and_clear();
    let secs = t.elapsed().as_secs_f64();
    // Every image is encoded and written to its temporary file before any is put in place: a
    // failure leaves none of them.
    let mut staged = Vec::new();
    for (path, f) in &outputs {
        let bytes = match f {
            Format::Exr => img.encode_exr(),
            Format::Png => img.encode_png(a.exposure),
        }
        .with_context(|| format!("{}: cannot encode the image", path.display()))?;
        staged.push(
            meso_core::io::stage_with(path, |w| w.write_all(&bytes))
                .with_context(|| format!("{}: cannot write", path.display()))?,
        );
    }
    meso_core::io::commit_all(staged)?;
    note!(
        "rendered {}x{} at {} spp in {:.2} s -> {}",
        img.width(),
        img.height(),
        spp,
        secs,
        outputs
            .iter()
            .map(|(p, _)| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
