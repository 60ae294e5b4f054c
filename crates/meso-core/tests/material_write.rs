//! The material writer (`MaterialSpec::to_toml`) against the parser: for generated materials of
//! every NDF kind, transfer, Fresnel, form, masking and quadrature option (random parameters from
//! a seeded generator, plus the edge cases), `parse(to_toml(spec)) == spec` exactly and the
//! re-read material's BRDF equals the original's; every kind the parser accepts has a generator
//! here and a row in docs/material-format.md; the docs' examples round-trip; the layout is the
//! documented one.

use glam::DVec3;
use meso_core::convolution::{Accuracy, Form};
use meso_core::frame::spherical_direction_deg;
use meso_core::grid::EqualAreaGrid;
use meso_core::material::{
    Material, MaterialSpec, NdfSpec, NoExternalNdfs, ShadowingKind, FRESNEL_KINDS, NDF_KINDS,
    TRANSFER_KINDS,
};
use meso_core::ndf::{
    Cylinder, DeltaSum, Distribution, Harmonics, Microfacet, Mixture, Ndf, PhongLobe, PhongPeaks,
    Radial, Sphere, Tabulated, VonMisesFisher, WeightedNormal,
};
use meso_core::transfer::{Fresnel, PhongVariant, Transfer};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use std::path::Path;

fn rng(seed: u64) -> Pcg64 {
    Pcg64::seed_from_u64(seed)
}

/// Log-uniform in `[lo, hi]`.
fn log_uniform(r: &mut Pcg64, lo: f64, hi: f64) -> f64 {
    (lo.ln() + r.random::<f64>() * (hi.ln() - lo.ln()))
        .exp()
        .clamp(lo, hi)
}

/// An axis as a file gives it: from degrees (sometimes round ones, sometimes the poles) or from
/// a vector of any length.
fn axis(r: &mut Pcg64) -> DVec3 {
    match r.random_range(0..5) {
        0 => spherical_direction_deg(
            f64::from(r.random_range(0..=18)) * 10.0,
            f64::from(r.random_range(-36..=72)) * 10.0,
        ),
        1 => spherical_direction_deg(r.random_range(0.0..=180.0), r.random_range(-360.0..720.0)),
        2 => [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            spherical_direction_deg(0.0, 45.0),
            spherical_direction_deg(180.0, 0.0),
        ][r.random_range(0..5)],
        // A unit vector the constructors keep as it is (its computed length is exactly 1),
        // scaled by a power of two: the writer cannot reproduce every unit vector, because
        // the NDF constructors normalise again what the parser normalised (module docs of
        // `material::write`).
        _ => loop {
            let a = DVec3::new(
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
                r.random_range(-1.0..1.0),
            )
            .normalize();
            if a.is_finite() && a.length() == 1.0 {
                break a * 2f64.powi(r.random_range(-8..8));
            }
        },
    }
}

/// Weights ≥ 0 with a positive sum; some zero, some equal.
fn weights(r: &mut Pcg64, n: usize) -> Vec<f64> {
    let mut w: Vec<f64> = (0..n)
        .map(|_| match r.random_range(0..6) {
            0 => 0.0,
            1 => 1.0,
            2 => f64::from(r.random_range(1..10)) / 10.0,
            _ => log_uniform(r, 1e-6, 1e3),
        })
        .collect();
    if w.iter().sum::<f64>() <= 0.0 {
        w[0] = 1.0;
    }
    w
}

fn distribution(r: &mut Pcg64) -> Distribution {
    match r.random_range(0..3) {
        0 => Distribution::Ggx,
        1 => Distribution::Beckmann,
        _ => student_t(r),
    }
}

/// A Student-t distribution with γ anywhere in its range (the ends included).
fn student_t(r: &mut Pcg64) -> Distribution {
    use meso_core::ndf::student_t::{MAX_GAMMA, MIN_GAMMA};
    let gamma = match r.random_range(0..5) {
        0 => MIN_GAMMA,
        1 => MAX_GAMMA,
        _ => log_uniform(r, MIN_GAMMA, MAX_GAMMA),
    };
    Distribution::StudentT { gamma }
}

fn microfacet(r: &mut Pcg64) -> Microfacet {
    let lo = meso_core::ndf::microfacet::MIN_ALPHA;
    let a = |r: &mut Pcg64| match r.random_range(0..6) {
        0 => lo,
        1 => 10.0,
        _ => log_uniform(r, lo, 10.0),
    };
    let ax = a(r);
    let ay = if r.random::<bool>() { ax } else { a(r) };
    Microfacet::new(distribution(r), ax, ay).unwrap()
}

fn rgb(r: &mut Pcg64, max: f64) -> [f64; 3] {
    [0; 3].map(|_| match r.random_range(0..5) {
        0 => 0.0,
        1 => max,
        _ => r.random_range(0.0..=max),
    })
}

/// A random NDF of `kind` (one of [`NDF_KINDS`]); panics for a kind with no generator, so that
/// a kind added to the parser fails [`every_parser_kind_has_a_generator_and_a_doc_row`] until
/// it is generated here (and written by the writer).
fn ndf_of_kind(kind: &str, r: &mut Pcg64) -> NdfSpec {
    let inline = |n: Ndf| NdfSpec::Inline(n);
    match kind {
        "phong-peaks" => {
            let n = r.random_range(1..6);
            let w = weights(r, n);
            let lobes = w
                .into_iter()
                .map(|w| {
                    let e = match r.random_range(0..5) {
                        0 => 0.0,
                        1 => 1e7,
                        _ => log_uniform(r, 1e-3, 1e7),
                    };
                    PhongLobe::new(axis(r), w, e)
                })
                .collect();
            inline(Ndf::PhongPeaks(PhongPeaks::new(lobes).unwrap()))
        }
        "deltas" => {
            let n = r.random_range(1..9);
            let w = weights(r, n);
            let normals = w
                .into_iter()
                .map(|weight| WeightedNormal {
                    normal: axis(r),
                    weight,
                })
                .collect();
            inline(Ndf::Deltas(DeltaSum::new(normals).unwrap()))
        }
        "sphere" => inline(Ndf::Sphere(Sphere)),
        "cylinder" => {
            let a = axis(r);
            let half = r.random::<bool>() && (a.z / a.length()).abs() < 0.99;
            inline(Ndf::Cylinder(Cylinder::new(a, half).unwrap()))
        }
        "vmf" => {
            let kappa = log_uniform(r, 1e-6, 1e7);
            inline(Ndf::VonMisesFisher(
                VonMisesFisher::new(axis(r), kappa).unwrap(),
            ))
        }
        "beckmann" | "ggx" | "student-t" => {
            let mut m = microfacet(r);
            m = Microfacet::new(
                match kind {
                    "ggx" => Distribution::Ggx,
                    "beckmann" => Distribution::Beckmann,
                    _ => student_t(r),
                },
                m.alpha_x,
                m.alpha_y,
            )
            .unwrap();
            inline(Ndf::Microfacet(m))
        }
        "mixture" => {
            let n = r.random_range(1..7);
            let w = weights(r, n);
            let lobes = w.into_iter().map(|w| (microfacet(r), w)).collect();
            inline(Ndf::Mixture(Mixture::new(lobes).unwrap()))
        }
        "harmonics" => {
            let lmax = r.random_range(0..5);
            let mut c: Vec<f64> = (0..(lmax + 1) * (lmax + 1))
                .map(|_| r.random_range(-0.3..0.3))
                .collect();
            c[0] = log_uniform(r, 1e-3, 1e3);
            inline(Ndf::Harmonics(Harmonics::from_coeffs(lmax, c).unwrap()))
        }
        "tabulated" => {
            let grid = EqualAreaGrid::new(r.random_range(1..9), r.random_range(1..13));
            let mut v: Vec<f64> = (0..grid.len())
                .map(|_| {
                    if r.random_range(0..4) == 0 {
                        0.0
                    } else {
                        log_uniform(r, 1e-6, 1e3)
                    }
                })
                .collect();
            v[0] += 1.0;
            inline(Ndf::Tabulated(Tabulated::from_values(grid, v).unwrap()))
        }
        "radial" => {
            // Node angles as a file gives them: degrees, 0 first, increasing, at most 90.
            let n = r.random_range(2..14);
            let mut deg = vec![0.0];
            while deg.len() < n {
                let last: f64 = deg[deg.len() - 1];
                if last >= 89.0 {
                    break;
                }
                let next = if r.random::<bool>() {
                    (last + f64::from(r.random_range(1..8))).min(90.0)
                } else {
                    last + r.random_range(0.0..(90.0 - last) / 2.0)
                };
                if next > last {
                    deg.push(next);
                } else {
                    break;
                }
            }
            let theta: Vec<f64> = deg.iter().map(|d| d.to_radians()).collect();
            let mut density: Vec<f64> = theta
                .iter()
                .map(|_| log_uniform(r, 1e-4, 1e4) * f64::from(r.random_range(0..3)))
                .collect();
            density[0] += 1.0;
            inline(Ndf::Radial(Radial::new(theta, density).unwrap()))
        }
        "heightmap" | "map" => {
            let mut table = toml::Table::new();
            table.insert("kind".into(), toml::Value::String(kind.into()));
            table.insert("file".into(), toml::Value::String("maps/a b.png".into()));
            if kind == "heightmap" {
                table.insert("texel_size".into(), toml::Value::Float(r.random()));
                table.insert("max_lobes".into(), toml::Value::Integer(4));
                table.insert("represent".into(), toml::Value::String("facets".into()));
            } else {
                table.insert(
                    "texel".into(),
                    toml::Value::Array(vec![toml::Value::Integer(3), toml::Value::Integer(5)]),
                );
            }
            NdfSpec::External {
                kind: kind.into(),
                file: Path::new("dir").join("maps/a b.png"),
                table,
            }
        }
        other => panic!(
            "no generator for the NDF kind \"{other}\": add one here (and check that \
             MaterialSpec::to_toml writes it)"
        ),
    }
}

fn fresnel_of_kind(kind: &str, r: &mut Pcg64) -> Fresnel {
    match kind {
        "none" => Fresnel::None,
        "dielectric" => Fresnel::Dielectric {
            eta: log_uniform(r, 1e-3, 100.0),
        },
        "conductor" => Fresnel::Conductor {
            eta: rgb(r, 5.0),
            k: rgb(r, 8.0),
        },
        "schlick" => Fresnel::Schlick { f0: rgb(r, 1.0) },
        other => panic!("no generator for the Fresnel kind \"{other}\""),
    }
}

fn transfer_of_kind(kind: &str, r: &mut Pcg64) -> Transfer {
    let fresnel = FRESNEL_KINDS[r.random_range(0..FRESNEL_KINDS.len())];
    match kind {
        "phong" => Transfer::Phong {
            exponent: match r.random_range(0..4) {
                0 => 0.0,
                1 => 1e7,
                _ => log_uniform(r, 1e-3, 1e7),
            },
            specular: rgb(r, 1e6),
            variant: if r.random::<bool>() {
                PhongVariant::Half
            } else {
                PhongVariant::Reflect
            },
        },
        "lambert" => Transfer::Lambert {
            albedo: rgb(r, 1.0),
        },
        "mirror" => Transfer::Mirror {
            fresnel: fresnel_of_kind(fresnel, r),
            specular: rgb(r, 1.0),
        },
        "microfacet" => Transfer::Microfacet {
            distribution: microfacet(r),
            fresnel: fresnel_of_kind(fresnel, r),
        },
        other => panic!("no generator for the transfer kind \"{other}\""),
    }
}

const NAMES: [&str; 5] = [
    "plain",
    "quotes \" and \\ backslash",
    "tab\tand\nnewline",
    "ünïcødé — κ",
    "",
];

/// The NDF as its constructor rebuilds it from its own numbers, when that is the NDF itself: the
/// rescalings of weights and densities (and of axes) are idempotent there. Far from always
/// otherwise: normalised weights need not sum to exactly 1 in floating point, and then the
/// parser's rescaling moves them by an ulp whatever numbers the writer picks (see
/// [`rescaled_lists_of_any_ndf_read_back_within_rounding`]).
fn settled(n: &Ndf) -> bool {
    let again = match n {
        Ndf::PhongPeaks(p) => Ndf::PhongPeaks(PhongPeaks::new(p.lobes().to_vec()).unwrap()),
        Ndf::Deltas(d) => Ndf::Deltas(DeltaSum::new(d.normals().to_vec()).unwrap()),
        Ndf::Mixture(m) => Ndf::Mixture(
            Mixture::new(m.lobes().iter().map(|l| (l.microfacet, l.weight)).collect()).unwrap(),
        ),
        Ndf::Tabulated(t) => {
            Ndf::Tabulated(Tabulated::from_values(t.grid(), t.values().to_vec()).unwrap())
        }
        Ndf::Radial(r) => {
            Ndf::Radial(Radial::new(r.theta().to_vec(), r.values().to_vec()).unwrap())
        }
        Ndf::Harmonics(h) => {
            Ndf::Harmonics(Harmonics::from_coeffs(h.lmax(), h.coeffs().to_vec()).unwrap())
        }
        other => other.clone(),
    };
    &again == n
}

/// An NDF of `kind` that its constructor keeps as it is ([`settled`]).
fn settled_ndf_of_kind(kind: &str, r: &mut Pcg64) -> NdfSpec {
    loop {
        let n = ndf_of_kind(kind, r);
        if matches!(&n, NdfSpec::Inline(x) if !settled(x)) {
            continue;
        }
        return n;
    }
}

/// A random material of NDF kind `kind`, every other option drawn at random.
fn spec_of_kind(kind: &str, r: &mut Pcg64) -> MaterialSpec {
    let ndf = settled_ndf_of_kind(kind, r);
    let singular = matches!(&ndf, NdfSpec::Inline(n) if n.is_singular());
    let mut t = TRANSFER_KINDS[r.random_range(0..TRANSFER_KINDS.len())];
    if singular && t == "mirror" {
        t = "microfacet"; // the parser refuses a mirror on deltas or a cylinder
    }
    let shadowing = [
        None,
        Some(ShadowingKind::None),
        Some(ShadowingKind::Smith),
        Some(ShadowingKind::Horizon),
        Some(ShadowingKind::Visibility),
        Some(ShadowingKind::VisibilityInterreflected),
    ][r.random_range(0..6)];
    MaterialSpec {
        name: if r.random::<bool>() {
            Some(NAMES[r.random_range(0..NAMES.len())].to_owned())
        } else {
            None
        },
        ndf,
        transfer: transfer_of_kind(t, r),
        diffuse: if r.random::<bool>() {
            [0.0; 3]
        } else {
            rgb(r, 1.0)
        },
        form: [None, Some(Form::MultipleSurface), Some(Form::Microfacet)][r.random_range(0..3)],
        shadowing,
        accuracy: if r.random::<bool>() {
            Accuracy::default()
        } else {
            Accuracy {
                radial: r.random_range(2..=128),
                azimuth: r.random_range(4..=1024),
            }
        },
    }
}

fn assert_round_trip(spec: &MaterialSpec) -> String {
    let text = spec.to_toml();
    let back = MaterialSpec::parse(&text, Path::new("dir"))
        .unwrap_or_else(|e| panic!("the written file does not parse: {e}\n{text}"));
    assert_eq!(&back, spec, "the file reads back differently:\n{text}");
    text
}

#[test]
fn random_materials_of_every_kind_read_back_exactly() {
    let mut r = rng(0x70_6d_6c);
    let mut count = 0;
    for kind in NDF_KINDS {
        for _ in 0..60 {
            let spec = spec_of_kind(kind, &mut r);
            assert_round_trip(&spec);
            count += 1;
        }
    }
    assert_eq!(count, 60 * NDF_KINDS.len());
}

#[test]
fn comments_come_first_and_are_ignored() {
    let spec = spec_of_kind("mixture", &mut rng(3));
    let text = spec.to_toml_with_comment("meso fit a.binary --lobes 2\n\nsecond line");
    assert!(
        text.starts_with("# meso fit a.binary --lobes 2\n# \n# second line\n"),
        "{text}"
    );
    assert_eq!(MaterialSpec::parse(&text, Path::new("dir")).unwrap(), spec);
}

/// Many pairs of directions above the surface (some grazing, some equal, some mirrored).
fn pairs(r: &mut Pcg64, n: usize) -> Vec<(DVec3, DVec3)> {
    let mut v = vec![
        (DVec3::Z, DVec3::Z),
        (
            spherical_direction_deg(60.0, 0.0),
            spherical_direction_deg(60.0, 180.0),
        ),
        (
            spherical_direction_deg(89.0, 10.0),
            spherical_direction_deg(30.0, 200.0),
        ),
    ];
    while v.len() < n {
        let d = |r: &mut Pcg64| {
            spherical_direction_deg(r.random_range(0.0..89.9), r.random_range(0.0..360.0))
        };
        v.push((d(r), d(r)));
    }
    v
}

#[test]
fn the_re_read_material_has_the_same_brdf() {
    let mut r = rng(0xb7df);
    let mut built = 0;
    for kind in NDF_KINDS {
        let mut tries = 0;
        loop {
            tries += 1;
            let mut spec = spec_of_kind(kind, &mut r);
            // Few quadrature nodes keep the test quick; the option itself is exercised above.
            spec.accuracy = Accuracy {
                radial: 6,
                azimuth: 8,
            };
            let Ok(a) = spec.clone().build(&NoExternalNdfs) else {
                assert!(tries < 200, "no buildable {kind} material in 200 draws");
                if matches!(spec.ndf, NdfSpec::External { .. }) {
                    break; // height maps need meso-maps' resolver
                }
                continue;
            };
            let text = assert_round_trip(&spec);
            let b = Material::from_toml_str(&text).unwrap();
            for (i, o) in pairs(&mut r, 40) {
                let (fa, fb) = (a.brdf(i, o), b.brdf(i, o));
                assert!(
                    fa == fb || fa.iter().zip(fb).all(|(x, y)| x.is_nan() && y.is_nan()),
                    "{kind}: BRDF {fa:?} vs {fb:?} at {i} {o}\n{text}"
                );
            }
            built += 1;
            break;
        }
    }
    assert_eq!(built, NDF_KINDS.len() - 2, "every inline kind evaluated");
}

#[test]
fn every_parser_kind_has_a_generator_and_a_doc_row() {
    let docs = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/material-format.md"),
    )
    .unwrap();
    let mut r = rng(1);
    for kind in NDF_KINDS {
        let spec = spec_of_kind(kind, &mut r);
        let got = match &spec.ndf {
            NdfSpec::Inline(n) => n.kind().to_owned(),
            NdfSpec::External { kind, .. } => kind.clone(),
        };
        assert_eq!(&got, kind);
        let text = assert_round_trip(&spec);
        assert!(text.contains(&format!("kind = \"{kind}\"")), "{text}");
        let row = format!("| `{kind}`");
        let alt = format!("`{kind}` |");
        assert!(
            docs.contains(&row) || docs.contains(&alt) || docs.contains(&format!(", `{kind}` |")),
            "docs/material-format.md has no row for the NDF kind `{kind}`"
        );
    }
    for kind in TRANSFER_KINDS {
        assert!(docs.contains(&format!("| `{kind}` |")), "{kind}");
        let t = transfer_of_kind(kind, &mut r);
        let spec = MaterialSpec {
            transfer: t,
            ..spec_of_kind("ggx", &mut r)
        };
        assert!(assert_round_trip(&spec).contains(&format!("kind = \"{kind}\"")));
    }
    for kind in FRESNEL_KINDS {
        assert!(docs.contains(&format!("\"{kind}\"")), "{kind}");
        let spec = MaterialSpec {
            transfer: Transfer::Mirror {
                fresnel: fresnel_of_kind(kind, &mut r),
                specular: [0.5; 3],
            },
            ..spec_of_kind("ggx", &mut r)
        };
        let text = assert_round_trip(&spec);
        assert!(
            *kind == "none" || text.contains(&format!("fresnel = \"{kind}\"")),
            "{text}"
        );
    }
}

#[test]
fn the_docs_examples_read_back_exactly() {
    let docs = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/material-format.md"),
    )
    .unwrap();
    let mut n = 0;
    for block in docs.split("```toml").skip(1) {
        let text = block.split("```").next().unwrap();
        let spec = MaterialSpec::parse(text, Path::new(".")).unwrap();
        assert_round_trip(&spec);
        n += 1;
    }
    assert!(n >= 4, "{n} examples");
}

#[test]
fn the_layout_is_the_documented_one() {
    let text = "[ndf]\nkind = \"phong-peaks\"\nlobes = [\n  { axis = [0, 0], weight = 0.6, \
                exponent = 40 },\n  { axis = [30, 90], weight = 0.4, exponent = 100 },\n]\n\
                [transfer]\nkind = \"phong\"\nexponent = 50\nspecular = [1, 0.8, 0.6]\n";
    let spec = MaterialSpec::parse(text, Path::new(".")).unwrap();
    assert_eq!(
        spec.to_toml(),
        "[ndf]\nkind = \"phong-peaks\"\nlobes = [\n  { axis = [0.0, 0.0], weight = 0.6, \
         exponent = 40.0 },\n  { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },\n]\n\n\
         [transfer]\nkind = \"phong\"\nexponent = 50.0\nspecular = [1.0, 0.8, 0.6]\n"
    );
    let full = MaterialSpec {
        name: Some("a \"b\"".into()),
        form: Some(Form::Microfacet),
        shadowing: Some(ShadowingKind::Smith),
        diffuse: [0.1, 0.2, 0.3],
        accuracy: Accuracy {
            radial: 16,
            azimuth: 24,
        },
        ..spec
    };
    assert_eq!(
        full.to_toml(),
        "name = \"a \\\"b\\\"\"\nform = \"microfacet\"\n\n[ndf]\nkind = \"phong-peaks\"\n\
         lobes = [\n  { axis = [0.0, 0.0], weight = 0.6, exponent = 40.0 },\n  \
         { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },\n]\n\n[transfer]\n\
         kind = \"phong\"\nexponent = 50.0\nspecular = [1.0, 0.8, 0.6]\n\n[shadowing]\n\
         kind = \"smith\"\n\n[diffuse]\nalbedo = [0.1, 0.2, 0.3]\n\n[quadrature]\nradial = 16\n\
         azimuth = 24\n"
    );
}

#[test]
fn material_to_spec_writes_a_file_that_builds_the_same_material() {
    let mut r = rng(9);
    for kind in ["phong-peaks", "deltas", "mixture", "radial", "vmf"] {
        let spec = MaterialSpec {
            shadowing: None,
            accuracy: Accuracy {
                radial: 6,
                azimuth: 8,
            },
            ..spec_of_kind(kind, &mut r)
        };
        let Ok(m) = spec.build(&NoExternalNdfs) else {
            continue;
        };
        let s = m.to_spec().unwrap();
        assert_eq!(s.form, Some(m.form));
        let back = Material::from_toml_str(&s.to_toml()).unwrap();
        assert_eq!(back.ndf, m.ndf);
        assert_eq!(back.transfer, m.transfer);
        assert_eq!(
            (back.diffuse, back.form, back.shadowing),
            (m.diffuse, m.form, m.shadowing)
        );
        for (i, o) in pairs(&mut r, 20) {
            assert_eq!(back.brdf(i, o), m.brdf(i, o));
        }
    }
    // Masking that needs the height map cannot be written inline.
    let mut m = Material::new(
        Ndf::surface_normal(),
        Transfer::Lambert { albedo: [0.5; 3] },
    );
    m.shadowing = ShadowingKind::Horizon;
    assert!(m.to_spec().is_err());
}

/// Weights and densities that the constructors' rescaling does not leave as they are: the
/// writer's search finds numbers that read back exactly for most, and the rest read back within
/// a few ulps (relative 1e-15; a radial NDF's mass is computed
/// to about 1e-14, worse with nodes very close together: 1e-9 here).
#[test]
fn rescaled_lists_of_any_ndf_read_back_within_rounding() {
    let mut r = rng(0x5ca1e);
    for kind in [
        "phong-peaks",
        "deltas",
        "mixture",
        "tabulated",
        "radial",
        "harmonics",
    ] {
        let (mut exact, mut total) = (0, 0);
        for _ in 0..200 {
            let NdfSpec::Inline(n) = ndf_of_kind(kind, &mut r) else {
                unreachable!()
            };
            let spec = MaterialSpec {
                ndf: NdfSpec::Inline(n.clone()),
                transfer: transfer_of_kind("lambert", &mut r),
                ..spec_of_kind("sphere", &mut r)
            };
            let back = MaterialSpec::parse(&spec.to_toml(), Path::new(".")).unwrap();
            let NdfSpec::Inline(m) = &back.ndf else {
                unreachable!()
            };
            total += 1;
            if m == &n {
                exact += 1;
                continue;
            }
            let close = |a: &[f64], b: &[f64], tol: f64| {
                a.len() == b.len()
                    && a.iter()
                        .zip(b)
                        .all(|(x, y)| (x - y).abs() <= tol * x.abs().max(y.abs()))
            };
            let ok = match (m, &n) {
                (Ndf::PhongPeaks(a), Ndf::PhongPeaks(b)) => {
                    let wa: Vec<f64> = a.lobes().iter().map(|l| l.weight).collect();
                    let wb: Vec<f64> = b.lobes().iter().map(|l| l.weight).collect();
                    close(&wa, &wb, 1e-15)
                        && a.lobes().iter().zip(b.lobes()).all(|(x, y)| {
                            (x.axis - y.axis).length() < 1e-15 && x.exponent == y.exponent
                        })
                }
                (Ndf::Deltas(a), Ndf::Deltas(b)) => {
                    let wa: Vec<f64> = a.normals().iter().map(|l| l.weight).collect();
                    let wb: Vec<f64> = b.normals().iter().map(|l| l.weight).collect();
                    close(&wa, &wb, 1e-15)
                        && a.normals()
                            .iter()
                            .zip(b.normals())
                            .all(|(x, y)| (x.normal - y.normal).length() < 1e-15)
                }
                (Ndf::Mixture(a), Ndf::Mixture(b)) => {
                    let wa: Vec<f64> = a.lobes().iter().map(|l| l.weight).collect();
                    let wb: Vec<f64> = b.lobes().iter().map(|l| l.weight).collect();
                    close(&wa, &wb, 1e-15)
                        && a.lobes()
                            .iter()
                            .zip(b.lobes())
                            .all(|(x, y)| x.microfacet == y.microfacet)
                }
                (Ndf::Tabulated(a), Ndf::Tabulated(b)) => {
                    a.grid() == b.grid() && close(a.values(), b.values(), 1e-15)
                }
                (Ndf::Radial(a), Ndf::Radial(b)) => {
                    a.theta() == b.theta() && close(a.values(), b.values(), 1e-9)
                }
                (Ndf::Harmonics(a), Ndf::Harmonics(b)) => {
                    a.lmax() == b.lmax() && close(a.coeffs(), b.coeffs(), 1e-15)
                }
                _ => false,
            };
            assert!(ok, "{kind}: {n:?}\nread back as\n{m:?}");
        }
        println!("{kind}: {exact}/{total} exact");
        if kind != "radial" {
            assert!(
                exact * 10 >= total * 8,
                "{kind}: only {exact}/{total} exact"
            );
        }
    }
}

/// Axes read from whole degrees are written as those degrees (φ in [0, 360)); the pole as
/// `[0.0, 0.0]`.
#[test]
fn axes_from_degrees_are_written_as_those_degrees() {
    let mut normals = vec![WeightedNormal {
        normal: spherical_direction_deg(0.0, 123.0),
        weight: 1.0,
    }];
    let mut expect = vec!["[0.0, 0.0]".to_owned()];
    for t in (15..=165).step_by(15) {
        for p in (0..360).step_by(30) {
            normals.push(WeightedNormal {
                normal: spherical_direction_deg(f64::from(t), f64::from(p)),
                weight: 1.0,
            });
            expect.push(format!("[{t}.0, {p}.0]"));
        }
    }
    let spec = MaterialSpec {
        ndf: NdfSpec::Inline(Ndf::Deltas(DeltaSum::new(normals).unwrap())),
        transfer: Transfer::Lambert { albedo: [0.5; 3] },
        ..spec_of_kind("sphere", &mut rng(5))
    };
    let text = assert_round_trip(&spec);
    let written: Vec<&str> = text
        .lines()
        .filter_map(|l| l.split("axis = ").nth(1))
        .map(|l| &l[..l.find(']').unwrap() + 1])
        .collect();
    assert_eq!(written, expect);
}

/// The first-column kinds of the table under `heading` in docs/material-format.md.
fn documented_kinds(docs: &str, heading: &str) -> Vec<String> {
    let table = docs.split(heading).nth(1).expect("the heading");
    let mut kinds = Vec::new();
    for line in table.lines().skip_while(|l| !l.starts_with('|')) {
        if !line.starts_with('|') {
            break;
        }
        let first = line.split('|').nth(1).unwrap_or("");
        kinds.extend(first.split('`').skip(1).step_by(2).map(str::to_owned));
    }
    kinds.retain(|k| k != "kind");
    kinds
}

/// The other way round: every kind the docs list is one the parser knows (so a kind added to
/// the parser and the docs but not to `NDF_KINDS` fails here, and through `NDF_KINDS` fails
/// the generator test until the writer is checked for it).
#[test]
fn every_documented_kind_is_in_the_kinds_lists_and_known_to_the_parser() {
    let docs = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/material-format.md"),
    )
    .unwrap();
    let ndf = documented_kinds(&docs, "## `[ndf]` kinds");
    assert!(ndf.len() >= 12, "{ndf:?}");
    for k in &ndf {
        assert!(
            NDF_KINDS.contains(&k.as_str()),
            "documented NDF kind {k} not in NDF_KINDS"
        );
        let text = format!("[ndf]\nkind = \"{k}\"\n[transfer]\nkind = \"lambert\"\n");
        if let Err(e) = MaterialSpec::parse(&text, Path::new(".")) {
            assert!(!e.0.contains("unknown NDF kind"), "{k}: {e}");
        }
    }
    let transfer = documented_kinds(&docs, "## `[transfer]` kinds");
    assert_eq!(transfer.len(), TRANSFER_KINDS.len(), "{transfer:?}");
    for k in &transfer {
        assert!(TRANSFER_KINDS.contains(&k.as_str()), "{k}");
    }
    // And the parser refuses what is not in the list, naming the list.
    let e = MaterialSpec::parse(
        "[ndf]\nkind = \"nope\"\n[transfer]\nkind = \"lambert\"\n",
        Path::new("."),
    )
    .unwrap_err();
    assert!(e.0.contains(&NDF_KINDS.join(", ")), "{e}");
}
