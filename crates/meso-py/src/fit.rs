//! `meso.fit` and `meso.fit_samples`: fit a measured BRDF (MERL binary, sample CSV or sample
//! arrays) with a sum of Phong peaks, as `meso fit` does (meso_measured::job), returning the
//! material and a report.

use crate::arrays::{directions, rows, same_rows, Arr};
use crate::error::{meso_err, require_input_not_output, value_err};
use crate::material::Material;
use meso_measured::fit::{FitErrors, LobeAxes};
use meso_measured::job::{self, Data, Transfer};
use meso_measured::metric::Metric;
use meso_measured::samples::{Sample, SampleSet};
use meso_measured::workflow::{self, FitReport, FitRequest};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The one-line message of an error and its causes, each cause once (as the CLI prints it).
pub(crate) fn chain_message(e: &(dyn std::error::Error + 'static)) -> String {
    let mut msg = String::new();
    let mut cur = Some(e);
    while let Some(c) = cur {
        let text = c.to_string();
        if !text.is_empty() && !msg.contains(&text) {
            if !msg.is_empty() {
                msg.push_str(": ");
            }
            msg.push_str(&text);
        }
        cur = c.source();
    }
    msg
}

/// The options as the CLI spells them.
struct Options {
    /// The number of lobes, or the most tried with `auto_k`.
    k: usize,
    /// `lobes = "auto"`: cut at `meso_measured::job::auto_lobes`.
    auto_k: bool,
    /// The families to try (two for `"auto"`).
    transfers: Vec<Transfer>,
    metric: Metric,
    axes: Option<LobeAxes>,
}

/// A number of lobes 1–6, or `"auto"` (`(most tried, auto)`).
fn parse_lobes(lobes: &Bound<'_, PyAny>) -> PyResult<(u32, bool)> {
    if lobes.extract::<String>().is_ok_and(|s| s == "auto") {
        return Ok((job::AUTO_LOBES_MAX as u32, true));
    }
    match lobes.extract::<u32>() {
        Ok(k) if (1..=6).contains(&k) => Ok((k, false)),
        _ => Err(value_err(format!(
            "lobes = {}: expected 1 to 6, or \"auto\"",
            lobes.repr().map_or_else(|_| "?".into(), |r| r.to_string())
        ))),
    }
}

/// `lobes`: a number 1–6 or `"auto"` (the default, as `meso fit`'s).
fn options(
    lobes: Option<&Bound<'_, PyAny>>,
    transfer: &str,
    metric: &str,
    axes: &str,
) -> PyResult<Options> {
    let (lobes, auto_k) = if let Some(lobes) = lobes {
        parse_lobes(lobes)?
    } else {
        (job::AUTO_LOBES_MAX as u32, true)
    };
    let transfers = match transfer {
        "auto" => Transfer::ALL.to_vec(),
        t => match Transfer::from_name(t) {
            Some(t) => vec![t],
            None => {
                return Err(value_err(format!(
                "transfer = {t:?}: expected \"auto\", \"phong\", \"microfacet\", \"ggx-lobes\" or \"student-t-lobes\""
            )))
            }
        },
    };
    let metric = match metric {
        "both" => Metric::Both,
        "log" => Metric::LowLog,
        "ngan" => Metric::NganL2,
        m => {
            return Err(value_err(format!(
                "metric = {m:?}: expected \"both\", \"log\" or \"ngan\""
            )))
        }
    };
    let axes = match axes {
        "auto" => None,
        "normal" => Some(LobeAxes::Normal),
        "free" => Some(LobeAxes::Free),
        a => {
            return Err(value_err(format!(
                "axes = {a:?}: expected \"auto\", \"normal\" or \"free\""
            )))
        }
    };
    Ok(Options {
        k: lobes as usize,
        auto_k,
        transfers,
        metric,
        axes,
    })
}

/// Fit `data` as `meso fit` does (the library's workflow, without the CLI's exact check and
/// baselines) and build the material text with the CLI's comment (`name` is the data as written
/// there).
fn run_fit(data: &Data, name: &str, o: &Options) -> Result<FitReport, String> {
    let request = FitRequest {
        data_name: name,
        lobes: o.k,
        auto_lobes: o.auto_k,
        candidates: &o.transfers,
        metric: o.metric,
        axes: o.axes,
        per_channel: false,
        baselines: false,
        exact_cells: 0,
    };
    workflow::run(data, &request, &mut |_| {}).map_err(|e| chain_message(&e))
}

/// The report's `engine` entry: glTF metallic–roughness parameters of the best single GGX +
/// Lambert fit (`meso_measured::engine`).
pub(crate) fn engine_dict<'py>(
    py: Python<'py>,
    engine: &meso_measured::engine::EngineParams,
) -> PyResult<Bound<'py, PyDict>> {
    let e = PyDict::new(py);
    e.set_item("base_color", engine.base_color)?;
    e.set_item("metallic", engine.metallic)?;
    e.set_item("roughness", engine.roughness)?;
    e.set_item("alpha", engine.alpha)?;
    e.set_item("diffuse", engine.diffuse)?;
    e.set_item("specular_f0", engine.specular_f0)?;
    e.set_item("mismatch", engine.mismatch)?;
    e.set_item("held_out_low_log", engine.fit.held_out.map(|h| h.low_log))?;
    Ok(e)
}

pub(crate) fn errors_dict<'py>(
    py: Python<'py>,
    e: &FitErrors,
    count: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("samples", count)?;
    d.set_item("ngan_l2", e.ngan_l2.to_vec())?;
    d.set_item("low_log", e.low_log.to_vec())?;
    Ok(d)
}

/// The material and report of a fit; the material file written to `out` when given.
fn finish(py: Python<'_>, f: FitReport, out: Option<PathBuf>) -> PyResult<(Material, Py<PyDict>)> {
    let [ch] = f.channels.as_slice() else {
        return Err(meso_err("internal error: one pass of lobes expected"));
    };
    let (_, r) = ch.last();
    let material = Material::from_text(py, &ch.text)?;
    if let Some(out) = &out {
        meso_core::io::write_atomic(out, ch.text.as_bytes())
            .map_err(|e| meso_err(format!("{}: cannot write: {e}", out.display())))?;
    }
    let d = PyDict::new(py);
    d.set_item("description", &f.description)?;
    d.set_item("lobes", ch.fits.len())?;
    d.set_item("model", &r.model)?;
    d.set_item("transfer", ch.transfer.name())?;
    let tried = PyDict::new(py);
    for t in &ch.tried {
        tried.set_item(t.transfer.name(), t.error)?;
    }
    d.set_item("transfers_tried", tried)?;
    d.set_item("engine", engine_dict(py, &f.engine)?)?;
    d.set_item("metric", f.metric.name())?;
    d.set_item("axes", f.axes.name())?;
    d.set_item("fitted", errors_dict(py, &f.fitted, f.fitted_count)?)?;
    match &f.held_out {
        Some(h) => d.set_item("held_out", errors_dict(py, h, f.held_out_count)?)?,
        None => d.set_item("held_out", py.None())?,
    }
    d.set_item("iterations", r.iterations)?;
    d.set_item("starts", r.starts)?;
    d.set_item("seconds", r.seconds)?;
    d.set_item("toml", &ch.text)?;
    Ok((material, d.unbind()))
}

/// Fit a measured BRDF with a sum of `lobes` lobes (default `"auto"`), as `meso fit DATA --lobes K --transfer T
/// --metric M --axes A`: `data` is a MERL binary or a sample CSV (`theta_i,phi_i,theta_o,phi_o,
/// r,g,b`). Returns `(material, report)`; `report` holds the data's description, the number of
/// lobes, the transfer family kept (`transfer = "auto"` fits both and keeps the one with the lower
/// held-out error in the metric, `transfers_tried` maps each to that error), `engine`: glTF
/// metallic-roughness parameters (`base_color`, `metallic`, `roughness`, GGX `alpha`) of the best
/// single GGX + Lambert fit (meso_measured::engine), the model, and the
/// errors per channel (`ngan_l2` in 1/sr, `low_log`) of the fitted
/// closed form on the fitted and the held-out samples (`held_out` is None without any). `out`:
/// also write the material file (atomically), the CLI's bytes but for the fit time in its comment.
#[pyfunction]
#[pyo3(signature = (data, lobes = None, transfer = "auto", metric = "both", axes = "auto", out = None, samples = 30_000))]
#[allow(clippy::too_many_arguments)]
pub fn fit(
    py: Python<'_>,
    data: PathBuf,
    lobes: Option<&Bound<'_, PyAny>>,
    transfer: &str,
    metric: &str,
    axes: &str,
    out: Option<PathBuf>,
    samples: usize,
) -> PyResult<(Material, Py<PyDict>)> {
    let o = options(lobes, transfer, metric, axes)?;
    require_input_not_output(&data, out.as_deref())?;
    let name = data.display().to_string();
    let f = py
        .detach(|| {
            let d = job::load(&data, samples).map_err(|e| chain_message(&e))?;
            run_fit(&d, &name, &o)
        })
        .map_err(meso_err)?;
    finish(py, f, out)
}

/// Fit sample arrays as [`fit`] fits a sample CSV: `wi` (towards the light) and `wo` (towards the
/// viewer) `(N, 3)` directions in the local frame, `values` `(N, 3)` RGB BRDF values in 1/sr.
/// Samples below the horizon are dropped; with 200 or more, every 10th is held out.
#[pyfunction]
#[pyo3(signature = (wi, wo, values, lobes = None, transfer = "auto", metric = "both", axes = "auto", out = None))]
#[allow(clippy::too_many_arguments)]
pub fn fit_samples<'py>(
    py: Python<'py>,
    wi: Arr<'py>,
    wo: Arr<'py>,
    values: Arr<'py>,
    lobes: Option<&Bound<'_, PyAny>>,
    transfer: &str,
    metric: &str,
    axes: &str,
    out: Option<PathBuf>,
) -> PyResult<(Material, Py<PyDict>)> {
    let o = options(lobes, transfer, metric, axes)?;
    let i = directions("wi", &wi)?;
    let w = directions("wo", &wo)?;
    let v = rows("values", &values, 3)?;
    same_rows(("wi", i.len()), ("wo", w.len()))?;
    same_rows(("wi", i.len()), ("values", v.len() / 3))?;
    if let Some(k) = v.iter().position(|x| !x.is_finite() || *x < 0.0) {
        return Err(value_err(format!(
            "values row {}: {} is not a finite non-negative BRDF value",
            k / 3,
            v[k]
        )));
    }
    let set = SampleSet {
        samples: i
            .iter()
            .zip(&w)
            .zip(v.chunks_exact(3))
            .map(|((&wi, &wo), c)| Sample {
                wi,
                wo,
                rgb: [c[0], c[1], c[2]],
                weight: 1.0,
            })
            .collect(),
        cell_size: 0.0,
        held_out: Vec::new(),
    };
    let f = py
        .detach(|| {
            let d =
                job::scattered(set, "sample arrays", "samples").map_err(|e| chain_message(&e))?;
            run_fit(&d, "<arrays>", &o)
        })
        .map_err(meso_err)?;
    finish(py, f, out)
}
