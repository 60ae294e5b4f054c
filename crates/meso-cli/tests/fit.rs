//! `meso fit` end to end: a MERL file generated from a known lobe model is fitted back, the
//! written material is read by meso-core and reproduces the generating BRDF; bad input fails
//! cleanly with one error line and no output file.

mod common;
use common::{run, tmpdir};

use glam::DVec3;
use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;
use meso_core::ndf::PhongLobe;
use meso_measured::merl::{CellPosition, MerlTable};
use meso_measured::model::LobeParams;
use std::path::{Path, PathBuf};

/// The generating material: one Phong peak on the normal, Phong transfer, diffuse term.
fn truth() -> LobeParams {
    LobeParams {
        lobes: vec![PhongLobe::new(DVec3::Z, 1.0, 400.0)],
        transfer_exponent: 150.0,
        specular: [0.8, 0.6, 0.4],
        albedo: [0.3, 0.2, 0.1],
    }
}

fn write_merl(dir: &Path) -> PathBuf {
    let t = truth();
    let table = MerlTable::from_fn(CellPosition::Edge, |wi, wo| t.eval(wi, wo)).unwrap();
    let p = dir.join("truth.binary");
    table.write(&p).unwrap();
    p
}

#[test]
fn fit_reproduces_the_generating_brdf_and_bad_input_fails_cleanly() {
    let dir = tmpdir("cli-fit", "merl");
    let merl = write_merl(&dir);
    let out = dir.join("fitted.toml");
    let o = run(&[
        "fit",
        merl.to_str().unwrap(),
        "--lobes",
        "1",
        "--samples",
        "4000",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "meso fit failed: {}\n{stdout}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("written material, exact"), "{stdout}");
    assert!(stdout.contains("lobe  theta(deg)"), "{stdout}");
    // MERL data: axes on the normal by default; there MERL's θh cells are far finer than the
    // lobe model's own bound (the cap is that bound); held-out cells reported.
    assert!(stdout.contains("axes: normal"), "{stdout}");
    assert!(
        stdout.contains("lobe sharpness cap: none below the model's bound"),
        "{stdout}"
    );
    let held = stdout
        .lines()
        .find(|l| l.contains("held out, not fitted ("))
        .unwrap_or_else(|| panic!("no held-out row in\n{stdout}"));
    let n_held: usize = held[held.find('(').unwrap() + 1..held.find(" samples").unwrap()]
        .parse()
        .unwrap();
    assert!(n_held > 100_000, "{held}");
    let v: Vec<f64> = held[held.find(')').unwrap() + 1..]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    assert!(v.len() == 6 && v[3..].iter().all(|e| *e < 0.01), "{held}");

    // The written material, read by meso-core and evaluated exactly, against the generating
    // closed form (tolerance: the closed form is within a few % of the exact quadrature for
    // lobes this sharp, plus the fit error).
    let text = std::fs::read_to_string(&out).unwrap();
    let m = Material::from_toml_str(&text).expect("the output is a valid material");
    let t = truth();
    assert!(text.contains("--axes normal"), "{text}");
    assert!(text.contains("held-out samples"), "{text}");
    let mut worst: f64 = 0.0;
    for (ti, pi, to, po) in [
        (0.0, 0.0, 5.0, 0.0),
        (20.0, 180.0, 20.0, 0.0),
        (30.0, 180.0, 25.0, 10.0),
        (45.0, 180.0, 45.0, 0.0),
        (45.0, 180.0, 40.0, 30.0),
        (60.0, 0.0, 60.0, 180.0),
        (30.0, 0.0, 60.0, 90.0),
        (10.0, 40.0, 70.0, 200.0),
    ] {
        let wi = spherical_direction_deg(ti, pi);
        let wo = spherical_direction_deg(to, po);
        let got = m.brdf(wi, wo);
        let want = t.eval(wi, wo);
        for c in 0..3 {
            let rel = (got[c] - want[c]).abs() / want[c].max(0.05);
            worst = worst.max(rel);
            assert!(
                rel < 0.08,
                "({ti},{pi},{to},{po}) channel {c}: material {} vs truth {}",
                got[c],
                want[c]
            );
        }
    }
    eprintln!("worst relative difference {worst}");

    // A truncated MERL file: non-zero exit, one error line, no output.
    let bytes = std::fs::read(&merl).unwrap();
    let cut = dir.join("cut.binary");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out2 = dir.join("never.toml");
    let o = run(&[
        "fit",
        cut.to_str().unwrap(),
        "--lobes",
        "2",
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "one error line: {err}");
    assert!(
        err.contains("truncated") && err.contains("expected"),
        "{err}"
    );
    assert!(!out2.exists());

    // A wrong header with the MERL extension.
    let mut bad = bytes[..4096].to_vec();
    bad[0] = 91;
    let badp = dir.join("header.binary");
    std::fs::write(&badp, &bad).unwrap();
    let o = run(&[
        "fit",
        badp.to_str().unwrap(),
        "--lobes",
        "1",
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("header"), "{err}");
    assert!(!out2.exists());

    // CSV: empty, negative and NaN samples.
    for (name, text, needle) in [
        ("empty.csv", "", "empty"),
        (
            "neg.csv",
            "theta_i,phi_i,theta_o,phi_o,r,g,b\n30,0,30,180,0.5,-0.1,0.2\n",
            "negative",
        ),
        (
            "nan.csv",
            "theta_i,phi_i,theta_o,phi_o,r,g,b\n30,0,30,180,NaN,0.1,0.2\n",
            "line 2",
        ),
    ] {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        let o = run(&[
            "fit",
            p.to_str().unwrap(),
            "--lobes",
            "1",
            "--out",
            out2.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{name} accepted");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "{name}: {err}");
        assert!(err.to_lowercase().contains(needle), "{name}: {err}");
        assert!(!out2.exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Direction pairs with θi, θo < 80°, dense near the specular configuration (θh sampled like
/// MERL's non-linear axis), all four half/difference angles varying (low-discrepancy sequence).
/// Run the command line in the first line of a written material file (`# meso fit …`) as
/// written, with `--out out` added; it must succeed and fit the same data: the re-run file's
/// command line and its description of the data (which cells were fitted and held out, e.g.
/// "MERL binary, 8000 of … valid cells fitted") equal the original's.
fn rerun_header(text: &str, out: &Path) {
    let header = text
        .lines()
        .next()
        .unwrap()
        .trim_start_matches("# ")
        .to_owned();
    let mut args: Vec<String> = header
        .split_whitespace()
        .skip(1)
        .map(str::to_owned)
        .collect();
    args.extend(["--out".into(), out.to_str().unwrap().to_owned()]);
    let o = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        o.status.success(),
        "{header}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let again = std::fs::read_to_string(out).unwrap();
    // Line 1: the command; line 2: "MODEL: fitted DATA DESCRIPTION in T s, N LM iterations"
    // (the time differs between runs).
    let data_line = |t: &str| {
        let l = t.lines().nth(1).unwrap_or("").to_owned();
        l.split(" in ").next().unwrap_or("").to_owned()
    };
    assert_eq!(text.lines().next(), again.lines().next(), "{again}");
    assert_eq!(data_line(text), data_line(&again), "{text}\n---\n{again}");
}

fn pairs(n: usize) -> Vec<(DVec3, DVec3)> {
    use meso_measured::rusinkiewicz::{dirs_from_half_diff, HalfDiff};
    use std::f64::consts::{FRAC_PI_2, PI};
    let g = [0.754_877_666, 0.569_840_291, 0.430_159_709, 0.324_717_957];
    let cmax = 80f64.to_radians().cos();
    let mut out = Vec::with_capacity(n);
    let mut k = 0usize;
    while out.len() < n {
        k += 1;
        let u: Vec<f64> = g.iter().map(|a| (0.5 + a * k as f64).fract()).collect();
        let (wi, wo) = dirs_from_half_diff(HalfDiff {
            theta_h: u[0] * u[0] * FRAC_PI_2,
            phi_h: 2.0 * PI * u[1],
            theta_d: u[2] * FRAC_PI_2,
            phi_d: 2.0 * PI * u[3],
        });
        if wi.z > cmax && wo.z > cmax {
            out.push((wi, wo));
        }
    }
    out
}

/// The "fitted closed form (N samples)" row of the report: Ngan L2 and Löw log per channel.
fn fitted_errors(report: &str, n: usize) -> ([f64; 3], [f64; 3]) {
    let tag = format!("fitted closed form ({n} samples)");
    let line = report
        .lines()
        .find(|l| l.contains(&tag))
        .unwrap_or_else(|| panic!("no `{tag}` row in\n{report}"));
    let v: Vec<f64> = line[line.find(')').unwrap() + 1..]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(v.len(), 6, "{line}");
    ([v[0], v[1], v[2]], [v[3], v[4], v[5]])
}

/// The lobe model written in a per-channel file, as closed-form parameters.
fn read_lobe_material(path: &Path) -> LobeParams {
    use meso_core::ndf::Ndf;
    use meso_core::transfer::Transfer;
    let text = std::fs::read_to_string(path).unwrap();
    let m = Material::from_toml_str(&text).expect("valid material");
    let Ndf::PhongPeaks(p) = &m.ndf else {
        panic!("{}: not Phong peaks", path.display());
    };
    let Transfer::Phong {
        exponent, specular, ..
    } = m.transfer
    else {
        panic!("{}: not the Phong transfer", path.display());
    };
    LobeParams {
        lobes: p.lobes().to_vec(),
        transfer_exponent: exponent,
        specular,
        albedo: m.diffuse,
    }
}

/// `--per-channel-lobes`: data whose red, green and blue channels come from three different lobe
/// geometries (an axis on the normal, tilted in two azimuths; three exponents). Each per-channel
/// file recovers its channel's lobe, and the per-channel fit beats the shared-geometry fit.
#[test]
fn per_channel_lobes_recover_each_channels_geometry() {
    use meso_measured::csv::{write_csv, CsvSample};
    let lobe = |t: f64, p: f64, eta: f64| PhongLobe::new(spherical_direction_deg(t, p), 1.0, eta);
    let truths = [
        (lobe(0.0, 0.0, 200.0), 0.8, 0.2),
        (lobe(20.0, 0.0, 1500.0), 0.6, 0.1),
        (lobe(15.0, 120.0, 60.0), 0.9, 0.05),
    ]
    .map(|(l, spec, alb)| LobeParams {
        lobes: vec![l],
        transfer_exponent: 300.0,
        specular: [spec; 3],
        albedo: [alb; 3],
    });
    let n = 6000;
    let samples: Vec<CsvSample> = pairs(n)
        .into_iter()
        .map(|(wi, wo)| CsvSample::from_dirs(wi, wo, [0, 1, 2].map(|c| truths[c].eval(wi, wo)[c])))
        .collect();
    let dir = tmpdir("cli-fit", "per-channel");
    let csv = dir.join("rgb.csv");
    write_csv(&csv, &samples).unwrap();

    let run = |extra: &[&str], out: &Path| -> String {
        let mut args = vec![
            "fit",
            csv.to_str().unwrap(),
            "--lobes",
            "1",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            o.status.success(),
            "meso fit {extra:?} failed: {}\n{stdout}",
            String::from_utf8_lossy(&o.stderr)
        );
        stdout
    };
    let per = run(&["--per-channel-lobes"], &dir.join("per.toml"));
    assert!(
        per.contains("red channel:") && per.contains("blue channel:"),
        "{per}"
    );
    let shared = run(&[], &dir.join("shared.toml"));
    assert!(
        !dir.join("per.toml").exists(),
        "per-channel mode writes three files"
    );

    for (c, name) in ["red", "green", "blue"].iter().enumerate() {
        let path = dir.join(format!("per.{name}.toml"));
        let got = read_lobe_material(&path);
        let want = &truths[c];
        assert_eq!(got.lobes.len(), 1, "{name}");
        let (g, w) = (got.lobes[0], want.lobes[0]);
        let angle = g.axis.dot(w.axis).clamp(-1.0, 1.0).acos().to_degrees();
        assert!(angle < 0.5, "{name}: axis off by {angle}° ({got:?})");
        // Only κκ_t/(κ + κ_t) (κ = η/4, κ_t = η_t) is sharply determined by the peak.
        let sharp = |p: &LobeParams| {
            let (k, kt) = (0.25 * p.lobes[0].exponent, p.transfer_exponent);
            k * kt / (k + kt)
        };
        let (sg, sw) = (sharp(&got), sharp(want));
        assert!(
            (sg / sw - 1.0).abs() < 0.03,
            "{name}: sharpness {sg} vs {sw}"
        );
        // Grey files: the channel's albedo in every channel.
        assert!(got.albedo.iter().all(|&a| a == got.albedo[0]), "{got:?}");
        assert!(
            (got.albedo[0] / want.albedo[0] - 1.0).abs() < 0.03,
            "{name}: albedo {} vs {}",
            got.albedo[0],
            want.albedo[0]
        );
        // The file's closed form reproduces its channel of the data.
        for &(wi, wo) in pairs(200).iter() {
            let (a, b) = (got.eval(wi, wo)[0], want.eval(wi, wo)[c]);
            assert!(
                (a - b).abs() < 0.02 * b.max(0.1),
                "{name}: {a} vs {b} at {wi:?} {wo:?}"
            );
        }
    }

    // One geometry for three different lobes cannot fit all channels.
    // Every 10th CSV sample is held out (and reported), the others are fitted.
    assert!(per.contains("held out, not fitted (600 samples)"), "{per}");
    let (per_l2, per_log) = fitted_errors(&per, n - n / 10);
    let (sh_l2, sh_log) = fitted_errors(&shared, n - n / 10);
    eprintln!("per-channel: {per_l2:?} {per_log:?}; shared: {sh_l2:?} {sh_log:?}");
    for c in 0..3 {
        assert!(per_log[c] < 2e-3, "per-channel log error {per_log:?}");
    }
    let worst_shared = sh_log.iter().copied().fold(0.0, f64::max);
    let worst_per = per_log.iter().copied().fold(0.0, f64::max);
    assert!(
        worst_per < 0.2 * worst_shared,
        "per-channel {per_log:?} vs shared {sh_log:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `meso fit --transfer ggx-lobes` (and the default `auto`, which tries it as a third family) on
/// a MERL table generated from a known mixture of two GGX lobes: the written `kind = "mixture"`
/// material, evaluated by `meso brdf`, is the fitted closed form (and the truth).
#[test]
fn ggx_lobes_fit_writes_a_mixture_that_meso_brdf_reproduces() {
    use meso_core::ndf::Ndf;
    use meso_core::shading::{FastBrdf, Policy};
    use meso_measured::model::{GgxLobe, LobeGgxParams};
    let dir = tmpdir("cli-fit", "ggx");
    let truth_text = "form = \"microfacet\"\n[ndf]\nkind = \"mixture\"\n\
        lobes = [{ kind = \"ggx\", alpha = 0.06, weight = 0.6 }, { kind = \"ggx\", alpha = 0.35, weight = 0.4 }]\n\
        [transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.6, 0.3]\nspecular = [0.8, 0.8, 0.8]\n\
        [shadowing]\nkind = \"smith\"\n[diffuse]\nalbedo = [0.05, 0.05, 0.05]\n";
    let truth = Material::from_toml_str(truth_text).unwrap();
    let plan = FastBrdf::with_policy(&truth, Policy::Accurate);
    let table = MerlTable::from_fn(CellPosition::Edge, |wi, wo| plan.eval(wi, wo)).unwrap();
    let merl = dir.join("mix.binary");
    table.write(&merl).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_owned();

    // The defaults, transfer auto and lobes auto (no --lobes given): three families tried, GGX
    // lobes kept, 2 lobes.
    let out = dir.join("auto.toml");
    let o = run(&["fit", &s(&merl), "--samples", "8000", "--out", &s(&out)]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{}\n{stdout}",
        String::from_utf8_lossy(&o.stderr)
    );
    let tried = stdout
        .lines()
        .find(|l| l.starts_with("transfer families tried"))
        .unwrap_or_else(|| panic!("no families line in\n{stdout}"));
    for fam in ["microfacet ", "phong ", "ggx-lobes "] {
        assert!(tried.contains(fam), "{tried}");
    }
    assert!(tried.ends_with("-> ggx-lobes"), "{tried}");
    assert!(stdout.contains("transfer: ggx-lobes; lobes: 2"), "{stdout}");
    assert!(
        stdout.contains(
            "written material vs fitted closed form: relative cos-weighted RMS difference 0.00 %"
        ),
        "{stdout}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("--transfer ggx-lobes"), "{text}");
    assert!(text.contains("kind = \"mixture\""), "{text}");
    // The engine parameters of the report are in the file's comment too.
    let engine = stdout
        .lines()
        .find(|l| l.starts_with("engine (glTF metallic-roughness"))
        .unwrap_or_else(|| panic!("no engine line in {stdout}"));
    assert!(text.contains(&format!("# {engine}\n")), "{text}");

    // --transfer ggx-lobes, and the header's command line re-runs as written.
    let out2 = dir.join("ggx.toml");
    let o = run(&[
        "fit",
        &s(&merl),
        "--lobes",
        "2",
        "--transfer",
        "ggx-lobes",
        "--samples",
        "8000",
        "--out",
        &s(&out2),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&out2).unwrap();
    rerun_header(&text, &dir.join("again.toml"));

    // The fitted closed form, rebuilt from the written material's parameters.
    let m = Material::from_toml_str(&text).unwrap();
    let Ndf::Mixture(mx) = &m.ndf else {
        panic!("not a mixture: {text}")
    };
    let meso_core::transfer::Transfer::Mirror {
        fresnel: meso_core::transfer::Fresnel::Schlick { f0 },
        specular,
    } = m.transfer
    else {
        panic!("not a Schlick mirror: {text}")
    };
    let fitted = LobeGgxParams {
        lobes: mx
            .lobes()
            .iter()
            .zip(mx.d_weights())
            .map(|(l, c)| GgxLobe {
                distribution: l.microfacet.distribution,
                alpha: l.microfacet.alpha_x,
                d_weight: *c,
            })
            .collect(),
        f0,
        specular,
        albedo: m.diffuse,
    };
    let rows = pairs(200);
    let mut csv = String::from("theta_i,phi_i,theta_o,phi_o\n");
    for (i, o) in &rows {
        let (ti, pi) = meso_core::frame::spherical_angles(*i);
        let (to, po) = meso_core::frame::spherical_angles(*o);
        csv += &format!(
            "{:?},{:?},{:?},{:?}\n",
            ti.to_degrees(),
            pi.to_degrees(),
            to.to_degrees(),
            po.to_degrees()
        );
    }
    let pairs_csv = dir.join("pairs.csv");
    std::fs::write(&pairs_csv, csv).unwrap();
    let values = dir.join("values.csv");
    let o = run(&[
        "brdf",
        &s(&out2),
        "--pairs",
        &s(&pairs_csv),
        "--out",
        &s(&values),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got = std::fs::read_to_string(&values).unwrap();
    let mut n = 0;
    for line in got.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let wi = spherical_direction_deg(v[0], v[1]);
        let wo = spherical_direction_deg(v[2], v[3]);
        let want = fitted.eval(wi, wo);
        let t = plan.eval(wi, wo);
        for c in 0..3 {
            assert!(
                (v[4 + c] - want[c]).abs() <= 1e-6 * want[c],
                "{line}: meso brdf {} vs fitted closed form {}",
                v[4 + c],
                want[c]
            );
            // And the fit recovered the truth.
            assert!(
                (v[4 + c] - t[c]).abs() <= 1e-3 * t[c],
                "{line}: {} vs truth {}",
                v[4 + c],
                t[c]
            );
        }
        n += 1;
    }
    assert_eq!(n, rows.len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `meso fit --transfer student-t-lobes` on a MERL table generated from one Student-t lobe
/// (γ = 3.5, heavier-tailed than Beckmann, lighter than GGX): the written material holds a
/// Student-t lobe with γ and α within 1 %, and the header's command line re-runs as written.
#[test]
fn student_t_lobes_fit_recovers_the_tail_exponent() {
    use meso_core::shading::{FastBrdf, Policy};
    let dir = tmpdir("cli-fit", "student-t");
    let truth_text = "form = \"microfacet\"\n[ndf]\nkind = \"mixture\"\n\
        lobes = [{ kind = \"student-t\", gamma = 3.5, alpha = 0.08, weight = 1.0 }]\n\
        [transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.6, 0.3]\nspecular = [0.8, 0.8, 0.8]\n\
        [shadowing]\nkind = \"smith\"\n[diffuse]\nalbedo = [0.05, 0.05, 0.05]\n";
    let truth = Material::from_toml_str(truth_text).unwrap();
    let plan = FastBrdf::with_policy(&truth, Policy::Accurate);
    let table = MerlTable::from_fn(CellPosition::Edge, |wi, wo| plan.eval(wi, wo)).unwrap();
    let merl = dir.join("st.binary");
    table.write(&merl).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_owned();
    let out = dir.join("st.toml");
    let o = run(&[
        "fit",
        &s(&merl),
        "--lobes",
        "1",
        "--transfer",
        "student-t-lobes",
        "--samples",
        "8000",
        "--out",
        &s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("--transfer student-t-lobes"), "{text}");
    let m = Material::from_toml_str(&text).unwrap();
    let meso_core::ndf::Ndf::Mixture(mx) = &m.ndf else {
        panic!("not a mixture: {text}")
    };
    let lobe = &mx.lobes()[0].microfacet;
    let gamma = lobe.distribution.gamma().unwrap_or(f64::NAN);
    assert!((gamma / 3.5 - 1.0).abs() < 0.01, "γ {gamma}: {text}");
    assert!(
        (lobe.alpha_x / 0.08 - 1.0).abs() < 0.01,
        "α {}: {text}",
        lobe.alpha_x
    );
    rerun_header(&text, &dir.join("again.toml"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Rows of a sample CSV from an anisotropic, rotated GGX material: a back-scattering pair at the
/// centre and at one more point of every upper cell of a `n_z × n_phi` grid (when `back`), and
/// `n` pairs over the hemisphere.
fn aniso_csv(path: &Path, n_z: usize, n_phi: usize, back: bool, n: usize) {
    use meso_core::grid::EqualAreaGrid;
    use meso_core::shading::{FastBrdf, Policy};
    use meso_measured::csv::{write_csv, CsvSample};
    use meso_testkit::{rng, uniform2};
    let m = Material::from_toml_str(
        r#"
        form = "microfacet"
        [ndf]
        kind = "ggx"
        alpha_x = 0.25
        alpha_y = 0.5
        [transfer]
        kind = "mirror"
        fresnel = "schlick"
        f0 = [0.9, 0.6, 0.3]
        specular = [0.8, 0.8, 0.8]
        [diffuse]
        albedo = [0.05, 0.1, 0.2]
        "#,
    )
    .unwrap();
    let plan = FastBrdf::with_policy(&m, Policy::Accurate);
    // The material turned by 30° about the normal.
    let rot = glam::DQuat::from_rotation_z(30f64.to_radians());
    let f = |i: DVec3, o: DVec3| plan.eval(rot.inverse() * i, rot.inverse() * o);
    let hemi = |u: [f64; 2]| {
        let z = u[0].max(0.02);
        let r = (1.0 - z * z).sqrt();
        DVec3::new(
            r * (std::f64::consts::TAU * u[1]).cos(),
            r * (std::f64::consts::TAU * u[1]).sin(),
            z,
        )
    };
    let mut r = rng(9);
    let mut rows = Vec::new();
    if back {
        let g = EqualAreaGrid::new(n_z, n_phi);
        for c in n_z / 2 * n_phi..g.len() {
            let u = uniform2(&mut r);
            for w in [g.cell_center(c), g.point_in_cell(c, u[0], u[1])] {
                rows.push(CsvSample::from_dirs(w, w, f(w, w)));
            }
        }
    }
    for _ in 0..n {
        let (i, o) = (hemi(uniform2(&mut r)), hemi(uniform2(&mut r)));
        rows.push(CsvSample::from_dirs(i, o, f(i, o)));
    }
    write_csv(path, &rows).unwrap();
}

#[test]
fn nonparametric_on_anisotropic_samples_writes_a_tabulated_ndf() {
    let dir = tmpdir("cli-fit", "np-aniso");
    let csv = dir.join("aniso.csv");
    aniso_csv(&csv, 64, 16, true, 6000);
    let out = dir.join("np.toml");
    let (csv_s, out_s) = (csv.to_str().unwrap(), out.to_str().unwrap());
    let o = run(&[
        "fit",
        csv_s,
        "--nonparametric",
        "--grid",
        "64,16",
        "--out",
        out_s,
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "meso fit failed: {}\n{stdout}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("non-parametric NDF (2-D): 64 × 16 table"),
        "{stdout}"
    );
    let held = stdout
        .lines()
        .find(|l| l.contains("held out, not fitted ("))
        .unwrap_or_else(|| panic!("no held-out row in\n{stdout}"));
    let v: Vec<f64> = held[held.find(')').unwrap() + 1..]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    // A 64 × 16 table is coarse (its polar cap is 14°): the held-out log error is that of the
    // table's steps, measured 0.01-0.03.
    assert!(v.len() == 6 && v[3..].iter().all(|e| *e < 0.05), "{held}");
    let text = std::fs::read_to_string(&out).unwrap();
    let m = Material::from_toml_str(&text).expect("the output is a valid material");
    assert_eq!(m.ndf.kind(), "tabulated");
    assert!(text.contains("--nonparametric --grid 64,16"), "{text}");
    // The engine parameters (glTF) are reported and written into the file, as for lobe fits.
    let engine = stdout
        .lines()
        .find(|l| l.starts_with("engine (glTF metallic-roughness"))
        .unwrap_or_else(|| panic!("no engine line in {stdout}"));
    assert!(text.contains(&format!("# {engine}\n")), "{text}");

    // Too fine a grid for these back-scattering samples: a clear error, no output.
    let out2 = dir.join("np2.toml");
    let o = run(&[
        "fit",
        csv_s,
        "--nonparametric",
        "--grid",
        "256,64",
        "--out",
        out2.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !out2.exists(), "{stderr}");
    assert!(
        stderr.contains(csv_s) && stderr.contains("back-scattering samples"),
        "{stderr}"
    );
    // No back-scattering samples at all.
    let bare = dir.join("bare.csv");
    aniso_csv(&bare, 64, 16, false, 3000);
    let o = run(&[
        "fit",
        bare.to_str().unwrap(),
        "--nonparametric",
        "--out",
        out2.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !out2.exists(), "{stderr}");
    assert!(stderr.contains("cover 0"), "{stderr}");
    // A bad grid is refused by the argument parser.
    let o = run(&[
        "fit",
        csv_s,
        "--nonparametric",
        "--grid",
        "64",
        "--out",
        out_s,
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("N_Z,N_PHI"));
    let _ = std::fs::remove_dir_all(&dir);
}
