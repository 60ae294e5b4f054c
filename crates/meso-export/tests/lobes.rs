//! K lobes in a shader (`meso_export::lobes`): the shipped WGSL and GLSL parsed and validated by
//! naga, the encoding round trip through an independent PNG reader, and the CPU reference of
//! the shaders' formula against meso's exact effective BRDF of the same lobes.

use glam::DVec3;
use meso_core::convolution::{effective_brdf, Accuracy, Form};
use meso_core::ndf::{Ndf, PhongLobe, PhongPeaks};
use meso_core::transfer::{Fresnel, Transfer};
use meso_export::lobes;

fn validate(module: &naga::Module) -> Result<(), String> {
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(module)
    .map(|_| ())
    .map_err(|e| format!("{e:?}"))
}

fn wgsl(src: &str) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| e.emit_to_string(src))?;
    for f in ["meso_lobe_add", "meso_lobes_finish", "meso_lobe_decode"] {
        if !module
            .functions
            .iter()
            .any(|(_, g)| g.name.as_deref() == Some(f))
        {
            return Err(format!("no function {f}"));
        }
    }
    validate(&module)
}

const WGSL_MAIN: &str = r"
@fragment
fn fs(@location(0) t: vec4<f32>, @location(1) wi: vec3<f32>, @location(2) wo: vec3<f32>) -> @location(0) vec4<f32> {
    let s = meso_lobe_add(t, normalize(wi), normalize(wo), vec4<f32>(0.0));
    return vec4<f32>(meso_lobes_finish(s, normalize(wi), normalize(wo), vec3<f32>(0.04)), 1.0);
}
";

/// The GLSL wrapped in a fragment shader; naga's GLSL front end reads `#version 440`–`460`
/// only (WebGL 2's ES 3.00 is run by `tests/engine/lobes.test.mjs`).
fn glsl(src: &str) -> Result<(), String> {
    let full = format!(
        "#version 450\nprecision highp float;\n{src}\n\
         layout(location = 0) in vec4 t;\nlayout(location = 1) in vec3 wi;\n\
         layout(location = 2) in vec3 wo;\nlayout(location = 0) out vec4 color;\n\
         void main() {{\n  vec4 s = meso_lobe_add(t, normalize(wi), normalize(wo), vec4(0.0));\n\
           color = vec4(meso_lobes_finish(s, normalize(wi), normalize(wo), vec3(0.04)), 1.0);\n}}\n"
    );
    let module = naga::front::glsl::Frontend::default()
        .parse(
            &naga::front::glsl::Options::from(naga::ShaderStage::Fragment),
            &full,
        )
        .map_err(|e| e.emit_to_string(&full))?;
    validate(&module)
}

#[test]
fn wgsl_parses_and_validates() {
    wgsl(&format!("{}{WGSL_MAIN}", lobes::WGSL)).unwrap();
    wgsl(lobes::WGSL).unwrap();
    // The check can fail: a type error and a missing function are refused.
    assert!(
        wgsl(&lobes::WGSL.replace("let mc = eta / (eta + 4.0);", "let mc = eta / 4u;")).is_err()
    );
    assert!(wgsl(&lobes::WGSL.replace("fn meso_lobes_finish", "fn meso_lobes_finis")).is_err());
}

#[test]
fn glsl_parses_and_validates() {
    glsl(lobes::GLSL).unwrap();
    assert!(glsl(&lobes::GLSL.replace(
        "vec4 l = meso_lobe_decode(texel, w);",
        "vec3 l = meso_lobe_decode(texel, w);"
    ))
    .is_err());
}

#[test]
fn encoding_round_trip() {
    // Axes over the whole sphere, 16-bit octahedral: within 1e-4 rad; η within 0.05 %.
    let mut worst = 0.0f64;
    for i in 0..40 {
        for j in 0..80 {
            let t = std::f64::consts::PI * (i as f64 + 0.5) / 40.0;
            let p = std::f64::consts::TAU * j as f64 / 80.0;
            let a = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
            let l = lobes::decode(lobes::from_u16(lobes::to_u16(lobes::encode(a, 0.0, 0.5))));
            worst = worst.max(l.axis.dot(a).clamp(-1.0, 1.0).acos());
        }
    }
    assert!(worst < 1e-4, "octahedral axis error {worst} rad");
    for eta in [0.0, 0.5, 3.0, 77.0, 1234.0, 1.0e5, 1.0e6] {
        let l = lobes::decode(lobes::from_u16(lobes::to_u16(lobes::encode(
            DVec3::Z,
            eta,
            1.0,
        ))));
        assert!(
            (l.eta - eta).abs() <= 5e-4 * (1.0 + eta),
            "eta {eta} -> {}",
            l.eta
        );
    }
}

fn pyramid() -> meso_maps::Pyramid {
    let map = meso_maps::fixtures::gaussian(32, 3.0, 2.0, 11, 1.0).unwrap();
    let mut p = meso_maps::ExtractParams::default();
    p = p.with_max_lobes(3);
    meso_maps::extract(meso_maps::Source::Heights(&map), &p, &mut |_| {}).unwrap()
}

#[test]
fn packed_pngs_read_back_by_the_image_crate() {
    let pyr = pyramid();
    let tex = lobes::pack(&pyr);
    assert!(
        tex.k >= 2,
        "the rough map should need several lobes, K = {}",
        tex.k
    );
    let files = lobes::files(&tex).unwrap();
    assert_eq!(files.len(), tex.k * pyr.levels.len() + 2);
    for (l, lev) in pyr.levels.iter().enumerate() {
        for k in 0..tex.k {
            let name = lobes::lobe_png(k, l);
            let bytes = &files.iter().find(|(n, _)| *n == name).unwrap().1;
            let img = image::load_from_memory(bytes).unwrap().into_rgba16();
            assert_eq!(
                (img.width() as usize, img.height() as usize),
                (lev.cols, lev.rows)
            );
            for r in 0..lev.rows {
                for c in 0..lev.cols {
                    let px = img.get_pixel(c as u32, (lev.rows - 1 - r) as u32).0;
                    let d = lobes::decode(lobes::from_u16(px));
                    match lev.texel_lobes(r, c).unwrap().get(k) {
                        Some(want) => {
                            assert!(
                                (d.weight - want.weight).abs() < 1e-4,
                                "{name} ({r},{c}) weight {} vs {}",
                                d.weight,
                                want.weight
                            );
                            assert!(d.axis.dot(want.axis) > 1.0 - 1e-8, "{name} ({r},{c})");
                            assert!((d.eta - want.exponent).abs() <= 5e-4 * (1.0 + want.exponent));
                        }
                        None => assert_eq!(px, [0; 4], "{name} ({r},{c}): empty slot"),
                    }
                }
            }
        }
    }
    let names: Vec<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
    assert!(names.contains(&"meso_lobes.wgsl") && names.contains(&"meso_lobes.glsl"));
}

fn exact(texels: &[[f64; 4]], wi: DVec3, wo: DVec3, f0: [f64; 3]) -> [f64; 3] {
    let peaks: Vec<PhongLobe> = texels
        .iter()
        .map(|t| lobes::decode(*t))
        .filter(|l| l.weight > 0.0)
        .map(|l| PhongLobe::new(l.axis, l.weight, l.eta))
        .collect();
    let ndf = Ndf::PhongPeaks(PhongPeaks::new(peaks).unwrap());
    let transfer = Transfer::Mirror {
        fresnel: Fresnel::Schlick { f0 },
        specular: [1.0; 3],
    };
    effective_brdf(&ndf, &transfer, Form::Microfacet, wi, wo, Accuracy::fine())
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// The relative errors of `eval_texel` against meso's exact BRDF, over `sets` × the sample
/// directions (pairs where the exact value is below 1e-6 of the set's largest are skipped).
fn errors(sets: &[Vec<[f64; 4]>]) -> Vec<f64> {
    let f0 = [0.9, 0.6, 0.5];
    let mut errs = Vec::new();
    for set in sets {
        let pairs = lobes::sample_directions();
        let vals: Vec<([f64; 3], [f64; 3])> = pairs
            .iter()
            .map(|(wi, wo)| {
                (
                    lobes::eval_texel(set, *wi, *wo, f0),
                    exact(set, *wi, *wo, f0),
                )
            })
            .collect();
        let top = vals.iter().map(|(_, e)| e[1]).fold(0.0, f64::max);
        if std::env::var_os("LOBES_DIAG").is_some() {
            let l = lobes::decode(set[0]);
            let mut w = 0.0f64;
            for (got, want) in &vals {
                if want[1] > 1e-6 * top {
                    w = w.max((got[1] - want[1]).abs() / want[1]);
                }
            }
            eprintln!(
                "set of {} lobes, eta0 {:.0} az {:.2}: max rel {w:.4}",
                set.len(),
                l.eta,
                l.axis.z
            );
        }
        for (got, want) in vals {
            if want[1] > 1e-6 * top {
                for c in 0..3 {
                    errs.push((got[c] - want[c]).abs() / want[c]);
                }
            }
        }
    }
    errs
}

#[test]
fn cpu_reference_against_exact_brdf() {
    let synthetic = lobes::sample_texels();
    let pyr = pyramid();
    let tex = lobes::pack(&pyr);
    // Fitted lobes: texels of every level from 2 × 2 texels up (several lobes each where the
    // fit found them).
    let mut fitted = Vec::new();
    for l in pyr.levels.len().saturating_sub(4)..pyr.levels.len() {
        let (cols, rows) = tex.sizes[l];
        for t in (0..cols * rows).step_by((cols * rows - 1).max(1)) {
            let set: Vec<[f64; 4]> = (0..tex.k)
                .map(|k| {
                    let o = t * 4;
                    let s = &tex.levels[l][k][o..o + 4];
                    lobes::from_u16([s[0], s[1], s[2], s[3]])
                })
                .filter(|v| v[3] > 0.0)
                .collect();
            fitted.push(set);
        }
    }
    let broad = synthetic[..2].to_vec();
    let sharp = synthetic[2..].to_vec();
    // (name, sets, bound on the median, bound on the maximum): the bounds sit just above the
    // measured figures (docs/export.md); broad lobes (η ≤ 2) have a known larger error.
    for (name, sets, med_max, max_max) in [
        ("sharp (eta >= 20)", &sharp, 0.002, 0.04),
        ("fitted", &fitted, 0.002, 0.06),
        ("broad (eta <= 2)", &broad, 0.2, 0.45),
    ] {
        let mut e = errors(sets);
        let n = e.len();
        let (med, p95, max) = (
            percentile(&mut e, 0.5),
            percentile(&mut e, 0.95),
            percentile(&mut e, 1.0),
        );
        eprintln!(
            "{name}: {} sets, {n} values, relative error median {med:.4}, p95 {p95:.4}, max {max:.4}",
            sets.len()
        );
        assert!(med < med_max, "{name}: median relative error {med}");
        assert!(max < max_max, "{name}: largest relative error {max}");
    }
}

#[test]
fn cpu_reference_matches_exact_where_masking_vanishes() {
    // A very sharp lobe on the normal at normal incidence: Λ ≈ 0 and A ≈ 1 in both, so the two
    // agree to 1e-3 — and a wrong normalisation (a factor 2 on n, say) would fail here.
    let set = vec![lobes::from_u16(lobes::to_u16(lobes::encode(
        DVec3::Z,
        5000.0,
        1.0,
    )))];
    let (wi, wo) = (DVec3::Z, DVec3::Z);
    let got = lobes::eval_texel(&set, wi, wo, [0.04; 3]);
    let want = exact(&set, wi, wo, [0.04; 3]);
    assert!((got[0] / want[0] - 1.0).abs() < 1e-3, "{got:?} vs {want:?}");
}
