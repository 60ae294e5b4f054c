//! The mirror transfer's per-channel `specular` scale: every evaluation path (the exact
//! quadrature of `Material::brdf` and `FastBrdf`, both forms) gives exactly `specular ×` the
//! unscaled specular part, the diffuse term is not scaled, and the parser accepts `[0, 1]` and
//! refuses anything else with a message naming the key.

use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;
use meso_core::shading::FastBrdf;
use meso_core::transfer::Transfer;

const SCALE: [f64; 3] = [0.3, 0.75, 0.05];

/// NDFs and forms the mirror transfer meets: closed-form microfacet D, a vMF, Phong peaks.
fn materials(specular: Option<[f64; 3]>) -> Vec<(String, Material)> {
    let ndfs = [
        "kind = \"beckmann\"\nalpha_x = 0.3\nalpha_y = 0.15",
        "kind = \"ggx\"\nalpha = 0.2",
        "kind = \"vmf\"\naxis = [10.0, 30.0]\nkappa = 40.0",
        "kind = \"phong-peaks\"\nlobes = [ { axis = [0.0, 0.0], weight = 0.7, exponent = 300.0 }, \
         { axis = [20.0, 90.0], weight = 0.3, exponent = 60.0 } ]",
    ];
    let fresnels = [
        "fresnel = \"schlick\"\nf0 = [0.9, 0.5, 0.1]",
        "fresnel = \"dielectric\"\neta = 1.5",
    ];
    let mut out = Vec::new();
    for form in ["microfacet", "multiple-surface"] {
        for ndf in ndfs {
            for fr in fresnels {
                let spec = specular.map_or(String::new(), |s| {
                    format!("specular = [{:?}, {:?}, {:?}]\n", s[0], s[1], s[2])
                });
                let toml = format!(
                    "form = \"{form}\"\n[ndf]\n{ndf}\n[transfer]\nkind = \"mirror\"\n{fr}\n{spec}"
                );
                let m =
                    Material::from_toml_str(&toml).unwrap_or_else(|e| panic!("{toml}\n{}", e.0));
                out.push((toml, m));
            }
        }
    }
    out
}

fn directions() -> Vec<(glam::DVec3, glam::DVec3)> {
    [
        (0.0, 0.0, 0.0, 0.0),
        (30.0, 0.0, 30.0, 180.0),
        (45.0, 90.0, 20.0, 250.0),
        (60.0, 10.0, 50.0, 200.0),
        (75.0, 300.0, 80.0, 110.0),
        (40.0, 0.0, 60.0, 30.0),
    ]
    .iter()
    .map(|&(a, b, c, d)| (spherical_direction_deg(a, b), spherical_direction_deg(c, d)))
    .collect()
}

fn assert_scaled(what: &str, scaled: [f64; 3], plain: [f64; 3], scale: [f64; 3]) {
    for c in 0..3 {
        let want = scale[c] * plain[c];
        assert!(
            (scaled[c] - want).abs() <= 1e-9 * want.abs(),
            "{what} channel {c}: {} vs {} × {}",
            scaled[c],
            scale[c],
            plain[c]
        );
    }
}

#[test]
fn scaled_mirror_is_scale_times_the_plain_one_on_every_path() {
    let plain = materials(None);
    let scaled = materials(Some(SCALE));
    let mut nonzero = 0;
    for ((toml, p), (_, s)) in plain.iter().zip(&scaled) {
        assert!(s.transfer.mirror_reflectance(1.0).is_some());
        let (fp, fs) = (FastBrdf::new(p), FastBrdf::new(s));
        assert_eq!(fp.path(), fs.path(), "{toml}");
        for &(i, o) in &directions() {
            let exact = p.brdf(i, o);
            nonzero += usize::from(exact.iter().all(|&x| x > 1e-6));
            assert_scaled(&format!("quadrature\n{toml}"), s.brdf(i, o), exact, SCALE);
            assert_scaled(
                &format!("{}\n{toml}", fs.path()),
                fs.eval(i, o),
                fp.eval(i, o),
                SCALE,
            );
        }
    }
    // The comparison is not vacuous: most pairs see the specular lobe.
    assert!(nonzero > plain.len() * 3, "{nonzero} non-zero pairs");
}

#[test]
fn the_diffuse_term_is_not_scaled_and_zero_leaves_only_it() {
    let base = "form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha = 0.25\n[transfer]\n\
                kind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.04, 0.04, 0.04]\n";
    let diffuse = "[diffuse]\nalbedo = [0.2, 0.4, 0.6]\n";
    let plain = Material::from_toml_str(&format!("{base}{diffuse}")).unwrap();
    let half =
        Material::from_toml_str(&format!("{base}specular = [0.5, 0.5, 0.5]\n{diffuse}")).unwrap();
    let off = Material::from_toml_str(&format!("{base}specular = [0, 0, 0]\n{diffuse}")).unwrap();
    let d = [0.2, 0.4, 0.6].map(|a| a / std::f64::consts::PI);
    for &(i, o) in &directions() {
        for (path, fp, fh, f0) in [
            (
                "quadrature",
                plain.brdf(i, o),
                half.brdf(i, o),
                off.brdf(i, o),
            ),
            (
                "fast",
                FastBrdf::new(&plain).eval(i, o),
                FastBrdf::new(&half).eval(i, o),
                FastBrdf::new(&off).eval(i, o),
            ),
        ] {
            for c in 0..3 {
                assert!((f0[c] - d[c]).abs() < 1e-15, "{path}: {f0:?} vs {d:?}");
                let want = d[c] + 0.5 * (fp[c] - d[c]);
                assert!(
                    (fh[c] - want).abs() <= 1e-9 * want,
                    "{path}: {} vs {want}",
                    fh[c]
                );
            }
        }
    }
}

#[test]
fn parser_accepts_the_unit_interval_and_refuses_the_rest() {
    let m = |spec: &str| {
        Material::from_toml_str(&format!(
            "form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha = 0.2\n[transfer]\n\
             kind = \"mirror\"\n{spec}"
        ))
    };
    let specular = |r: Result<Material, meso_core::material::MaterialError>| match r {
        Ok(Material {
            transfer: Transfer::Mirror { specular, .. },
            ..
        }) => specular,
        Ok(other) => panic!("not a mirror: {:?}", other.transfer),
        Err(e) => panic!("refused: {}", e.0),
    };
    assert_eq!(specular(m("")), [1.0; 3], "default");
    assert_eq!(specular(m("specular = [0, 1, 0.25]")), [0.0, 1.0, 0.25]);
    assert_eq!(specular(m("specular = [1.0, 1.0, 1.0]")), [1.0; 3]);
    for bad in ["specular = [1.5, 0.5, 0.5]", "specular = [0.5, -0.1, 0.5]"] {
        let e = m(bad).unwrap_err().0;
        assert!(
            e.contains("[transfer] specular") && e.contains("[0, 1]"),
            "{bad}: {e}"
        );
    }
    for bad in [
        "specular = [0.5, 0.5]",
        "specular = [0.5, 0.5, nan]",
        "specular = [0.5, 0.5, inf]",
        "specular = 0.5",
        "specular = [\"a\", 0.5, 0.5]",
    ] {
        let e = m(bad).unwrap_err().0;
        assert!(e.contains("specular"), "{bad}: {e}");
    }
}
