//! Materials in the renderer against independent truth: the core's effective BRDF, Eq. 4,
//! Monte Carlo convergence, and the NDF-mapped material against the supersampled bump map.

use glam::{DVec2, DVec3};
use meso_core::material::Material;
use meso_maps::{extract, Border, ExtractParams, HeightMap, Source};
use meso_render::sampling::PixelSampler;
use meso_render::*;
use std::sync::Arc;

mod common;
use common::render_plane;

/// The light of the plane scenes (towards the light).
const LIGHT: DVec3 = DVec3::new(-0.5, 0.3, 0.8);

fn ortho_sphere_scene(shader: Arc<dyn Shader>, size: u32, spp: u32, light: Light) -> Scene {
    let cam = Camera::new(
        Projection::Orthographic { width: 2.5 },
        DVec3::new(0.0, 0.0, 5.0),
        DVec3::ZERO,
        DVec3::Y,
    )
    .unwrap();
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            width: size,
            height: size,
            spp,
            background: [0.0; 3],
        },
    );
    let m = b.material(shader);
    b.sphere(DVec3::ZERO, 1.0, DVec3::Y, m).unwrap();
    b.light(light).unwrap();
    b.build().unwrap()
}

const SINGLE_LOBE: &str = r#"
[ndf]
kind = "phong-peaks"
lobes = [ { axis = [25.0, 40.0], weight = 1.0, exponent = 80.0 } ]
[transfer]
kind = "phong"
exponent = 30.0
specular = [1.0, 0.7, 0.4]
[diffuse]
albedo = [0.1, 0.2, 0.3]
"#;

/// The radiance the renderer computes at pixel centres equals `Material::brdf` (the core's
/// Eq. 2 quadrature) × irradiance × cos θi at the same local directions, within 2% (FastBrdf's
/// Phong-peak node kernel is documented < 1% on the BRDF, plus f32 rounding).
#[test]
fn single_lobe_matches_core_brdf() {
    let mat = Material::from_toml_str(SINGLE_LOBE).unwrap();
    let l = DVec3::new(0.3, 0.4, 0.866).normalize();
    let e = 1.5;
    let scene = ortho_sphere_scene(
        Arc::new(MaterialShader::new(&mat)),
        24,
        1,
        Light::Directional {
            direction: l,
            irradiance: DVec3::splat(e),
        },
    );
    let mut checked = 0;
    let mut worst = 0.0f64;
    for y in 0..24 {
        for x in 0..24 {
            let rd = scene
                .camera
                .generate_ray(f64::from(x) + 0.5, f64::from(y) + 0.5, 24, 24);
            let Some(sp) = scene.intersect(&rd) else {
                continue;
            };
            let wo = -rd.ray.d;
            let got = shade(&scene, &sp, wo, &PixelSampler::new(x, y, 0, 0));
            let (il, ol) = (sp.frame.to_local(l), sp.frame.to_local(wo));
            let f = mat.brdf(il, ol);
            let c = il.z.max(0.0) * e;
            let want = DVec3::new(f[0] * c, f[1] * c, f[2] * c);
            for k in 0..3 {
                let err = (got[k] - want[k]).abs() / (want[k].abs() + 0.02);
                worst = worst.max(err);
            }
            checked += 1;
        }
    }
    assert!(checked > 200, "{checked} pixels on the sphere");
    assert!(worst < 0.02, "worst relative error {worst}");
}

fn deltas(lobes: &[(f64, f64, f64)]) -> Material {
    let mut s = String::from("[ndf]\nkind = \"deltas\"\nlobes = [\n");
    for (t, p, w) in lobes {
        s.push_str(&format!("  {{ axis = [{t}, {p}], weight = {w} }},\n"));
    }
    s.push_str("]\n[transfer]\nkind = \"phong\"\nexponent = 40.0\nspecular = [1.0, 0.9, 0.8]\n");
    Material::from_toml_str(&s).unwrap()
}

/// Eq. 4: the render of a multiple surface is the weighted sum of the renders of its
/// single-normal surfaces (same samples).
#[test]
fn multiple_surface_is_weighted_sum_of_single_normals() {
    let lobes = [(0.0, 0.0, 0.5), (30.0, 90.0, 0.3), (20.0, 200.0, 0.2)];
    let light = Light::Point {
        position: DVec3::new(2.0, 3.0, 4.0),
        intensity: DVec3::splat(20.0),
    };
    let opts = RenderOptions::default();
    let multi = render(
        &ortho_sphere_scene(Arc::new(MaterialShader::new(&deltas(&lobes))), 32, 2, light),
        &opts,
        None,
    );
    let mut sum = vec![[0.0f64; 3]; 32 * 32];
    for &(t, p, w) in &lobes {
        let img = render(
            &ortho_sphere_scene(
                Arc::new(MaterialShader::new(&deltas(&[(t, p, 1.0)]))),
                32,
                2,
                light,
            ),
            &opts,
            None,
        );
        for (s, px) in sum.iter_mut().zip(img.pixels()) {
            for c in 0..3 {
                s[c] += w * f64::from(px[c]);
            }
        }
    }
    let mut max_err = 0.0f64;
    let mut peak = 0.0f64;
    for (a, b) in multi.pixels().iter().zip(&sum) {
        for c in 0..3 {
            max_err = max_err.max((f64::from(a[c]) - b[c]).abs());
            peak = peak.max(b[c]);
        }
    }
    assert!(peak > 0.1, "the test image is lit (peak {peak})");
    assert!(max_err < 1e-4 * peak.max(1.0), "max error {max_err}");
}

fn rms(a: &Image, b: &Image) -> f64 {
    let n = a.pixels().len() as f64;
    (a.pixels()
        .iter()
        .zip(b.pixels())
        .map(|(p, q)| (0..3).map(|c| f64::from(p[c] - q[c]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / (3.0 * n))
        .sqrt()
}

/// Under a spherical area light the error against a high-spp reference falls at least like
/// 1/√spp (rendered with a different scrambling seed than the reference).
#[test]
fn area_light_converges() {
    let mat = deltas(&[(0.0, 0.0, 0.6), (35.0, 0.0, 0.4)]);
    let light = Light::Sphere {
        center: DVec3::new(1.5, 2.0, 2.5),
        radius: 1.0,
        radiance: DVec3::splat(3.0),
    };
    let scene = ortho_sphere_scene(Arc::new(MaterialShader::new(&mat)), 20, 1, light);
    let reference = render(
        &scene,
        &RenderOptions {
            spp: Some(4096),
            seed: 99,
            ..RenderOptions::default()
        },
        None,
    );
    let errs: Vec<f64> = [4u32, 16, 64, 256]
        .iter()
        .map(|&spp| {
            rms(
                &render(
                    &scene,
                    &RenderOptions {
                        spp: Some(spp),
                        seed: 1,
                        ..RenderOptions::default()
                    },
                    None,
                ),
                &reference,
            )
        })
        .collect();
    assert!(
        errs[0] > 1e-4,
        "the light is soft enough to leave noise: {errs:?}"
    );
    for w in errs.windows(2) {
        // 4× the samples: 1/√spp predicts a factor 2.
        assert!(w[1] < w[0] / 1.7, "errors {errs:?}");
    }
}

/// An egg-crate bump map (period 8 texels, slopes up to ~40°), tileable, texel 1/32.
fn egg_crate() -> HeightMap {
    let tau = std::f64::consts::TAU;
    let p = 8.0 / 32.0;
    HeightMap::from_fn(32, 32, 1.0 / 32.0, Border::Wrap, |x, y| {
        0.035 * (tau * x / p).sin() * (tau * y / p).sin()
    })
    .unwrap()
}

/// Mean relative error `Σ|a − b| / Σ b` over all pixels and channels.
fn mean_rel(a: &Image, b: &Image) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (p, q) in a.pixels().iter().zip(b.pixels()) {
        for c in 0..3 {
            num += f64::from((p[c] - q[c]).abs());
            den += f64::from(q[c]);
        }
    }
    num / den
}

const SURFACE: &str = r#"
[transfer]
kind = "phong"
exponent = 20.0
specular = [0.6, 0.6, 0.6]
[diffuse]
albedo = [0.5, 0.4, 0.3]
"#;

/// The NDF-mapped render (4 spp) of a bump map against the bump-mapped render supersampled
/// at 1024 spp, at footprints of 4, 16, 64 and 256 cells per pixel (one map tile per world
/// unit, 32 cells): mean relative image error below 3% at every zoom level (measured 1.4%,
/// 1.2%, 1.4% and 1.6%; with whole-pixel footprints for each of the 4 samples 4.0% at 4 cells
/// per pixel, and with the pyramid's EM-only lobe fits 4.3%, 4.4%, 2.4% and 2.5%; the
/// closed-form evaluation agrees with a fine quadrature of the fitted lobes within about 1%;
/// see docs/figures.md).
#[test]
fn ndf_mapped_matches_supersampled_bump_map() {
    let map = egg_crate();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let surface = Material::from_toml_str(SURFACE).unwrap();
    let tpu = 32.0;
    let bump: Arc<dyn Shader> = Arc::new(BumpMapped::new(&map, &surface, tpu, false).unwrap());
    // The whole pixel's footprint at every sample: with 4 jittered samples this is more
    // accurate here than `with_samples_per_pixel(4)` (8.5% at 4 cells per pixel).
    let ndf: Arc<dyn Shader> = Arc::new(NdfMapped::new(&pyr, &surface, tpu, false).unwrap());
    let size = 24u32;
    let mut errors = Vec::new();
    for cells_per_pixel in [4.0, 16.0, 64.0, 256.0] {
        let width = cells_per_pixel * f64::from(size) / tpu;
        let truth = render_plane(bump.clone(), width, size, LIGHT, 1024);
        let filtered = render_plane(ndf.clone(), width, size, LIGHT, 4);
        errors.push(mean_rel(&filtered, &truth));
    }
    eprintln!("mean relative errors at 4, 16, 64, 256 cells/pixel: {errors:?}");
    // Measured 1.4%, 1.2%, 1.4%, 1.6% (1.1% at 4 cells per pixel before each lobe's share of
    // projected area came from the level-0 normals, see mapped.rs "Steep maps"; 4.0% before
    // the renderer fitted each of the 4 samples' footprints to its quarter of the pixel).
    for (e, bound) in errors.iter().zip([0.03, 0.03, 0.03, 0.03]) {
        assert!(*e < bound, "errors {errors:?}");
    }
}

/// Zooming is smooth: over four octaves of footprint (1 to 40 cells per pixel, widths 10%
/// apart), the mean radiance of the NDF-mapped plane (4 spp, shadowed) follows that of the
/// bump-mapped plane (64 spp): their ratio moves by less than 2% between neighbouring widths
/// (no pop between levels; measured at most 1.6%) and stays within 7% of 1 (measured
/// 0.978–1.056: the lobe fits of the middle levels). The mean itself is not a constant: at
/// the first widths the view holds about one tile, and the true mean changes by up to 2%
/// between widths.
#[test]
fn ndf_mapped_zoom_is_smooth() {
    let map = egg_crate();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let surface = Material::from_toml_str(SURFACE).unwrap();
    let ndf = Arc::new(NdfMapped::new(&pyr, &surface, 32.0, true).unwrap());
    let bump = Arc::new(BumpMapped::new(&map, &surface, 32.0, true).unwrap());
    let mean = |shader: Arc<dyn Shader>, width: f64, spp: u32| -> f64 {
        let img = render_plane(shader, width, 32, LIGHT, spp);
        img.pixels()
            .iter()
            .map(|p| f64::from(p[0] + p[1] + p[2]))
            .sum::<f64>()
            / img.pixels().len() as f64
    };
    let mut prev: Option<f64> = None;
    let mut ratios = Vec::new();
    let mut width = 1.0;
    while width < 40.0 {
        let ratio = mean(ndf.clone(), width, 4) / mean(bump.clone(), width, 64);
        ratios.push(ratio);
        if let Some(p) = prev {
            assert!(
                (ratio - p).abs() < 0.02,
                "jump at width {width}: ratios {ratios:?}"
            );
        }
        // Measured 0.995–1.014 (0.978–1.055 with EM-only lobe fits).
        assert!((ratio - 1.0).abs() < 0.03, "ratios {ratios:?}");
        prev = Some(ratio);
        width *= 1.1;
    }
    eprintln!("NDF-mapped / bump-mapped mean radiance: {ratios:?}");
}

/// Magnified with `with_sharp_magnification`, a point of the NDF-mapped material shades as
/// the mean of the bump map's two triangles of the cell under it (level 0 holds their normals
/// as sharp lobes, each with half the cell's projected area), within 0.5%.
#[test]
fn ndf_mapped_sharp_magnification_reads_the_cell() {
    let map = egg_crate();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let surface = Material::from_toml_str(SURFACE).unwrap();
    let tpu = 32.0;
    let bump = BumpMapped::new(&map, &surface, tpu, false).unwrap();
    let ndf = NdfMapped::new(&pyr, &surface, tpu, false)
        .unwrap()
        .with_sharp_magnification(true);
    let wo = DVec3::new(0.1, -0.4, 0.9).normalize();
    let wi = DVec3::new(-0.5, 0.3, 0.8).normalize();
    let mut worst = 0.0f64;
    for k in 0..40 {
        // Cell (i, j) and a point inside it.
        let (j, i) = ((k * 7) % 32, (k * 13) % 32);
        let (fx, fy) = (0.3 + 0.01 * f64::from(k % 5), 0.6);
        // Map point (x, y) in cells (y up the image, the map's 32 rows) → uv (v down it).
        let at = |x: f64, y: f64| {
            let mut sp = materials_point(DVec2::new(x / tpu, (32.0 - y) / tpu));
            // A footprint of a tenth of a cell: the single cell.
            sp.duvdx = DVec2::new(0.1 / tpu, 0.0);
            sp.duvdy = DVec2::new(0.0, 0.1 / tpu);
            sp
        };
        let p = at(f64::from(j) + fx, f64::from(i) + fy);
        let got = ndf.eval(&p, wi, wo);
        // Triangle A (y − y_i < x − x_j) and triangle B of the same cell.
        let a = bump.eval(&at(f64::from(j) + 0.7, f64::from(i) + 0.2), wi, wo);
        let b = bump.eval(&at(f64::from(j) + 0.2, f64::from(i) + 0.7), wi, wo);
        for c in 0..3 {
            let want = 0.5 * (a[c] + b[c]);
            worst = worst.max(f64::from((got[c] - want).abs() / want));
        }
    }
    assert!(worst < 0.005, "worst relative error {worst}");
}

/// A shading point on the plane `z = 0` at texture coordinates `uv` (local frame = world).
fn materials_point(uv: DVec2) -> ShadingPoint {
    ShadingPoint {
        position: DVec3::new(uv.x, uv.y, 0.0),
        geometric_normal: DVec3::Z,
        frame: meso_core::frame::Frame::from_normal_tangent(DVec3::Z, DVec3::X),
        uv,
        dpdu: DVec3::X,
        dpdv: DVec3::Y,
        dpdx: DVec3::ZERO,
        dpdy: DVec3::ZERO,
        duvdx: DVec2::ZERO,
        duvdy: DVec2::ZERO,
        filter_uv: uv,
        material: MaterialId(0),
    }
}

/// Bad placements are refused with a message, not a panic.
#[test]
fn mapped_materials_reject_bad_scale() {
    let map = egg_crate();
    let surface = Material::from_toml_str(SURFACE).unwrap();
    let e = BumpMapped::new(&map, &surface, 0.0, false).unwrap_err();
    assert!(e.contains("texels_per_uv"), "{e}");
}

/// A measured (non-parametric) NDF renders as the NDF it tabulates (issue #13 item 3: usable
/// where an NDF is): a `radial` table of GGX α = 0.25 every 0.5° (what `meso fit
/// --nonparametric` writes), under the same Schlick mirror facets and Smith masking (derived
/// numerically from the table), shades a sphere like the closed-form GGX material: the images
/// differ by less than 0.5 % (sum of absolute differences over the sum; measured 0.03 %).
#[test]
fn a_tabulated_ndf_renders_as_its_closed_form() {
    let alpha: f64 = 0.25;
    let a2 = alpha * alpha;
    let thetas: Vec<f64> = (0..180).map(|k| f64::from(k) * 0.5).collect();
    let density: Vec<String> = thetas
        .iter()
        .map(|t| {
            let c = t.to_radians().cos();
            let d = c * c * (a2 - 1.0) + 1.0;
            format!("{:e}", a2 / (std::f64::consts::PI * d * d))
        })
        .collect();
    let theta: Vec<String> = thetas.iter().map(|t| format!("{t:.1}")).collect();
    let facets = "[transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.6, 0.3]\n\
                  [shadowing]\nkind = \"smith\"\n[diffuse]\nalbedo = [0.05, 0.05, 0.05]\n";
    let tabulated = format!(
        "form = \"microfacet\"\n[ndf]\nkind = \"radial\"\ntheta = [{}]\ndensity = [{}]\n{facets}",
        theta.join(", "),
        density.join(", ")
    );
    let closed = format!("form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha = {alpha}\n{facets}");
    let light = Light::Directional {
        direction: DVec3::new(0.4, 0.3, 0.866).normalize(),
        irradiance: DVec3::splat(2.0),
    };
    let render_of = |text: &str| {
        let m = Material::from_toml_str(text).unwrap();
        render(
            &ortho_sphere_scene(Arc::new(MaterialShader::new(&m)), 48, 1, light),
            &RenderOptions::default(),
            None,
        )
    };
    let (a, b) = (render_of(&tabulated), render_of(&closed));
    let (mut num, mut den) = (0.0, 0.0);
    for (p, q) in a.pixels().iter().zip(b.pixels()) {
        for c in 0..3 {
            num += f64::from((p[c] - q[c]).abs());
            den += f64::from(q[c]);
        }
    }
    let err = num / den;
    eprintln!(
        "radial table against closed-form GGX: {:.3} % of the image",
        100.0 * err
    );
    assert!(den > 0.0 && err < 0.005, "relative image difference {err}");
}
