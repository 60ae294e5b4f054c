//! `meso.material_toml`: a material file from Python values, written by meso's one writer
//! (`meso_core::material::MaterialSpec::to_toml`) after the validation every material file gets.

use crate::error::meso_err;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};
use std::path::Path;

/// A Python value (bool, int, float, str, dict with str keys, sequence, numpy array or scalar)
/// as a TOML value; `path` names it in errors (`ndf.lobes[1].axis`).
fn to_toml(v: &Bound<'_, PyAny>, path: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return v.extract::<i64>().map(toml::Value::Integer).map_err(|_| {
            PyTypeError::new_err(format!("{path}: {v} does not fit in a 64-bit integer"))
        });
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, x) in d.iter() {
            let k: String = k
                .extract()
                .map_err(|_| PyTypeError::new_err(format!("{path}: keys must be strings")))?;
            let sub = format!("{path}.{k}");
            t.insert(k, to_toml(&x, &sub)?);
        }
        return Ok(toml::Value::Table(t));
    }
    // numpy arrays and scalars: their Python values.
    if v.hasattr("tolist")? {
        return to_toml(&v.call_method0("tolist")?, path);
    }
    if let Ok(items) = v.try_iter() {
        let mut a = Vec::new();
        for (k, x) in items.enumerate() {
            a.push(to_toml(&x?, &format!("{path}[{k}]"))?);
        }
        return Ok(toml::Value::Array(a));
    }
    Err(PyTypeError::new_err(format!(
        "{path}: {} cannot be written in a material file",
        v.repr()?
    )))
}

/// The material file text of the given tables (keys as in docs/material-format.md): `ndf` and
/// `transfer` are dicts of the `[ndf]` and `[transfer]` tables (`{"kind": "beckmann", "alpha":
/// 0.1}`), `diffuse` the Lambert albedo (RGB), `form` `"multiple-surface"` or `"microfacet"`,
/// `shadowing` the `[shadowing]` table. The tables are validated as a material file is (a
/// `transfer` is required) and written by `MaterialSpec::to_toml`, so the text reads back to the
/// same material; weights appear normalised as meso reads them. Raises `MesoError` with meso's
/// message for an invalid material, `TypeError` for a value TOML cannot hold.
#[pyfunction]
#[pyo3(signature = (ndf = None, transfer = None, diffuse = None, form = None, shadowing = None, name = None))]
pub fn material_toml(
    ndf: Option<&Bound<'_, PyAny>>,
    transfer: Option<&Bound<'_, PyAny>>,
    diffuse: Option<&Bound<'_, PyAny>>,
    form: Option<&Bound<'_, PyAny>>,
    shadowing: Option<&Bound<'_, PyAny>>,
    name: Option<&Bound<'_, PyAny>>,
) -> PyResult<String> {
    let mut doc = toml::Table::new();
    for (key, value) in [
        ("name", name),
        ("form", form),
        ("ndf", ndf),
        ("transfer", transfer),
        ("shadowing", shadowing),
    ] {
        if let Some(v) = value {
            doc.insert(key.into(), to_toml(v, key)?);
        }
    }
    if let Some(v) = diffuse {
        let mut t = toml::Table::new();
        t.insert("albedo".into(), to_toml(v, "diffuse")?);
        doc.insert("diffuse".into(), toml::Value::Table(t));
    }
    let spec =
        meso_core::material::MaterialSpec::from_table(&doc, Path::new("")).map_err(meso_err)?;
    Ok(spec.to_toml())
}
