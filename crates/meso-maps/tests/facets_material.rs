//! `[ndf] kind = "heightmap"` with `represent = "facets"` (every facet normal, binned, as a delta
//! sum) against the virtual gonioreflectometer (`Gonio`: brute-force ray tracing of the
//! triangulated map with exact masking and shadowing), next to the default fitted lobes, for
//! Phong (N·H, η = 20) facets on maps whose normals four lobes cannot follow (slopes up to 45°).
//! `FACETS_DEBUG=1` prints every pair.

use glam::DVec3;
use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;
use meso_maps::{Border, Gonio, GonioParams, HeightMap, MapsResolver};
use std::path::Path;

/// Heights over one period, `(x, y) ∈ [0, 1)²`, in units of the height scale.
type HeightFn = Box<dyn Fn(f64, f64) -> f64>;

/// Height samples `h(x, y)` on an `n × n` grid of one period, written as a float EXR.
fn write_map(dir: &Path, name: &str, n: usize, h: impl Fn(f64, f64) -> f64) {
    let values: Vec<f32> = (0..n * n)
        .map(|k| h((k % n) as f64 / n as f64, (k / n) as f64 / n as f64) as f32)
        .collect();
    std::fs::write(
        dir.join(name),
        meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap(),
    )
    .unwrap();
}

fn material(dir: &Path, name: &str, represent: &str) -> Material {
    let text = format!(
        "[ndf]\nkind = \"heightmap\"\nfile = \"{name}\"\ntexel_size = 0.015625\n\
         height_scale = 0.08\nrepresent = \"{represent}\"\n\
         [transfer]\nkind = \"phong\"\nexponent = 20.0\n[shadowing]\nkind = \"horizon\"\n"
    );
    let p = dir.join(format!("{name}.{represent}.toml"));
    std::fs::write(&p, text).unwrap();
    Material::from_file(&p, &MapsResolver::new()).unwrap()
}

/// Six view/light pairs, normal incidence to 60°, several azimuths.
fn pairs() -> [(DVec3, DVec3); 6] {
    let d = spherical_direction_deg;
    [
        (d(0.0, 0.0), d(0.0, 0.0)),
        (d(30.0, 0.0), d(30.0, 180.0)),
        (d(40.0, 0.0), d(10.0, 0.0)),
        (d(45.0, 90.0), d(20.0, 270.0)),
        (d(60.0, 30.0), d(30.0, 200.0)),
        (d(20.0, 0.0), d(50.0, 150.0)),
    ]
}

/// Mean over the pairs of `|f − gonio| / max_pairs(gonio)`, red channel.
fn error_vs_gonio(m: &Material, g: &Gonio, pairs: &[(DVec3, DVec3)]) -> f64 {
    let params = GonioParams {
        rays_per_side: 192,
        ..GonioParams::default()
    };
    let truth: Vec<f64> = pairs
        .iter()
        .map(|&(i, o)| g.measure(&m.transfer, i, o, &params)[0])
        .collect();
    let peak = truth.iter().cloned().fold(0.0, f64::max);
    if std::env::var_os("FACETS_DEBUG").is_some() {
        for (&(i, o), t) in pairs.iter().zip(&truth) {
            eprintln!(
                "  i {i:.3} o {o:.3}: material {:.4}, gonio {t:.4}",
                m.brdf(i, o)[0]
            );
        }
    }
    pairs
        .iter()
        .zip(&truth)
        .map(|(&(i, o), t)| (m.brdf(i, o)[0] - t).abs() / peak)
        .sum::<f64>()
        / pairs.len() as f64
}

#[test]
fn facets_follow_the_ray_traced_surface_closer_than_lobes() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("facets_material");
    std::fs::create_dir_all(&dir).unwrap();
    let n = 64;
    let pi = std::f64::consts::PI;
    // Half-cylinders along y (4 per tile) and a woven pattern: multi-modal NDFs.
    let maps: Vec<(&str, HeightFn)> = vec![
        (
            "cylinders.exr",
            Box::new(move |x: f64, _y: f64| (pi * (4.0 * x).fract()).sin()),
        ),
        (
            "woven.exr",
            Box::new(move |x: f64, y: f64| {
                let (a, b) = ((2.0 * pi * 4.0 * x).sin(), (2.0 * pi * 4.0 * y).sin());
                if ((4.0 * x).fract() < 0.5) == ((4.0 * y).fract() < 0.5) {
                    a.abs()
                } else {
                    b.abs()
                }
            }),
        ),
    ];
    let pairs = pairs();
    for (name, h) in &maps {
        write_map(&dir, name, n, h);
        // The surface the materials see: the file as loaded (rows up the image).
        let map = HeightMap::load(&dir.join(name), 1.0 / n as f64, 0.08, Border::Wrap).unwrap();
        let g = Gonio::new(&map).unwrap();
        let lobes = error_vs_gonio(&material(&dir, name, "lobes"), &g, &pairs);
        let facets = error_vs_gonio(&material(&dir, name, "facets"), &g, &pairs);
        eprintln!("{name}: mean |f − gonio| / peak: lobes {lobes:.4}, facets {facets:.4}");
        // Measured: cylinders lobes 0.021, facets 0.006; woven (cliffs between the patches)
        // lobes 0.71, facets 0.068 — what is left with the facets is the horizon model of
        // masking and shadowing against the exact ray tracing.
        assert!(facets < 0.1, "{name}: facets {facets}");
        assert!(facets <= lobes, "{name}: facets {facets} vs lobes {lobes}");
    }
}

/// On a Gaussian random surface (the usual test microgeometry: unimodal slopes) the default
/// fitted lobes are already close to the ray-traced BRDF, and the facets closer still.
#[test]
fn gaussian_surface_lobes_and_facets_against_the_gonioreflectometer() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("facets_material_gaussian");
    std::fs::create_dir_all(&dir).unwrap();
    let n = 64;
    // RMS height 0.012 over a 3-texel correlation length of 1/64: RMS slope ≈ 0.35 (19°).
    let map = meso_maps::fixtures::gaussian(n, 3.0, 0.012, 7, 1.0 / n as f64).unwrap();
    let (lo, hi) = map.range();
    let values: Vec<f32> = map
        .heights()
        .iter()
        .map(|h| ((h - lo) / (hi - lo)) as f32)
        .collect();
    std::fs::write(
        dir.join("gauss.exr"),
        meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap(),
    )
    .unwrap();
    let material = |represent: &str| {
        let p = dir.join(format!("gauss.{represent}.toml"));
        std::fs::write(
            &p,
            format!(
                "[ndf]\nkind = \"heightmap\"\nfile = \"gauss.exr\"\ntexel_size = 0.015625\n\
                 height_scale = {}\nrepresent = \"{represent}\"\n\
                 [transfer]\nkind = \"phong\"\nexponent = 20.0\n[shadowing]\nkind = \"horizon\"\n",
                hi - lo
            ),
        )
        .unwrap();
        Material::from_file(&p, &MapsResolver::new()).unwrap()
    };
    let pairs = pairs();
    let map = HeightMap::load(
        &dir.join("gauss.exr"),
        1.0 / n as f64,
        hi - lo,
        Border::Wrap,
    )
    .unwrap();
    let g = Gonio::new(&map).unwrap();
    let lobes = error_vs_gonio(&material("lobes"), &g, &pairs);
    let facets = error_vs_gonio(&material("facets"), &g, &pairs);
    eprintln!("gaussian: mean |f − gonio| / peak: lobes {lobes:.4}, facets {facets:.4}");
    assert!(
        lobes < 0.1 && facets < 0.05,
        "lobes {lobes}, facets {facets}"
    );
    assert!(facets <= lobes, "facets {facets} vs lobes {lobes}");
}
