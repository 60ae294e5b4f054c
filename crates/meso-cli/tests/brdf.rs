//! `meso brdf` and `meso ndf` through the binary: the issue's example against an independent
//! quadrature of Eq. 2, and bad input giving one error line, a non-zero exit and no output file.

mod common;
use common::{cmd, tmpdir};

const EXAMPLE: &str = r#"[ndf]
kind = "phong-peaks"            # Eq. 12; weights are normalised to sum to 1
lobes = [
  { axis = [0.0, 0.0],  weight = 0.6, exponent = 40.0 },    # axis = [theta_deg, phi_deg]
  { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },
]
[transfer]
kind = "phong"
exponent = 50.0
specular = [1.0, 0.8, 0.6]
"#;

/// Eq. 2 (multiple-surface form) by a plain midpoint rule in (θ, φ) over the whole sphere, written
/// from the definitions with no meso code at all.
fn independent(i: [f64; 3], o: [f64; 3]) -> f64 {
    let lobes = [
        ([0.0, 0.0, 1.0], 0.6, 40.0),
        (
            {
                let (t, p) = (30f64.to_radians(), 90f64.to_radians());
                [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
            },
            0.4,
            100.0,
        ),
    ];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let h = {
        let s = [i[0] + o[0], i[1] + o[1], i[2] + o[2]];
        let l = dot(s, s).sqrt();
        [s[0] / l, s[1] / l, s[2] / l]
    };
    let (nt, np) = (1500, 3000);
    let mut sum = 0.0;
    for a in 0..nt {
        let t = std::f64::consts::PI * (a as f64 + 0.5) / nt as f64;
        for b in 0..np {
            let p = 2.0 * std::f64::consts::PI * (b as f64 + 0.5) / np as f64;
            let m = [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
            let mi = dot(m, i);
            if mi <= 0.0 {
                continue;
            }
            let n: f64 = lobes
                .iter()
                .map(|(ax, w, e)| {
                    w * (e + 2.0) / (8.0 * std::f64::consts::PI)
                        * ((1.0 + dot(*ax, m)) / 2.0).powf(e / 2.0)
                })
                .sum();
            sum += n * dot(m, h).max(0.0).powf(50.0) * mi * t.sin();
        }
    }
    sum * (std::f64::consts::PI / nt as f64) * (2.0 * std::f64::consts::PI / np as f64) / i[2]
}

#[test]
fn brdf_matches_an_independent_quadrature_within_one_percent() {
    let d = tmpdir("cli-brdf", "ok");
    std::fs::write(d.join("m.toml"), EXAMPLE).unwrap();
    let rows = [
        (0.0, 0.0, 0.0, 0.0),
        (30.0, 0.0, 30.0, 180.0),
        (45.0, 90.0, 20.0, 250.0),
        (60.0, 200.0, 40.0, 30.0),
    ];
    let mut csv = String::from("theta_i,phi_i,theta_o,phi_o\n");
    for r in rows {
        csv += &format!("{},{},{},{}\n", r.0, r.1, r.2, r.3);
    }
    std::fs::write(d.join("p.csv"), csv).unwrap();
    let st = cmd()
        .arg("brdf")
        .arg(d.join("m.toml"))
        .arg("--pairs")
        .arg(d.join("p.csv"))
        .arg("--out")
        .arg(d.join("o.csv"))
        .status()
        .unwrap();
    assert!(st.success());
    let out = std::fs::read_to_string(d.join("o.csv")).unwrap();
    let mut lines = out.lines();
    assert_eq!(lines.next().unwrap(), "theta_i,phi_i,theta_o,phi_o,r,g,b");
    for (line, r) in lines.zip(rows) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(&v[..4], &[r.0, r.1, r.2, r.3]);
        let dir = |t: f64, p: f64| {
            let (t, p) = (t.to_radians(), p.to_radians());
            [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
        };
        let want = independent(dir(r.0, r.1), dir(r.2, r.3));
        assert!(
            (v[4] / want - 1.0).abs() < 0.01,
            "{line}: r {} vs {want}",
            v[4]
        );
        assert!((v[5] / v[4] - 0.8).abs() < 1e-6 && (v[6] / v[4] - 0.6).abs() < 1e-6);
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn bad_inputs_fail_cleanly() {
    let d = tmpdir("cli-brdf", "bad");
    std::fs::write(d.join("m.toml"), EXAMPLE).unwrap();
    std::fs::write(d.join("bad.toml"), "[ndf]\nkind = \"phong-peaks\"\nlobes = [{ axis = [0, 0], weight = nan, exponent = 1 }]\n[transfer]\nkind = \"lambert\"\n").unwrap();
    std::fs::write(
        d.join("p.csv"),
        "theta_i,phi_i,theta_o,phi_o\n10,0,10,180\n",
    )
    .unwrap();
    std::fs::write(
        d.join("nan.csv"),
        "theta_i,phi_i,theta_o,phi_o\n10,0,NaN,180\n",
    )
    .unwrap();
    std::fs::write(
        d.join("short.csv"),
        "theta_i,phi_i,theta_o,phi_o\n10,0,10\n",
    )
    .unwrap();
    std::fs::write(
        d.join("below.csv"),
        "theta_i,phi_i,theta_o,phi_o\n10,0,120,0\n",
    )
    .unwrap();
    std::fs::write(d.join("empty.csv"), "").unwrap();
    std::fs::write(d.join("binary.csv"), [0xff, 0xfe, 0x00, 0x41]).unwrap();
    let cases = [
        ("bad.toml", "p.csv", "weight"),
        ("missing.toml", "p.csv", "missing.toml"),
        ("m.toml", "nan.csv", "line 2"),
        ("m.toml", "short.csv", "line 2"),
        ("m.toml", "below.csv", "above the surface"),
        ("m.toml", "empty.csv", "empty"),
        ("m.toml", "binary.csv", "UTF-8"),
        ("m.toml", "nothere.csv", "nothere.csv"),
    ];
    for (m, p, needle) in cases {
        let out = d.join("out.csv");
        let o = cmd()
            .arg("brdf")
            .arg(d.join(m))
            .arg("--pairs")
            .arg(d.join(p))
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(!o.status.success(), "{m} {p}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "one error line: {err}");
        assert!(err.contains(needle), "{m} {p}: `{err}` lacks `{needle}`");
        assert!(!err.contains("panicked"));
        assert!(!out.exists(), "{m} {p}: partial output left");
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn ndf_stats_and_plot() {
    let d = tmpdir("cli-brdf", "ndf");
    std::fs::write(d.join("m.toml"), EXAMPLE).unwrap();
    let o = cmd()
        .args(["ndf", "stats"])
        .arg(d.join("m.toml"))
        .arg("--json")
        .output()
        .unwrap();
    assert!(o.status.success());
    let s = String::from_utf8(o.stdout).unwrap();
    let integral: f64 = s
        .split("\"integral\":")
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((integral - 1.0).abs() < 1e-3, "{s}");
    let png = d.join("n.png");
    assert!(cmd()
        .args(["ndf", "plot"])
        .arg(d.join("m.toml"))
        .arg("--out")
        .arg(&png)
        .status()
        .unwrap()
        .success());
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    std::fs::remove_dir_all(&d).unwrap();
}
