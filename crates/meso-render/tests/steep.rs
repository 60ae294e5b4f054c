//! Steep normal maps (issue #11, item 5): a stone-wall normal map generated here — blocks in
//! running bond with steep rims, about 20% of the texels with `n_z < 0.2` and some at or below
//! the horizon — rendered NDF-mapped at 1 spp against the bump-mapped (texel by texel) render
//! at 256 spp. The filtered render must match on average and have no class of pixels (a
//! regular grid tied to the pyramid's texels) far brighter than the truth; with the box filter
//! it must be within the issue's 3% mean pixel error.

use glam::DVec3;
use meso_core::material::Material;
use meso_maps::{extract, ExtractParams, NormalMap, Source};
use meso_render::*;
use std::sync::Arc;

mod common;
use common::{plane_scene, render_at, render_plane};

/// A deterministic hash of `(a, b, c)` to `[0, 1)`.
fn hash(a: i64, b: i64, c: i64) -> f64 {
    let mut h = (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (b as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (c as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 31;
    h = h.wrapping_mul(0xD6E8_FEB8_6659_FD93);
    h ^= h >> 32;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Side of the stone-wall map in texels (it tiles).
const N: usize = 128;

/// A stone wall as a tangent-space normal map, `N × N` texels, tileable: 4 courses of blocks
/// 32 × 16 texels in running bond with mortar joints 2 texels wide; each block has a rim about
/// 4 texels wide whose normals turn from the face's towards the joint, steepest (80°–96°
/// from +z at the joint, so some point at or below the horizon: undercut edges, as in real
/// scans); faces tilt per block by up to 12° and carry small bumps; the mortar is rough
/// (up to 25°).
fn stone_wall() -> Vec<DVec3> {
    let (bw, bh, joint, rim, corner) = (32.0f64, 16.0f64, 1.0f64, 4.0f64, 3.0f64);
    let mut out = Vec::with_capacity(N * N);
    for row in 0..N {
        for col in 0..N {
            let (x, y) = (col as f64 + 0.5, row as f64 + 0.5);
            let course = (y / bh).floor();
            let shift = if course as i64 % 2 == 1 {
                0.5 * bw
            } else {
                0.0
            };
            let xs = (x + shift).rem_euclid(N as f64);
            let block = (xs / bw).floor();
            let id = (course as i64, block as i64);
            // Position relative to the block's centre; signed distance to its rounded rectangle.
            let (px, py) = (xs - (block + 0.5) * bw, y - (course + 0.5) * bh);
            let (hx, hy) = (0.5 * bw - joint - corner, 0.5 * bh - joint - corner);
            let (qx, qy) = (px.abs() - hx, py.abs() - hy);
            let outside = (qx.max(0.0).powi(2) + qy.max(0.0).powi(2)).sqrt();
            let sd = outside + qx.max(qy).min(0.0) - corner;
            // Outward direction of the nearest edge.
            let (ex, ey) = if qx > 0.0 && qy > 0.0 {
                (qx * px.signum() / outside, qy * py.signum() / outside)
            } else if qx > qy {
                (px.signum(), 0.0)
            } else {
                (0.0, py.signum())
            };
            let jitter = hash(id.0, id.1, (row * N + col) as i64);
            let n = if sd >= 0.0 {
                // Mortar: rough, up to 25° in any azimuth.
                let t = 25f64.to_radians() * hash(row as i64, col as i64, 7).sqrt();
                let p = std::f64::consts::TAU * hash(row as i64, col as i64, 11);
                DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
            } else if -sd < rim {
                // Rim: from the face (inner edge) to 80°–96° at the joint.
                let s = 1.0 - (-sd) / rim;
                let theta = (80.0 + 16.0 * jitter).to_radians() * s.powf(0.3);
                DVec3::new(theta.sin() * ex, theta.sin() * ey, theta.cos())
            } else {
                // Face: a tilt per block plus small bumps.
                let t = 12f64.to_radians() * hash(id.0, id.1, 1);
                let p = std::f64::consts::TAU * hash(id.0, id.1, 2);
                let bump = 0.12;
                let (gx, gy) = (
                    t.tan() * p.cos() + bump * (0.7 * x + 3.0 * hash(id.0, id.1, 3)).sin(),
                    t.tan() * p.sin() + bump * (0.9 * y + 3.0 * hash(id.0, id.1, 4)).cos(),
                );
                DVec3::new(-gx, -gy, 1.0).normalize()
            };
            out.push(n);
        }
    }
    out
}

/// What the comparison of one filtered image against its truth found.
#[derive(Debug)]
struct Comparison {
    /// `Σ|a − b| / Σ b` over pixels and channels.
    mean_error: f64,
    /// Ratio of the mean radiances.
    mean_ratio: f64,
    /// Per class of sub-texel phase (4 × 4 classes of where the pixel's centre falls in the
    /// texels of the finer pyramid level it reads): `Σ a / Σ b` over the class.
    class_ratios: Vec<f64>,
    /// Largest per-pixel ratio `a / b` (pixels with a truth above 5% of the mean).
    max_pixel_ratio: f64,
    /// Largest per-pixel excess `(a − b)` over the mean of the truth (a sparkle).
    max_excess: f64,
}

fn compare(
    scene: &Scene,
    ndf: &NdfMapped,
    tpu: f64,
    filtered: &Image,
    truth: &Image,
) -> Comparison {
    let (w, h) = (truth.width(), truth.height());
    let sum = |p: [f32; 3]| f64::from(p[0] + p[1] + p[2]);
    let (mut num, mut den, mut sa, mut sb) = (0.0, 0.0, 0.0, 0.0);
    let mut classes = vec![(0.0f64, 0.0f64); 16];
    let mean_truth =
        truth.pixels().iter().map(|&p| sum(p)).sum::<f64>() / truth.pixels().len() as f64;
    let mut max_pixel_ratio = 0.0f64;
    let mut max_excess = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (filtered.get(x, y), truth.get(x, y));
            for c in 0..3 {
                num += f64::from((a[c] - b[c]).abs());
                den += f64::from(b[c]);
            }
            sa += sum(a);
            sb += sum(b);
            let rd = scene
                .camera
                .generate_ray(f64::from(x) + 0.5, f64::from(y) + 0.5, w, h);
            let Some(sp) = scene.intersect(&rd) else {
                continue;
            };
            let span = f64::from(1u32 << (ndf.lod(&sp).floor() as u32));
            let phase = |t: f64| {
                let f = (t * tpu / span - 0.5).rem_euclid(1.0);
                ((f * 4.0) as usize).min(3)
            };
            let k = phase(sp.filter_uv.y) * 4 + phase(sp.filter_uv.x);
            classes[k].0 += sum(a);
            classes[k].1 += sum(b);
            max_excess = max_excess.max((sum(a) - sum(b)) / mean_truth);
            if sum(b) > 0.05 * mean_truth {
                max_pixel_ratio = max_pixel_ratio.max(sum(a) / sum(b));
            }
        }
    }
    Comparison {
        mean_error: num / den,
        mean_ratio: sa / sb,
        class_ratios: classes
            .iter()
            .filter(|c| c.1 > 0.0)
            .map(|c| c.0 / c.1)
            .collect(),
        max_pixel_ratio,
        max_excess,
    }
}

/// One case of [`measure`].
struct Measurement {
    facets: &'static str,
    box_filter: bool,
    texels_per_pixel: f64,
    comparison: Comparison,
    /// The case and its numbers, as printed.
    line: String,
}

impl Measurement {
    /// The lowest and highest ratio of the classes of sub-texel phase.
    fn class_range(&self) -> (f64, f64) {
        self.comparison
            .class_ratios
            .iter()
            .fold((f64::MAX, 0.0f64), |(l, h), &r| (l.min(r), h.max(r)))
    }
}

/// The normal map `map` (one tile per unit of uv) NDF-mapped at 1 spp against bump-mapped at
/// 256 spp: a plane seen from ≈ 24° (48² pixels) at `texels_per_pixel` map texels per pixel,
/// Phong η = 20 facets with a diffuse term and Lambert facets, a high and a grazing light,
/// the trilinear and the box filter. Prints every case; `STEEP_REPORT=DIR` also writes the
/// images there.
fn measure(map: &NormalMap, texels_per_pixel: &[f64]) -> Vec<Measurement> {
    measure_facets(
        map,
        texels_per_pixel,
        &[("phong20", PHONG), ("lambert", LAMBERT)],
    )
}

/// [`measure`] with the given facet materials (name, TOML).
fn measure_facets(
    map: &NormalMap,
    texels_per_pixel: &[f64],
    facet_list: &[(&'static str, &str)],
) -> Vec<Measurement> {
    let pyr = extract(Source::Normals(map), &ExtractParams::default(), &mut |_| {}).unwrap();
    let tpu = map.width() as f64;
    let size = 48u32;
    let report = std::env::var("STEEP_REPORT").ok();
    let mut out = Vec::new();
    for &(facets, text) in facet_list {
        let surface = Material::from_toml_str(text).unwrap();
        let bump: Arc<dyn Shader> =
            Arc::new(BumpMapped::from_normal_map(map, &surface, tpu).unwrap());
        let lights = [DVec3::new(-0.5, 0.3, 0.8), DVec3::new(0.2, 0.9, 0.35)];
        // The 256-spp truth of each light and distance, rendered once for both filters.
        let truths: Vec<Image> = lights
            .iter()
            .flat_map(|&light| texels_per_pixel.iter().map(move |&cells| (light, cells)))
            .map(|(light, cells)| {
                render_plane(
                    bump.clone(),
                    cells * f64::from(size) / tpu,
                    size,
                    light,
                    256,
                )
            })
            .collect();
        for box_filter in [false, true] {
            let ndf = NdfMapped::new(&pyr, &surface, tpu, false)
                .unwrap()
                .with_box_filter(box_filter);
            let mut truth = truths.iter();
            for light in lights {
                for &cells in texels_per_pixel {
                    let width = cells * f64::from(size) / tpu;
                    let truth = truth.next().unwrap();
                    let scene = plane_scene(Arc::new(ndf.clone()), width, size, light);
                    let filtered = render_at(&scene, 1);
                    let comparison = compare(&scene, &ndf, tpu, &filtered, truth);
                    let filter = if box_filter { "box" } else { "trilinear" };
                    let mut m = Measurement {
                        facets,
                        box_filter,
                        texels_per_pixel: cells,
                        comparison,
                        line: String::new(),
                    };
                    let (lo, hi) = m.class_range();
                    let c = &m.comparison;
                    m.line = format!(
                        "{facets}, {filter}, light y = {:.2}, {cells} texels/px: error {:.4}, \
                         mean ratio {:.4}, classes {lo:.3}..{hi:.3}, max pixel ratio {:.2}, \
                         max excess {:.2}",
                        light.normalize().y,
                        c.mean_error,
                        c.mean_ratio,
                        c.max_pixel_ratio,
                        c.max_excess
                    );
                    eprintln!("{}", m.line);
                    if let Some(dir) = &report {
                        let stem =
                            format!("{dir}/{facets}-{filter}-{:.2}-{cells}", light.normalize().y);
                        filtered
                            .write_png(std::path::Path::new(&format!("{stem}-ndf.png")), 0.0)
                            .unwrap();
                        truth
                            .write_png(std::path::Path::new(&format!("{stem}-bump.png")), 0.0)
                            .unwrap();
                    }
                    out.push(m);
                }
            }
        }
    }
    out
}

/// Assert that no measurement is out of bounds by `out` (each one that is, by its line).
fn assert_in_bounds(measured: Vec<Measurement>, out: impl Fn(&Measurement) -> bool) {
    let failures: Vec<String> = measured
        .into_iter()
        .filter(|m| out(m))
        .map(|m| m.line)
        .collect();
    assert!(
        failures.is_empty(),
        "out of bounds:\n{}",
        failures.join("\n")
    );
}

/// The shipped real normal map: ambientCG Facade005's, box-filtered to 256² (CC0,
/// `tests/data/README.md`), OpenGL convention.
fn facade_normal_map() -> NormalMap {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/facade_normal_256.png");
    NormalMap::load(&path, meso_maps::NormalConvention::Gl).unwrap()
}

const PHONG: &str = r#"
[transfer]
kind = "phong"
exponent = 20.0
specular = [0.6, 0.6, 0.6]
[diffuse]
albedo = [0.5, 0.4, 0.3]
"#;

/// Glossy facets: GGX of roughness `alpha` with a small diffuse term (albedo 0.1).
fn ggx(alpha: f64) -> String {
    common::facet_toml(alpha, 0.1)
}

const LAMBERT: &str = r#"
[transfer]
kind = "lambert"
albedo = [0.7, 0.6, 0.5]
"#;

/// The stone wall NDF-mapped at 1 spp against bump-mapped at 256 spp (48² pixels, a plane
/// seen from ≈ 24°), Phong facets (η = 20, plus a diffuse term) and Lambert facets, two lights
/// (one high, one grazing from +y), 2, 4, 8 and 16 map texels per pixel, with the default
/// trilinear filter and with [`NdfMapped::with_box_filter`]; every case is printed.
///
/// Compared per pixel (mean relative error `Σ|a − b|/Σb`), on average, per class of sub-texel
/// phase (where the pixel centre falls in the texels of the pyramid level it reads, 4 × 4
/// classes: a regular grid of sparkles makes one class brighter) and by the largest excess of
/// one pixel over its truth, relative to the image's mean radiance.
///
/// * Trilinear, 2 and 4 texels per pixel: mean within 5%, every class within 10%, no excess
///   over 3, error below 14%. Measured: means 0.967–1.003, classes 0.931–1.044, excess ≤ 0.77,
///   errors 5.5–13.5%. The code before (commit 52fe59d) fails: Lambert facets up to 47% too
///   bright on average, a class 1.65×, one pixel 54× its truth (excess 3.96).
/// * Box filter, up to 8 texels per pixel for Phong facets and 4 for Lambert facets: the
///   issue's 3% mean pixel error, classes within 5%, no excess over 0.5. Measured: errors
///   0.1–2.9% (Phong), 0.2–1.2% (Lambert), classes 0.990–1.009, excess ≤ 0.25. At 8 texels
///   per pixel Lambert facets are at 3.4–5.7%, at 16 texels per pixel Phong facets at
///   3.3–4.2% and Lambert at 4.9–7.0% (the lobe fits of the coarser levels), reported only.
///
/// Command and tables: docs/heightmaps.md, "Steep maps".
#[test]
fn steep_normal_map_renders_without_sparkle() {
    let normals = stone_wall();
    let steep = normals.iter().filter(|n| n.z < 0.2).count() as f64 / normals.len() as f64;
    let below = normals.iter().filter(|n| n.z <= 0.0).count();
    let map = NormalMap::from_normals(N, N, normals).unwrap();
    eprintln!(
        "stone wall {N}²: {:.1}% of texels with n_z < 0.2, {below} at or below the horizon, \
         {} tilted up to n_z = 0.01",
        100.0 * steep,
        map.clamped()
    );
    // The map is as steep as the issue's stone wall (20% of texels with n_z < 0.2) and has
    // texels at or below the horizon.
    assert!((0.15..0.25).contains(&steep), "steep fraction {steep}");
    assert!(below > 100, "{below} texels at or below the horizon");
    assert_in_bounds(measure(&map, &[2.0, 4.0, 8.0, 16.0]), |m| {
        let (c, (lo, hi)) = (&m.comparison, m.class_range());
        if m.box_filter {
            // The box filter: the issue's 3% mean pixel error.
            let reach = if m.facets == "lambert" { 4.0 } else { 8.0 };
            m.texels_per_pixel <= reach
                && (c.mean_error > 0.03 || lo < 0.95 || hi > 1.05 || c.max_excess > 0.5)
        } else {
            m.texels_per_pixel <= 4.0
                && ((c.mean_ratio - 1.0).abs() > 0.05
                    || lo < 0.9
                    || hi > 1.1
                    || c.max_excess > 3.0
                    || c.mean_error > 0.14)
        }
    });
}

/// A real normal map made steep: ambientCG's Facade005 normal map (CC0, box-filtered to 256²,
/// `tests/data/README.md`) is gentle (no texel at `n_z < 0.2`, nor after its slopes are
/// multiplied by 20: box-filtered 8-bit normals), so its slopes are multiplied by 30
/// (`n ← normalise(30 n_x, 30 n_y, n_z)`: 25% of texels at `n_z < 0.2`). At 2 and 4 texels per pixel: with the
/// trilinear filter every class of sub-texel phase within 10% and no pixel excess over 3; with
/// the box filter the issue's 3% mean pixel error. Measured: see docs/heightmaps.md, "Steep
/// maps".
#[test]
fn real_normal_map_made_steep_renders_without_sparkle() {
    let map = facade_normal_map();
    let normals: Vec<DVec3> = map
        .normals()
        .iter()
        .map(|n| DVec3::new(30.0 * n.x, 30.0 * n.y, n.z))
        .collect();
    let map = NormalMap::from_normals(map.width(), map.height(), normals).unwrap();
    let steep =
        map.normals().iter().filter(|n| n.z < 0.2).count() as f64 / map.normals().len() as f64;
    eprintln!("facade ×30: {:.1}% of texels with n_z < 0.2", 100.0 * steep);
    assert!(steep > 0.15, "steep fraction {steep}");
    assert_in_bounds(measure(&map, &[2.0, 4.0]), |m| {
        let (c, (lo, hi)) = (&m.comparison, m.class_range());
        if m.box_filter {
            c.mean_error > 0.03 || lo < 0.95 || hi > 1.05 || c.max_excess > 0.5
        } else {
            lo < 0.9 || hi > 1.1 || c.max_excess > 3.0
        }
    });
}

/// Glossy facets on the stone wall (GGX α = 0.1 and 0.05, mirror-like microfacet facets with
/// a small diffuse term), NDF-mapped at 1 spp with the default box filter against bump-mapped
/// at 256 spp, as [`steep_normal_map_renders_without_sparkle`] does for Phong 20 and Lambert
/// facets. Up to 4 texels per pixel: mean pixel error under 5 %, the mean within 1 %, every
/// class of sub-texel phase within 3 %, no pixel's excess over 1.5 × the mean. At 8 texels per
/// pixel the mean within 1 % and the classes within 5 %; at 16, within 3 % and 10 %. The far
/// bounds hold because the box filter's default detail for these facets is 3 (α = 0.05 and,
/// since 2026-12-07, α = 0.1; 1.16 before, and 2 for α = 0.05 gave the same figures to
/// 0.1 %): finer levels than the footprint (`default_box_detail`). At detail 0 the
/// grazing light's mean at 16 texels per pixel was 0.63 (α = 0.05) and 0.80 (α = 0.1), now
/// 0.99 both (docs/heightmaps.md, "Glossy facets"). The far views' per-pixel error is reported
/// only: the 256-spp truth's own noise is 6–27 % there.
#[test]
fn glossy_facets_on_a_steep_map_render_without_sparkle() {
    let map = NormalMap::from_normals(N, N, stone_wall()).unwrap();
    assert_in_bounds(
        measure_facets(
            &map,
            &[2.0, 4.0, 8.0, 16.0],
            &[("ggx0.1", &ggx(0.1)), ("ggx0.05", &ggx(0.05))],
        ),
        |m| {
            let (c, (lo, hi)) = (&m.comparison, m.class_range());
            // Up close, every measure; further out (where the glossy facets' default box
            // detail, 3, reads finer levels than the footprint) the mean and the
            // phase classes: the 256-spp truth's own noise is 6–27 % per pixel there
            // (docs/heightmaps.md, "Glossy facets"). At detail 0 the grazing light's
            // 16 texels/px were 0.63 (α = 0.05) and 0.80 (α = 0.1).
            m.box_filter
                && if m.texels_per_pixel <= 4.0 {
                    c.mean_error > 0.05
                        || (c.mean_ratio - 1.0).abs() > 0.01
                        || lo < 0.97
                        || hi > 1.03
                        || c.max_excess > 1.5
                } else if m.texels_per_pixel <= 8.0 {
                    (c.mean_ratio - 1.0).abs() > 0.01 || lo < 0.95 || hi > 1.05
                } else {
                    (c.mean_ratio - 1.0).abs() > 0.03 || lo < 0.9 || hi > 1.1
                }
        },
    );
}

/// Glossy facets far away on the shipped real normal map as it is (ambientCG Facade005, the
/// 256² box-filtered copy in `tests/data/`, OpenGL convention): GGX α = 0.1 and 0.05 at 8 and
/// 16 texels per pixel with the default box filter, against the 256-spp bump map: mean pixel
/// error under 4 %, the mean within 2 %, phase classes within 5 %. At detail 0 (the box filter
/// before `default_box_detail`) α = 0.05 at 16 texels per pixel under the high light was 14.4 %
/// off, its mean 1.144 (docs/heightmaps.md, "Glossy facets").
#[test]
fn glossy_facets_far_away_on_a_real_normal_map() {
    let map = facade_normal_map();
    assert_in_bounds(
        measure_facets(
            &map,
            &[8.0, 16.0],
            &[("ggx0.1", &ggx(0.1)), ("ggx0.05", &ggx(0.05))],
        ),
        |m| {
            let (c, (lo, hi)) = (&m.comparison, m.class_range());
            m.box_filter
                && (c.mean_error > 0.04
                    || (c.mean_ratio - 1.0).abs() > 0.02
                    || lo < 0.95
                    || hi > 1.05)
        },
    );
}

/// Glossy facets seen from very far on both normal maps (the stone wall and the shipped
/// facade), 32 and 64 texels per pixel, with the default box filter and detail (3 for GGX
/// α = 0.05, 0.1 and 0.15), against the 256-spp bump map: the mean within 5 % for α = 0.1 and
/// 0.15 and 8 % for α = 0.05, the phase classes within 10 % and 20 % (α = 0.05's 256-spp truth
/// is the noisier). Measured: α = 0.1 means 0.965–1.003, classes 0.919–1.012; α = 0.05 means
/// 0.929–1.018, classes 0.823–1.053 (the stone wall under the grazing light at 64 texels per
/// pixel the lowest of both); α = 0.15 means 0.978–1.001, classes 0.949–1.014. The defaults
/// before 2026-12-07 fail it: α = 0.1 at detail 1.16 (the stone wall's grazing view 0.787 /
/// 0.752; detail 2 0.774 at 64 texels per pixel), α = 0.15 at 0.58 (0.69 at 64 texels per
/// pixel under both lights): docs/heightmaps.md, "Detail 3 for GGX α = 0.1 on more maps".
/// Per-pixel errors (1–57 % there, the truth's own noise included) are reported only.
#[test]
fn glossy_facets_seen_from_very_far() {
    let maps = [
        NormalMap::from_normals(N, N, stone_wall()).unwrap(),
        facade_normal_map(),
    ];
    for map in &maps {
        assert_in_bounds(
            measure_facets(
                map,
                &[32.0, 64.0],
                &[
                    ("ggx0.15", &ggx(0.15)),
                    ("ggx0.1", &ggx(0.1)),
                    ("ggx0.05", &ggx(0.05)),
                ],
            ),
            |m| {
                let (c, (lo, hi)) = (&m.comparison, m.class_range());
                let (mean, class) = if m.facets == "ggx0.05" {
                    (0.08, 0.20)
                } else {
                    (0.05, 0.10)
                };
                m.box_filter
                    && ((c.mean_ratio - 1.0).abs() > mean || lo < 1.0 - class || hi > 1.0 + class)
            },
        );
    }
}
