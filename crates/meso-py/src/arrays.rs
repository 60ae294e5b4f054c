//! numpy arrays in and out: shapes and values checked once, with messages that name the argument.

use crate::error::value_err;
use glam::DVec3;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// A 2-D float64 array argument: any array-like numpy converts (lists, other dtypes) is accepted;
/// anything else raises `TypeError` saying what a 2-D array was expected for and what came
/// (`argument 'wi': expected a 2-D array of numbers, one row per item (one direction:
/// [[x, y, z]]; …); got an array of shape (3,)`), which pyo3 prefixes with the argument's name.
pub struct Arr<'py>(numpy::PyArrayLike2<'py, f64, numpy::AllowTypeChange>);

impl<'py> std::ops::Deref for Arr<'py> {
    type Target = PyReadonlyArray2<'py, f64>;

    fn deref(&self) -> &PyReadonlyArray2<'py, f64> {
        &self.0
    }
}

impl<'a, 'py> FromPyObject<'a, 'py> for Arr<'py> {
    type Error = PyErr;

    fn extract(ob: pyo3::Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        match numpy::PyArrayLike2::<f64, numpy::AllowTypeChange>::extract(ob) {
            Ok(a) => Ok(Arr(a)),
            Err(_) => Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "expected a 2-D array of numbers, a list of rows (one direction: [[x, y, z]]; a \
                 height map: rows × columns); got {}",
                describe(&ob)
            ))),
        }
    }
}

/// What an argument that is not a 2-D array of numbers is: its Python type, with the shape
/// numpy reads it as (`a list of shape (3,)`, `a str`, `None`), and the dtype where it is not
/// a number's.
fn describe(ob: &Bound<'_, PyAny>) -> String {
    if ob.is_none() {
        return "None".to_string();
    }
    let kind = ob
        .get_type()
        .name()
        .map_or_else(|_| "object".to_string(), |n| n.to_string());
    let array = ob
        .py()
        .import("numpy")
        .and_then(|np| np.call_method1("asarray", (ob,)));
    let Ok(a) = array else {
        return format!("{} {kind}", article(&kind));
    };
    let (Ok(shape), Ok(ndim)) = (a.getattr("shape"), a.getattr("ndim")) else {
        return format!("{} {kind}", article(&kind));
    };
    if ndim.extract::<usize>().unwrap_or(0) == 0 {
        return format!("{} {kind}", article(&kind));
    }
    let numeric = a
        .getattr("dtype")
        .and_then(|d| d.getattr("kind"))
        .and_then(|k| k.extract::<String>())
        .is_ok_and(|k| matches!(k.as_str(), "f" | "i" | "u" | "b"));
    let dtype = if numeric {
        String::new()
    } else {
        a.getattr("dtype")
            .map(|d| format!(" and dtype {d}"))
            .unwrap_or_default()
    };
    format!("{} {kind} of shape {shape}{dtype}", article(&kind))
}

/// "a" or "an" before `word` (as read aloud: "an ndarray").
fn article(word: &str) -> &'static str {
    if word.starts_with(['a', 'e', 'i', 'o', 'u']) || word == "ndarray" {
        "an"
    } else {
        "a"
    }
}

/// Rows of an `(N, 3)` float64 array as unit directions: each row normalised, non-finite or
/// zero-length rows refused with their index ([`unit_row`]).
pub fn directions(name: &str, a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<DVec3>> {
    let v = flat(name, a, 3)?;
    (0..v.len() / 3)
        .map(|k| unit_row(name, &v, k).map_err(value_err))
        .collect()
}

/// The values of an `(N, cols)` float64 array, row-major, every value finite.
pub fn rows(name: &str, a: &PyReadonlyArray2<'_, f64>, cols: usize) -> PyResult<Vec<f64>> {
    let v = flat(name, a, cols)?.into_owned();
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(value_err(format!(
            "{name}[{}, {}] = {}: not a finite number",
            k / cols,
            k % cols,
            v[k]
        )));
    }
    Ok(v)
}

/// The values of an `(N, cols)` float64 array of uniform random numbers, row-major: each
/// finite and in [0, 1] (a sampler's input; outside it, the warped direction means nothing).
pub fn uniforms(name: &str, a: &PyReadonlyArray2<'_, f64>, cols: usize) -> PyResult<Vec<f64>> {
    let v = rows(name, a, cols)?;
    if let Some(k) = v.iter().position(|x| !(0.0..=1.0).contains(x)) {
        return Err(value_err(format!(
            "{name}[{}, {}] = {}: random numbers must lie in [0, 1]",
            k / cols,
            k % cols,
            v[k]
        )));
    }
    Ok(v)
}

/// Two arrays of the same number of rows.
pub fn same_rows(a: (&str, usize), b: (&str, usize)) -> PyResult<()> {
    if a.1 != b.1 {
        return Err(value_err(format!(
            "{} has {} rows but {} has {}",
            a.0, a.1, b.0, b.1
        )));
    }
    Ok(())
}

/// `(N, 3)` float64 array from RGB or vector rows.
pub fn array_n3<'py>(py: Python<'py>, v: &[[f64; 3]]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat: Vec<f64> = v.iter().flatten().copied().collect();
    PyArray1::from_vec(py, flat).reshape([v.len(), 3])
}

/// `(N,)` float64 array.
pub fn array_n<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_vec(py, v)
}

/// The values of an `(N, cols)` float64 array as one row-major slice: borrowed when the array is
/// C-contiguous, copied otherwise.
pub fn flat<'a>(
    name: &str,
    a: &'a PyReadonlyArray2<'_, f64>,
    cols: usize,
) -> PyResult<std::borrow::Cow<'a, [f64]>> {
    let shape = a.shape();
    if shape[1] != cols {
        return Err(value_err(format!(
            "{name}: expected an array of shape (N, {cols}), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    Ok(match a.as_slice() {
        Ok(s) => std::borrow::Cow::Borrowed(s),
        Err(_) => std::borrow::Cow::Owned(a.as_array().iter().copied().collect()),
    })
}

/// Row `k` of a flat `(N, 3)` slice as a unit direction; the error names the argument and row,
/// as [`directions`] does.
pub fn unit_row(name: &str, v: &[f64], k: usize) -> Result<DVec3, String> {
    let r = &v[3 * k..3 * k + 3];
    let d = DVec3::new(r[0], r[1], r[2]);
    let l2 = d.length_squared();
    // The common case first: a finite unit row (a NaN or infinity makes `l2` fail this test).
    if (l2 - 1.0).abs() <= 1e-12 {
        return Ok(d);
    }
    if let Some(j) = r.iter().position(|x| !x.is_finite()) {
        return Err(format!("{name}[{k}, {j}] = {}: not a finite number", r[j]));
    }
    let l = l2.sqrt();
    if !(l.is_finite() && l > 1e-12) {
        return Err(format!(
            "{name}[{k}] = [{}, {}, {}]: not a direction (zero length or not finite)",
            r[0], r[1], r[2]
        ));
    }
    Ok(d / l)
}
