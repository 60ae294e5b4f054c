//! `meso render SCENE.toml -o IMAGE [--spp N] [--width W --height H] [--exposure STOPS]` —
//! render a scene file (docs/scene-format.md) with meso-core materials.

use anyhow::{bail, Context, Result};
use meso_render::{render, RenderOptions, ResolveError, Scene, Shader};
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

/// Time spent extracting NDF pyramids while the scene loads (nanoseconds, all materials).
static PYRAMID_NANOS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
/// Time spent marching the facet horizons of `represent = "facets"` materials (nanoseconds).
static FACETS_NANOS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
/// Time spent summing the NDF-mapped materials' tables (nanoseconds, all materials).
static TABLES_NANOS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// The scene's material resolver: meso material files as `MaterialShader`s, and material
/// files with a `[texture]` table as bump- or NDF-mapped materials
/// ([`meso_render::load_textured`]).
pub fn resolve_material(path: &Path) -> std::result::Result<Arc<dyn Shader>, ResolveError> {
    // NDF-mapped materials extract their height map's pyramid (or read a map file) at load: a
    // progress bar on a terminal, weighted by the work of each level (or bytes read), an
    // extraction's time counted as the `pyramid` phase.
    // The bar appears with the first extraction's first report (with its total), not for
    // materials that extract nothing.
    let bar = Arc::new(std::sync::OnceLock::<indicatif::ProgressBar>::new());
    let shown = bar.clone();
    let st = std::sync::Mutex::new(None::<std::time::Instant>);
    let maps = meso_maps::MapsResolver::new()
        .with_warnings(crate::print_warning())
        .with_progress(Arc::new(move |_, p| {
            use meso_maps::ProgressTask;
            let what = match p.task {
                ProgressTask::Extract => "pyramid",
                ProgressTask::Facets => "facets",
                ProgressTask::Read => "map file",
                ProgressTask::Tables => "tables",
            };
            let b = shown.get_or_init(|| crate::util::progress_work(p.work_total, what));
            if b.prefix() != what {
                // A new phase: its own position and clock from 0 (not the last phase's 100 %).
                b.reset();
                b.set_prefix(what);
            }
            b.set_length(p.work_total);
            b.set_position(p.work_done);
            // Reading a map file is part of the load phase, not timed apart.
            let total = match p.task {
                ProgressTask::Extract => &PYRAMID_NANOS,
                ProgressTask::Facets => &FACETS_NANOS,
                ProgressTask::Tables => &TABLES_NANOS,
                ProgressTask::Read => return,
            };
            let mut s = st.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            if p.work_done == 0 && p.levels_done == 0 && s.is_none() {
                *s = Some(std::time::Instant::now());
            } else if p.work_done >= p.work_total {
                if let Some(t) = s.take() {
                    let ns = u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX);
                    total.fetch_add(ns, std::sync::atomic::Ordering::Relaxed);
                }
            }
        }));
    let result = meso_render::resolve_material_file(path, &maps);
    if let Some(b) = bar.get() {
        b.finish_and_clear();
    }
    result
}

/// Bytes of the rendered image and of encoding it to `outputs` (f32 RGB radiance; per PNG the
/// 8-bit pixels and the encoded file; per EXR two f32 copies).
fn render_bytes(width: u32, height: u32, outputs: &[(PathBuf, Format)]) -> u64 {
    let px = u64::from(width) * u64::from(height);
    let per_px: u64 = 12
        + outputs
            .iter()
            .map(|(_, f)| match f {
                Format::Png => 6,
                Format::Exr => 24,
            })
            .sum::<u64>();
    px.saturating_mul(per_px)
}

/// The image size the scene file asks for (its `[image]` table), read before the scene (and
/// its materials, environment and meshes) is loaded; `None` when the file does not say.
fn scene_image_size(scene: &Path) -> Option<(u32, u32)> {
    let text = crate::util::read_text(scene, meso_render::limits::MAX_SCENE_BYTES).ok()?;
    let t: toml::Table = text.parse().ok()?;
    let img = t.get("image")?.as_table()?;
    let dim = |k: &str| {
        img.get(k)
            .and_then(toml::Value::as_integer)
            .and_then(|v| u32::try_from(v).ok())
    };
    Some((dim("width")?, dim("height")?))
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
    // The image's memory, from the options or the scene's [image] table, before loading.
    let size = match (a.width, a.height) {
        (Some(w), Some(h)) => Some((w, h)),
        (w, h) => scene_image_size(&a.scene).map(|(sw, sh)| (w.unwrap_or(sw), h.unwrap_or(sh))),
    };
    if let Some((w, h)) = size {
        meso_core::budget::check(
            &a.scene,
            &format!("rendering {w}×{h} pixels"),
            render_bytes(w, h, &outputs),
        )?;
    }
    let mut phases = crate::util::Phases::default();
    // The material files the scene loads are inputs too.
    let loaded = std::sync::Mutex::new(Vec::<PathBuf>::new());
    // What each textured material says of how it shades (levels, filter, visibility): printed
    // with the closing line, so that a failed run prints its error alone.
    let described = std::sync::Mutex::new(Vec::<String>::new());
    let resolver = |p: &Path| {
        loaded
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .push(p.to_path_buf());
        let shader = resolve_material(p)?;
        if let Some(d) = shader.describe() {
            described
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push(format!("{}: {d}", p.display()));
        }
        Ok(shader)
    };
    PYRAMID_NANOS.store(0, std::sync::atomic::Ordering::Relaxed);
    FACETS_NANOS.store(0, std::sync::atomic::Ordering::Relaxed);
    TABLES_NANOS.store(0, std::sync::atomic::Ordering::Relaxed);
    let t = std::time::Instant::now();
    let scene = Scene::from_toml_file(&a.scene, &resolver)
        // The scene's errors start with the file they are about (the scene or a file it names).
        .context("cannot load the scene")?;
    let pyramid = PYRAMID_NANOS.load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-9;
    let facets = FACETS_NANOS.load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-9;
    let tables = TABLES_NANOS.load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-9;
    phases.add(
        "load",
        (t.elapsed().as_secs_f64() - pyramid - facets - tables).max(0.0),
    );
    if pyramid > 0.0 {
        phases.add("pyramid", pyramid);
    }
    if facets > 0.0 {
        phases.add("facets", facets);
    }
    if tables > 0.0 {
        phases.add("tables", tables);
    }
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
    meso_core::budget::check(
        &a.scene,
        &format!("rendering {w}×{h} pixels"),
        render_bytes(w, h, &outputs),
    )?;
    let ts = opts.tile_size.max(1);
    let tiles = u64::from(w.div_ceil(ts) * h.div_ceil(ts));
    let spp = u64::from(a.spp.unwrap_or(scene.image.spp));
    // The bar's threshold is in work units: show it for renders of more than ~2000 tile·spp.
    let bar = crate::progress(tiles * spp.max(1), "render");
    let step = spp.max(1);
    let tick = |_: usize, _: usize| bar.inc(step);
    let img = phases.time("render", || render(&scene, &opts, Some(&tick)));
    bar.finish_and_clear();
    // A map file read as the render went (level 0 held by band) that changed meanwhile: the
    // image is not the file's; write nothing.
    scene.check_sources().map_err(|e| anyhow::anyhow!("{e}"))?;
    // Every image is encoded and written to its temporary file before any is put in place: a
    // failure leaves none of them.
    let t = std::time::Instant::now();
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
    phases.add("write", t.elapsed().as_secs_f64());
    for d in described
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
    {
        note!("{d}");
    }
    note!(
        "rendered {}x{} at {} spp in {:.2} s ({:.2} s in all) -> {} ({})",
        img.width(),
        img.height(),
        spp,
        phases.seconds("render"),
        // The load, extraction and tables can take far longer than the render itself.
        phases.total(),
        outputs
            .iter()
            .map(|(p, _)| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        phases.summary()
    );
    Ok(())
}
