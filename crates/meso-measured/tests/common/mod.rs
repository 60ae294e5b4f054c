//! Shared by the lobe-mixture round trips (`ggx_lobes.rs`, `student_t_lobes.rs`): the truth
//! written as a `kind = "mixture"` material under a Schlick mirror and Lambert, sampled like a
//! MERL table, and the worst relative error of a fit against it.

use meso_core::material::Material;
use meso_core::ndf::{Distribution, Ndf};
use meso_core::shading::{FastBrdf, Policy};
use meso_measured::merl::{CellPosition, MerlTable};
use meso_measured::model::LobeGgxParams;
use meso_measured::samples::{MerlSampling, SampleSet};

/// A lobe of the truth: `(distribution, α, Eq. 1 weight)`.
pub type Lobe = (Distribution, f64, f64);

/// A microfacet mixture material: lobes `(distribution, α, Eq. 1 weight)`.
pub fn material(lobes: &[Lobe], f0: [f64; 3], specular: f64, albedo: [f64; 3]) -> Material {
    let l: Vec<String> = lobes
        .iter()
        .map(|(d, a, w)| match d.gamma() {
            Some(g) => {
                format!("{{ kind = \"student-t\", gamma = {g}, alpha = {a}, weight = {w} }}")
            }
            None => format!("{{ kind = \"{}\", alpha = {a}, weight = {w} }}", d.name()),
        })
        .collect();
    Material::from_toml_str(&format!(
        "form = \"microfacet\"\n[ndf]\nkind = \"mixture\"\nlobes = [{}]\n[transfer]\nkind = \"mirror\"\n\
         fresnel = \"schlick\"\nf0 = {f0:?}\nspecular = [{specular}, {specular}, {specular}]\n\
         [shadowing]\nkind = \"smith\"\n[diffuse]\nalbedo = {albedo:?}\n",
        l.join(", ")
    ))
    .unwrap()
}

/// The material sampled like a MERL table (30 000 cells fitted, 100 000 held out).
pub fn merl_samples(m: &Material) -> SampleSet {
    let f = FastBrdf::with_policy(m, Policy::Accurate);
    let table = MerlTable::from_fn(CellPosition::Edge, |i, o| f.eval(i, o)).unwrap();
    SampleSet::from_merl(
        &table,
        &MerlSampling {
            held_out: 100_000,
            ..MerlSampling::default()
        },
    )
    .0
}

/// `|a − b| / |b|`.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The worst relative error of the fitted parameters against the truth: α and Eq. 1 weights
/// (lobes sorted by α; the families must match, and γ too for Student-t lobes), f0, specular
/// and albedo per channel; with what it was.
pub fn recovery_error(got: &LobeGgxParams, truth: &Material) -> (f64, String) {
    let Ndf::Mixture(mx) = &truth.ndf else {
        panic!("truth is not a mixture")
    };
    let mut want: Vec<(f64, f64, Distribution)> = mx
        .lobes()
        .iter()
        .map(|l| (l.microfacet.alpha_x, l.weight, l.microfacet.distribution))
        .collect();
    want.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut have: Vec<(f64, f64, Distribution)> = got
        .lobes
        .iter()
        .zip(got.eq1_weights())
        .map(|(l, w)| (l.alpha, w, l.distribution))
        .collect();
    have.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert_eq!(have.len(), want.len());
    let meso_core::transfer::Transfer::Mirror {
        fresnel: meso_core::transfer::Fresnel::Schlick { f0 },
        specular,
    } = truth.transfer
    else {
        panic!("truth is not a Schlick mirror")
    };
    let mut worst = (0.0, String::new());
    let mut check = |what: &str, g: f64, w: f64| {
        let e = rel(g, w);
        if e > worst.0 {
            worst = (e, format!("{what}: {g} vs {w}"));
        }
    };
    for ((ga, gw, gd), (wa, ww, wd)) in have.iter().zip(&want) {
        // A Student-t lobe with γ = 2 is a GGX lobe (the same D and Λ): on noiseless data the
        // two tie to rounding, and which one the fit keeps is decided by rounding.
        let gamma_of = |d: &Distribution| match d {
            Distribution::Ggx => Some(2.0),
            _ => d.gamma(),
        };
        let ggx_like =
            |d: &Distribution| matches!(d, Distribution::Ggx | Distribution::StudentT { .. });
        if !(gd.same_family(*wd) || ggx_like(gd) && ggx_like(wd)) {
            return (f64::INFINITY, format!("distributions {have:?} vs {want:?}"));
        }
        if let (Some(gg), Some(wg)) = (gamma_of(gd), gamma_of(wd)) {
            check("gamma", gg, wg);
        }
        check("alpha", *ga, *wa);
        check("weight", *gw, *ww);
    }
    for c in 0..3 {
        check("f0", got.f0[c], f0[c]);
        check("specular", got.specular[c], specular[c]);
        check("albedo", got.albedo[c], truth.diffuse[c]);
    }
    worst
}

/// Asserts the fit within `tol` of the truth ([`recovery_error`]) and returns its error.
pub fn assert_recovered(got: &LobeGgxParams, truth: &Material, tol: f64) -> f64 {
    let (e, what) = recovery_error(got, truth);
    eprintln!("worst relative error {e:.2e} ({what})");
    assert!(e < tol, "worst relative error {e} ({what}) in {got:?}");
    e
}
