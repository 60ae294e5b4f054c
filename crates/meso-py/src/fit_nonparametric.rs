//! `meso.fit_nonparametric`: the non-parametric NDF of measured data, as `meso fit DATA
//! --nonparametric [--grid N_Z,N_PHI]`: 1-D in θm from a MERL table
//! (meso_measured::nonparametric), 2-D over an equal-area grid from a sample CSV
//! (meso_measured::nonparametric_aniso); returns the material and a report.

use crate::error::{meso_err, require_input_not_output};
use crate::fit::{chain_message, engine_dict, errors_dict};
use crate::material::Material;
use meso_measured::fit::FitErrors;
use meso_measured::job;
use meso_measured::nonparametric::{self, MAX_THETA_H_DEG};
use meso_measured::nonparametric_aniso::{self, AnisoOptions, MAX_THETA_DEG};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Fit the non-parametric NDF of measured `data`, as `meso fit DATA --nonparametric [--grid
/// N_Z,N_PHI]` (docs/measured.md, "Non-parametric NDF"), with Smith masking derived from it,
/// Schlick `f0`, the mirror `specular` scale and a Lambert albedo fitted alongside.
///
/// - A MERL binary (isotropic): the NDF tabulated in θm (`[ndf] kind = "radial"`) from the
///   back-scattering cells; `grid` must be `None`. Report keys `nodes` (θh bins used),
///   `max_theta_h_deg`, `rms_theta_deg`, `start` (`"power-iteration"` or `"ggx"`).
/// - A sample CSV (anisotropic): the NDF tabulated over an equal-area grid of `grid = (n_z,
///   n_phi)` cells (`[ndf] kind = "tabulated"`, default 512 × 64; `n_z` even) from the
///   back-scattering samples. Report keys `grid`, `back_samples`, `cells_covered`,
///   `cells_needed` (upper cells up to `max_theta_deg`).
///
/// Both report `description`, `kind` (`"radial"` or `"tabulated"`), `f0`, `specular`,
/// `albedo`, `specular_at_limit`, `engine` (glTF metallic–roughness parameters of the best
/// single GGX + Lambert fit, as `meso.fit`'s, also written into the file as a comment), the errors per channel (`ngan_l2` in 1/sr, `low_log`) on the
/// `fitted` and `held_out` samples (None without any), and `toml`, the material file (the CLI's
/// bytes but for the comment lines). `out`: also write the file (atomically).
#[pyfunction]
#[pyo3(signature = (data, out = None, samples = 30_000, grid = None))]
pub fn fit_nonparametric(
    py: Python<'_>,
    data: PathBuf,
    out: Option<PathBuf>,
    samples: usize,
    grid: Option<(usize, usize)>,
) -> PyResult<(Material, Py<PyDict>)> {
    require_input_not_output(&data, out.as_deref())?;
    let name = data.display().to_string();
    let (fitted, engine, description, n_fit, n_held) = py
        .detach(|| {
            let d = job::load(&data, samples).map_err(|e| chain_message(&e))?;
            let fitted = match (&d.merl, grid) {
                (Some(table), None) => Fitted::Radial(
                    nonparametric::fit(table, &d.samples).map_err(|e| format!("{name}: {e}"))?,
                ),
                (Some(_), Some(_)) => {
                    return Err(format!(
                        "{name}: grid is the 2-D table of a sample CSV; a MERL table is isotropic \
                         and gets the 1-D NDF in θm (leave grid = None)"
                    ))
                }
                (None, g) => {
                    let opts = g.map_or_else(AnisoOptions::default, |(n_z, n_phi)| AnisoOptions {
                        n_z,
                        n_phi,
                    });
                    Fitted::Tabulated(
                        nonparametric_aniso::fit(&d.samples, &opts)
                            .map_err(|e| format!("{name}: {e}"))?,
                        opts,
                    )
                }
            };
            let engine = meso_measured::engine::fit_engine(&d.samples, &Default::default())
                .map_err(|e| format!("{name}: engine parameters: {e}"))?;
            Ok((
                fitted,
                engine,
                d.description.clone(),
                d.samples.samples.len(),
                d.samples.held_out.len(),
            ))
        })
        .map_err(meso_err)?;
    let d = PyDict::new(py);
    d.set_item("description", &description)?;
    let counts = (n_fit, n_held);
    let mut text = match &fitted {
        Fitted::Radial(r) => {
            d.set_item("kind", "radial")?;
            d.set_item("nodes", r.nodes)?;
            d.set_item("max_theta_h_deg", MAX_THETA_H_DEG)?;
            d.set_item("rms_theta_deg", r.ndf.rms_theta().to_degrees())?;
            d.set_item("start", r.start.name())?;
            let comment = format!(
                "meso fit {name} --nonparametric --samples {samples}\nnon-parametric NDF ({} nodes): {description}",
                r.nodes
            );
            let terms = (r.f0, r.specular, r.albedo, r.specular_at_limit);
            set_terms(py, &d, terms, &r.fitted, r.held_out.as_ref(), counts)?;
            nonparametric::material_toml(r, &comment)
        }
        Fitted::Tabulated(r, o) => {
            d.set_item("kind", "tabulated")?;
            d.set_item("grid", (o.n_z, o.n_phi))?;
            d.set_item("max_theta_deg", MAX_THETA_DEG)?;
            d.set_item("back_samples", r.back_samples)?;
            d.set_item("cells_covered", r.cells_covered)?;
            d.set_item("cells_needed", r.cells_needed)?;
            let comment = format!(
                "meso fit {name} --nonparametric --grid {},{}\nnon-parametric NDF ({} × {} table): {description}",
                o.n_z, o.n_phi, o.n_z, o.n_phi
            );
            let terms = (r.f0, r.specular, r.albedo, r.specular_at_limit);
            set_terms(py, &d, terms, &r.fitted, r.held_out.as_ref(), counts)?;
            nonparametric_aniso::material_toml(r, &comment)
        }
    };
    engine.annotate(&mut text);
    d.set_item("engine", engine_dict(py, &engine)?)?;
    let material = Material::from_text(py, &text)?;
    if let Some(out) = &out {
        meso_core::io::write_atomic(out, text.as_bytes())
            .map_err(|e| meso_err(format!("{}: cannot write: {e}", out.display())))?;
    }
    d.set_item("toml", text)?;
    Ok((material, d.unbind()))
}

/// The fit of either route.
enum Fitted {
    Radial(nonparametric::NonParametric),
    Tabulated(nonparametric_aniso::NonParametricAniso, AnisoOptions),
}

/// The report keys both routes share: the mirror's Schlick terms `(f0, specular, albedo,
/// specular_at_limit)` and the error tables on `counts = (fitted, held out)` samples.
fn set_terms(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    terms: ([f64; 3], [f64; 3], [f64; 3], bool),
    fitted: &FitErrors,
    held_out: Option<&FitErrors>,
    counts: (usize, usize),
) -> PyResult<()> {
    let (f0, specular, albedo, at_limit) = terms;
    d.set_item("f0", f0.to_vec())?;
    d.set_item("specular", specular.to_vec())?;
    d.set_item("albedo", albedo.to_vec())?;
    d.set_item("specular_at_limit", at_limit)?;
    d.set_item("fitted", errors_dict(py, fitted, counts.0)?)?;
    match held_out {
        Some(h) => d.set_item("held_out", errors_dict(py, h, counts.1)?)?,
        None => d.set_item("held_out", py.None())?,
    }
    Ok(())
}
