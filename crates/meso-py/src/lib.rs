//! # meso-py
//!
//! The native part (`meso._meso`) of the `meso` Python package: numpy bindings of the meso libraries,
//! built by maturin as an abi3 extension module (CPython ≥ 3.9). The Python layer
//! (`python/meso/__init__.py`) re-exports these names, converts array-likes to `float64`, and adds
//! the Mitsuba 3 plugin (`meso.mitsuba`) and the Dask batch runner (`meso.batch`).
//!
//! Conventions are meso's (docs/conventions.md): directions are unit vectors in the local frame
//! (normal +z, tangent +x); `wi` points towards the light and `wo` towards the viewer; BRDF values are
//! in 1/sr, without the cosine. Every error arrives as a Python exception carrying meso's message
//! (`meso.MesoError`, `ValueError` for bad arrays, `FileNotFoundError` for missing inputs); nothing
//! panics across the boundary. Array work runs with the GIL released, across cores (rayon).
#![warn(missing_docs)]

mod arrays;
mod error;
mod export;
mod fit;
mod fit_nonparametric;
mod maps;
mod material;
mod render;
mod writer;

use pyo3::prelude::*;

/// The native module `meso._meso`.
#[pymodule]
fn _meso(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("MesoError", m.py().get_type::<error::MesoError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<material::Material>()?;
    m.add_class::<material::Ndf>()?;
    m.add_class::<maps::Pyramid>()?;
    m.add_class::<maps::Level>()?;
    m.add_function(wrap_pyfunction!(maps::extract, m)?)?;
    m.add_function(wrap_pyfunction!(maps::extract_file, m)?)?;
    m.add_function(wrap_pyfunction!(maps::read_heights, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(export::export, m)?)?;
    m.add_function(wrap_pyfunction!(error::set_memory_budget, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit_samples, m)?)?;
    m.add_function(wrap_pyfunction!(fit_nonparametric::fit_nonparametric, m)?)?;
    m.add_function(wrap_pyfunction!(writer::material_toml, m)?)?;
    Ok(())
}
