//! `meso gonio MATERIAL --pairs PAIRS.csv [--out OUT.csv] [--rays N] [--bounces N]` — the virtual
//! gonioreflectometer: the effective BRDF of a height-map material measured by ray tracing the
//! triangulated height map (docs/heightmaps.md).

use anyhow::{bail, Context, Result};
use meso_core::material::{MaterialSpec, NdfSpec};
use meso_maps::{Gonio, GonioParams, MapsResolver};
use std::path::PathBuf;

/// Measure a height-map material's BRDF by ray tracing its height map (tiled, directional light,
/// orthographic view). Same input and output columns as `meso brdf`.
///
/// The material must have `[ndf] kind = "heightmap"`; its `[transfer]` is the facet BRDF, and its
/// `[diffuse]` albedo, if any, is added as `albedo/π` as `meso brdf` does.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Material file (TOML) with `[ndf] kind = "heightmap"`.
    pub material: PathBuf,
    #[command(flatten)]
    pub table: crate::util::BrdfTable,
    /// Rays per side of the stratified grid: N² rays per direction pair (1–8192).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub rays: u32,
    /// Scattering events per path (1–64; 1 = single bounce; more adds inter-reflection).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub bounces: u32,
    /// Seed of the ray jitter.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    let text = crate::read_text(&a.material, meso_core::material::MAX_MATERIAL_BYTES)?;
    let dir = a
        .material
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .to_path_buf();
    let spec =
        MaterialSpec::parse(&text, &dir).with_context(|| format!("{}", a.material.display()))?;
    let (table, file) = match &spec.ndf {
        NdfSpec::External { kind, table, file } if kind == "heightmap" => (table, file),
        _ => bail!(
            "{}: meso gonio needs a material with [ndf] kind = \"heightmap\" (it ray-traces the heights)",
            a.material.display()
        ),
    };
    if let Some(out) = &a.table.out {
        crate::util::check_outputs(&[out], &[&a.material, &a.table.pairs, file])?;
    }
    let map = MapsResolver::new()
        .with_warnings(crate::print_warning())
        .load_heightmap(table, file)
        .with_context(|| format!("{}", a.material.display()))?;
    let gonio = Gonio::new(&map).with_context(|| format!("{}", file.display()))?;
    let pairs = a.table.read_pairs()?;
    let params = GonioParams {
        rays_per_side: a.rays as usize,
        bounces: a.bounces as usize,
        seed: a.seed,
        ..GonioParams::default()
    };
    let bar = crate::progress(
        if (a.rays as u64).pow(2) * pairs.len() as u64 > 1 << 20 {
            pairs.len() as u64 * 2000
        } else {
            0
        },
        "gonio",
    );
    let diffuse = spec.diffuse;
    let mut values = Vec::with_capacity(pairs.len());
    for p in &pairs {
        // Each measurement is parallel inside (rays), so pairs go one at a time.
        let mut v = gonio.measure(&spec.transfer, p.i, p.o, &params);
        for (c, d) in v.iter_mut().zip(diffuse) {
            *c += d / std::f64::consts::PI;
        }
        values.push(v);
        bar.inc(2000);
    }
    bar.finish_and_clear();
    a.table.write(&pairs, &values)
}
