//! Errors across the boundary: meso's messages as Python exceptions.

use pyo3::exceptions::{PyException, PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;
use std::path::Path;

pyo3::create_exception!(
    meso,
    MesoError,
    PyException,
    "An error reported by meso: the message names the file, the field and the problem."
);

/// Any displayable error as a [`MesoError`] (with its source chain).
pub fn meso_err(e: impl std::fmt::Display) -> PyErr {
    MesoError::new_err(format!("{e:#}"))
}

/// A [`ValueError`](PyValueError) with `msg`.
pub fn value_err(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// `FileNotFoundError` for an input path that does not exist (the message names it), so callers
/// can catch the usual Python exception; other problems are left to the reader.
pub fn require_exists(path: &Path) -> PyResult<()> {
    if std::fs::symlink_metadata(path).is_err() {
        return Err(PyFileNotFoundError::new_err(format!(
            "{}: no such file",
            path.display()
        )));
    }
    Ok(())
}

/// [`require_exists`] for the input `data`, and a [`MesoError`] when the output `out` names the
/// same file (the fits write their material there; the data must never be overwritten).
pub fn require_input_not_output(data: &Path, out: Option<&Path>) -> PyResult<()> {
    require_exists(data)?;
    if let (Some(out), Ok(d)) = (out, std::fs::canonicalize(data)) {
        if std::fs::canonicalize(out).is_ok_and(|o| o == d) {
            return Err(meso_err(format!(
                "{}: the output would overwrite the input data",
                out.display()
            )));
        }
    }
    Ok(())
}

/// Set the memory budget of this process (bytes, or a size with a K, M, G or T suffix: `"8G"`),
/// as the CLI's `--memory-budget`: work whose estimated peak memory is larger is refused with a
/// `MesoError` before it starts. The default is the CLI's (4G, or less on small machines, or the
/// `MESO_MEMORY_BUDGET` environment variable). Raises `ValueError` with the CLI's message for
/// a size that is not one (0, negative, an unknown suffix), `TypeError` for another type.
#[pyfunction]
pub fn set_memory_budget(size: &Bound<'_, PyAny>) -> PyResult<()> {
    // Every number goes through the CLI's parser, so 0, -1 and 0.5 get its message (a
    // ValueError), not a silent default or a TypeError.
    let text = if size.is_instance_of::<pyo3::types::PyBool>() {
        return Err(value_err(format!(
            "not a size (a number of bytes, or a string such as \"8G\"): {size}"
        )));
    } else if size.is_instance_of::<pyo3::types::PyInt>()
        || size.is_instance_of::<pyo3::types::PyFloat>()
    {
        size.str()?.to_string()
    } else if let Ok(s) = size.extract::<String>() {
        s
    } else {
        return Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "a memory budget is a number of bytes or a string such as \"8G\", got {}",
            size.repr()?
        )));
    };
    let bytes = meso_core::budget::parse_size(&text).map_err(value_err)?;
    meso_core::budget::set_budget(bytes);
    Ok(())
}

/// A resolver whose load warnings (`MapsResolver::with_warnings`: a colour image given as
/// heights, 8-bit terraces dequantised, normal-map texels tilted to the horizon) are kept, to be
/// raised as Python warnings by [`emit_warnings`] once the GIL is held again.
pub fn collecting_resolver() -> (
    meso_maps::MapsResolver,
    std::sync::Arc<std::sync::Mutex<Vec<String>>>,
) {
    let said = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let hook = said.clone();
    let maps = meso_maps::MapsResolver::new().with_warnings(std::sync::Arc::new(
        move |file: &Path, w: &str| {
            hook.lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push(format!("{}: {w}", file.display()));
        },
    ));
    (maps, said)
}

/// Raise each message as a `UserWarning` (Python's `warnings.warn`), in order.
///
/// # Errors
/// What `warnings.warn` raises (an error when warnings are turned into errors).
pub fn emit_warnings(py: Python<'_>, said: &std::sync::Mutex<Vec<String>>) -> PyResult<()> {
    let msgs = std::mem::take(
        &mut *said
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner),
    );
    if msgs.is_empty() {
        return Ok(());
    }
    let warnings = py.import("warnings")?;
    for m in msgs {
        warnings.call_method1("warn", (m,))?;
    }
    Ok(())
}
