//! `meso.fit_nonparametric`: the non-parametric NDF of a MERL table, as `meso fit DATA
//! --nonparametric` (meso_measured::nonparametric), returning the material and a report.

use crate::error::{meso_err, require_exists};
use crate::fit::{chain_message, errors_dict};
use crate::material::Material;
use meso_measured::job;
use meso_measured::nonparametric::{fit, material_toml, MAX_THETA_H_DEG};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Fit the non-parametric NDF of a MERL binary `data`, as `meso fit DATA --nonparametric`: the
/// NDF tabulated in θm (`[ndf] kind = "radial"`) from the back-scattering cells, Smith masking
/// derived from it, Schlick `f0`, the mirror `specular` scale and a Lambert albedo fitted
/// alongside (docs/measured.md, "Non-parametric NDF"). Returns `(material, report)`; `report`
/// holds `description`, `nodes` (θh bins used), `rms_theta_deg`, `f0`, `specular`, `albedo`,
/// `specular_at_limit`, `start` (`"power-iteration"` or `"ggx"`: the start of the kept fit), the
/// errors per channel (`ngan_l2` in 1/sr, `low_log`) on the `fitted` and
/// `held_out` cells (None without any), and `toml`, the material file. `out`: also write the
/// file (atomically).
#[pyfunction]
#[pyo3(signature = (data, out = None, samples = 30_000))]
pub fn fit_nonparametric(
    py: Python<'_>,
    data: PathBuf,
    out: Option<PathBuf>,
    samples: usize,
) -> PyResult<(Material, Py<PyDict>)> {
    require_exists(&data)?;
    if let (Some(out), Ok(d)) = (&out, std::fs::canonicalize(&data)) {
        if std::fs::canonicalize(out).is_ok_and(|o| o == d) {
            return Err(meso_err(format!(
                "{}: the output would overwrite the input data",
                out.display()
            )));
        }
    }
    let name = data.display().to_string();
    let (r, description, n_fit, n_held) = py
        .detach(|| {
            let d = job::load(&data, samples).map_err(|e| chain_message(&e))?;
            let Some(table) = &d.merl else {
                return Err(format!(
                    "{name}: the non-parametric NDF needs a MERL table (it reads the NDF from the \
                     back-scattering cells); this is {}",
                    d.description
                ));
            };
            let r = fit(table, &d.samples).map_err(|e| format!("{name}: {e}"))?;
            Ok((
                r,
                d.description.clone(),
                d.samples.samples.len(),
                d.samples.held_out.len(),
            ))
        })
        .map_err(meso_err)?;
    let comment = format!(
        "meso fit {name} --nonparametric --samples {samples}\nnon-parametric NDF ({} nodes): {description}",
        r.nodes
    );
    let text = material_toml(&r, &comment);
    let material = Material::from_text(&text)?;
    if let Some(out) = &out {
        meso_core::io::write_atomic(out, text.as_bytes())
            .map_err(|e| meso_err(format!("{}: cannot write: {e}", out.display())))?;
    }
    let d = PyDict::new(py);
    d.set_item("description", description)?;
    d.set_item("nodes", r.nodes)?;
    d.set_item("max_theta_h_deg", MAX_THETA_H_DEG)?;
    d.set_item("rms_theta_deg", r.ndf.rms_theta().to_degrees())?;
    d.set_item("f0", r.f0.to_vec())?;
    d.set_item("specular", r.specular.to_vec())?;
    d.set_item("albedo", r.albedo.to_vec())?;
    d.set_item("specular_at_limit", r.specular_at_limit)?;
    d.set_item("start", r.start.name())?;
    d.set_item("fitted", errors_dict(py, &r.fitted, n_fit)?)?;
    match &r.held_out {
        Some(h) => d.set_item("held_out", errors_dict(py, h, n_held)?)?,
        None => d.set_item("held_out", py.None())?,
    }
    d.set_item("toml", text)?;
    Ok((material, d.unbind()))
}
