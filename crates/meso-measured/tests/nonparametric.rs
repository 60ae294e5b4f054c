//! The non-parametric NDF fit (`meso_measured::nonparametric`) against known materials: a MERL
//! table written from a radial-NDF material (GGX-shaped, with a broad tail) and from an analytic
//! GGX material must give back their NDF, Fresnel, specular scale and albedo.

use meso_core::material::Material;
use meso_core::ndf::Ndf;
use meso_core::shading::{FastBrdf, Policy};
use meso_measured::merl::{CellPosition, MerlTable};
use meso_measured::nonparametric::{fit, material_toml};
use meso_measured::samples::{MerlSampling, SampleSet};
use std::f64::consts::{FRAC_PI_2, PI};

/// GGX `D` (microfacet convention) of width `a` at polar angle `t`.
fn ggx(a: f64, t: f64) -> f64 {
    let (a2, c2) = (a * a, t.cos().powi(2));
    a2 / (PI * (c2 * (a2 - 1.0) + 1.0).powi(2))
}

fn table_of(m: &Material) -> MerlTable {
    let plan = FastBrdf::with_policy(m, Policy::Accurate);
    MerlTable::from_fn(CellPosition::Edge, |i, o| plan.eval(i, o)).unwrap()
}

fn data(table: &MerlTable) -> SampleSet {
    let opts = MerlSampling {
        held_out: 20_000,
        ..MerlSampling::default()
    };
    SampleSet::from_merl(table, &opts).0
}

/// Relative error of the fitted NDF (microfacet convention) against `truth(θ)` over θ ≤ `max`.
fn ndf_error(fitted: &Ndf, truth: impl Fn(f64) -> f64, max_deg: f64) -> f64 {
    let p = meso_core::convolution::isotropic_projected_area(fitted, 1.0);
    let mut worst = 0.0f64;
    for k in 0..=60 {
        let t = (f64::from(k) / 60.0).powi(2) * max_deg.to_radians();
        let m = glam::DVec3::new(t.sin(), 0.0, t.cos());
        let (f, w) = (fitted.eval(m) / p, truth(t));
        worst = worst.max((f - w).abs() / w);
    }
    worst
}

#[test]
fn a_ggx_material_is_recovered_with_its_ndf_fresnel_and_albedo() {
    let m = Material::from_toml_str(
        r#"
        form = "microfacet"
        [ndf]
        kind = "ggx"
        alpha_x = 0.15
        alpha_y = 0.15
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
    let table = table_of(&m);
    let d = data(&table);
    let r = fit(&table, &d).unwrap();
    // Measured: the NDF within 0.22 % up to 45° and 0.24 % up to 60°, f0 within 0.05 %, the
    // specular scale within 0.18 %, the albedo within 0.02 %, from the GGX start (the
    // power-iteration start alone settled 0.9 % / 1.4 % off the NDF and 2.1 % off f0).
    let e = ndf_error(&Ndf::Radial(r.ndf.clone()), |t| ggx(0.15, t), 60.0);
    assert!(e < 0.01, "NDF off GGX by {e:.4} (relative, θ ≤ 60°)");
    for c in 0..3 {
        let want_f0 = [0.9, 0.6, 0.3][c];
        let want_rho = [0.05, 0.1, 0.2][c];
        assert!((r.f0[c] - want_f0).abs() < 0.01 * want_f0, "f0 {:?}", r.f0);
        assert!(
            (r.specular[c] - 0.8).abs() < 0.01 * 0.8,
            "specular {:?}",
            r.specular
        );
        assert!(
            (r.albedo[c] - want_rho).abs() < 0.01 * want_rho,
            "albedo {:?}",
            r.albedo
        );
    }
    let h = r.held_out.expect("held-out cells");
    for c in 0..3 {
        assert!(h.low_log[c] < 1e-3, "held-out log error {:?}", h.low_log);
    }
    // The written file parses to the same material.
    let back = Material::from_toml_str(&material_toml(&r, "round trip")).unwrap();
    assert!(matches!(back.ndf, Ndf::Radial(_)));
}

#[test]
fn a_radial_material_with_a_long_tail_is_recovered() {
    // GGX 0.08 core plus 30 % of a broad cosine tail: no parametric family has this shape.
    let theta: Vec<f64> = (0..=90)
        .map(|k| (f64::from(k) / 90.0).powi(2) * FRAC_PI_2)
        .collect();
    let shape = |t: f64| 0.7 * ggx(0.08, t) + 0.3 * t.cos() / PI;
    let deg: Vec<String> = theta
        .iter()
        .map(|t| format!("{:?}", t.to_degrees()))
        .collect();
    let den: Vec<String> = theta.iter().map(|&t| format!("{:?}", shape(t))).collect();
    let toml = format!(
        "form = \"microfacet\"\n[ndf]\nkind = \"radial\"\ntheta = [{}]\ndensity = [{}]\n\
         [transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.04, 0.04, 0.04]\n\
         [diffuse]\nalbedo = [0.3, 0.2, 0.1]\n",
        deg.join(", "),
        den.join(", ")
    );
    let m = Material::from_toml_str(&toml).unwrap();
    let table = table_of(&m);
    let d = data(&table);
    let r = fit(&table, &d).unwrap();
    eprintln!(
        "tail fit: start {}, f0 {:?}, albedo {:?}",
        r.start.name(),
        r.f0,
        r.albedo
    );
    // `shape` integrates to 1 in the microfacet convention up to the tail's horizon cut.
    let truth = Ndf::Radial(r.ndf.clone());
    let scale = {
        let p = meso_core::convolution::isotropic_projected_area(&m.ndf, 1.0);
        let t = 0.2f64;
        let mm = glam::DVec3::new(t.sin(), 0.0, t.cos());
        (m.ndf.eval(mm) / p) / shape(t)
    };
    let e = ndf_error(&truth, |t| shape(t) * scale, 60.0);
    assert!(e < 0.01, "NDF off the truth by {e:.4} (relative, θ ≤ 60°)");
    for c in 0..3 {
        assert!((r.f0[c] - 0.04).abs() < 0.01 * 0.04 + 2e-4, "f0 {:?}", r.f0);
        let want_rho = [0.3, 0.2, 0.1][c];
        assert!(
            (r.albedo[c] - want_rho).abs() < 0.01 * want_rho,
            "albedo {:?}",
            r.albedo
        );
    }
}

#[test]
fn data_without_back_scattering_cells_are_refused() {
    // Every θd = 0 cell missing (negative).
    // Every θd = 0 cell marked "not measured" (negative) in the file's bytes.
    let full = MerlTable::from_fn(CellPosition::Edge, |_, _| [0.1; 3]).unwrap();
    let path = std::env::temp_dir().join(format!("meso-np-{}.binary", std::process::id()));
    full.write(&path).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let n = meso_measured::merl::N_CELLS;
    for ch in 0..3 {
        for ih in 0..90 {
            for ip in 0..180 {
                let k = 12 + 8 * (ch * n + (ih * 90) * 180 + ip);
                bytes[k..k + 8].copy_from_slice(&(-1.0f64).to_le_bytes());
            }
        }
    }
    let table = MerlTable::from_bytes(&bytes).unwrap();
    let d = data(&table);
    let e = fit(&table, &d).unwrap_err().to_string();
    assert!(e.contains("back-scattering"), "{e}");
}
