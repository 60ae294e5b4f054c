//! `meso fit` end to end: a MERL file generated from a known lobe model is fitted back, the
//! written material is read by meso-core and reproduces the generating BRDF; bad input fails
//! cleanly with one error line and no output file.

use glam::DVec3;
use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;
use meso_core::ndf::PhongLobe;
use meso_measured::merl::{CellPosition, MerlTable};
use meso_measured::model::LobeParams;
use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-cli-fit-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn meso(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_meso"))
        .args(args)
        .output()
        .expect("meso runs")
}

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
    let dir = temp_dir("merl");
    let merl = write_merl(&dir);
    let out = dir.join("fitted.toml");
    let o = meso(&[
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

    // The written material, read by meso-core and evaluated exactly, against the generating
    // closed form (tolerance: the closed form is within a few % of the exact quadrature for
    // lobes this sharp, plus the fit error).
    let text = std::fs::read_to_string(&out).unwrap();
    let m = Material::from_toml_str(&text).expect("the output is a valid material");
    let t = truth();
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
    let o = meso(&[
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
    let o = meso(&[
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
        let o = meso(&[
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
