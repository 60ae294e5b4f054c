//! `meso.Material` and `meso.Ndf`: a material file's effective BRDF (Eq. 2/8), its importance
//! sampler, and its NDF (Eq. 1) evaluated and sampled, on numpy arrays.

use crate::arrays::Arr;
use crate::arrays::{array_n, array_n3, directions, flat, same_rows, uniforms, unit_row};
use crate::error::{meso_err, require_exists, value_err};
use glam::DVec3;
use meso_core::material::{Material as CoreMaterial, MaterialSpec};
use meso_core::shading::{FastBrdf, Policy};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// `(directions (N, 3), densities (N,))` of [`Material::sample`].
type Sampled<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// Rows per rayon task: large enough that the scheduling is free, small enough to balance.
const CHUNK: usize = 1024;

/// A meso material: an NDF, a facet transfer function, an optional Lambert term and the
/// convolution form (docs/material-format.md). Build it with `Material.from_toml(text)`,
/// `Material.from_file(path)` or `Material.from_params(...)` (Python layer).
#[pyclass(module = "meso._meso", frozen)]
pub struct Material {
    pub(crate) inner: Arc<CoreMaterial>,
    /// The TOML text it was built from.
    toml: String,
    /// The compiled plan of `meso brdf` ([`Policy::Accurate`]), built on first use.
    plan: OnceLock<FastBrdf>,
}

fn build(py: Python<'_>, text: &str, dir: &Path, label: Option<&Path>) -> PyResult<CoreMaterial> {
    let (maps, said) = crate::error::collecting_resolver();
    let m = MaterialSpec::parse(text, dir)
        .and_then(|s| s.build(&maps))
        .map_err(|e| match label {
            Some(p) => meso_err(format!("{}: {}", p.display(), e.0)),
            None => meso_err(e.0),
        })?;
    crate::error::emit_warnings(py, &said)?;
    Ok(m)
}

/// Evaluate `f(row)` over `n` rows across cores, in chunks, with the GIL released.
pub(crate) fn par_rows<T: Send + Default + Clone>(
    py: Python<'_>,
    n: usize,
    f: impl Fn(usize) -> T + Sync + Send,
) -> Vec<T> {
    py.detach(|| {
        let mut out = vec![T::default(); n];
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                for (k, slot) in chunk.iter_mut().enumerate() {
                    *slot = f(c * CHUNK + k);
                }
            });
        out
    })
}

impl Material {
    /// A material from TOML text (relative paths resolved against the current directory), as
    /// `Material.from_toml(text)`.
    pub(crate) fn from_text(py: Python<'_>, text: &str) -> PyResult<Material> {
        Material::from_toml(py, text, None)
    }
}

#[pymethods]
impl Material {
    /// A material from TOML text. Relative paths in it (height maps, map files) are resolved
    /// against `base_dir` (default: the current directory).
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = None))]
    fn from_toml(py: Python<'_>, text: &str, base_dir: Option<PathBuf>) -> PyResult<Material> {
        let dir = base_dir.unwrap_or_else(|| PathBuf::from("."));
        Ok(Material {
            inner: Arc::new(build(py, text, &dir, None)?),
            toml: text.to_owned(),
            plan: OnceLock::new(),
        })
    }

    /// A material from a TOML file (as `meso brdf MATERIAL` reads it; height-map NDFs are loaded
    /// and their facets cached like the CLI's).
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<Material> {
        require_exists(&path)?;
        let text = meso_core::material::read_limited(&path).map_err(|e| meso_err(e.0))?;
        let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        Ok(Material {
            inner: Arc::new(build(py, &text, &dir, Some(&path))?),
            toml: text,
            plan: OnceLock::new(),
        })
    }

    /// A material from keyword arguments: the tables of the material format as dicts, e.g.
    /// `Material.from_params(form="microfacet", ndf={"kind": "ggx", "alpha": 0.1},
    /// transfer={"kind": "mirror"}, diffuse=[0.5, 0.5, 0.5])` (`meso.material_toml` writes the
    /// text; `base_dir` resolves relative paths). The same validation as a material file.
    #[staticmethod]
    #[pyo3(signature = (base_dir = None, **tables))]
    fn from_params(
        py: Python<'_>,
        base_dir: Option<PathBuf>,
        tables: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<Material> {
        let text: String = py
            .import("meso")?
            .getattr("material_toml")?
            .call((), tables)?
            .extract()?;
        Material::from_toml(py, &text, base_dir)
    }

    /// The optional display name (`name = "…"`).
    #[getter]
    fn name(&self) -> Option<String> {
        self.inner.name.clone()
    }

    /// The TOML text this material was built from.
    #[getter]
    fn toml(&self) -> String {
        self.toml.clone()
    }

    /// The convolution form: `"multiple-surface"` or `"microfacet"`.
    #[getter]
    fn form(&self) -> &'static str {
        match self.inner.form {
            meso_core::convolution::Form::MultipleSurface => "multiple-surface",
            meso_core::convolution::Form::Microfacet => "microfacet",
        }
    }

    /// The material's NDF.
    #[getter]
    fn ndf(&self) -> Ndf {
        Ndf {
            inner: Arc::new(self.inner.ndf.clone()),
        }
    }

    /// The effective BRDF at direction pairs: `wi` (towards the light) and `wo` (towards the
    /// viewer) are `(N, 3)` float64 arrays of directions in the local frame (normal +z; rows are
    /// normalised); returns `(N, 3)` RGB values in 1/sr, without the cosine, 0 where either
    /// direction is below the surface. The same numbers as `meso brdf`: the material's compiled
    /// plan, or with `exact=True` the quadrature of every pair (`meso brdf --exact`).
    #[pyo3(signature = (wi, wo, exact = false))]
    fn brdf<'py>(
        &self,
        py: Python<'py>,
        wi: Arr<'py>,
        wo: Arr<'py>,
        exact: bool,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let i = flat("wi", &wi, 3)?;
        let o = flat("wo", &wo, 3)?;
        let n = i.len() / 3;
        same_rows(("wi", n), ("wo", o.len() / 3))?;
        // The result is written in place into the numpy array, rows validated and normalised on
        // the fly, across cores with the GIL released: no copy of the inputs or the output.
        // SAFETY: every element is written below before the array is returned; on an error the
        // array is dropped unread.
        let out = unsafe { PyArray2::<f64>::new(py, [n, 3], false) };
        let mut rw = out.readwrite();
        let dst = rw.as_slice_mut().map_err(meso_err)?;
        let m = &*self.inner;
        let plan = (!exact).then(|| {
            py.detach(|| {
                self.plan
                    .get_or_init(|| FastBrdf::with_policy(m, Policy::Accurate))
            })
        });
        let (i, o) = (&*i, &*o);
        py.detach(|| {
            dst.par_chunks_mut(3 * CHUNK)
                .enumerate()
                .try_for_each(|(c, chunk)| {
                    for (k, slot) in chunk.chunks_exact_mut(3).enumerate() {
                        let row = c * CHUNK + k;
                        let (wi, wo) = (unit_row("wi", i, row)?, unit_row("wo", o, row)?);
                        let f = match plan {
                            Some(p) => p.eval(wi, wo),
                            None => m.brdf(wi, wo),
                        };
                        slot.copy_from_slice(&f);
                    }
                    Ok::<(), String>(())
                })
        })
        .map_err(value_err)?;
        drop(rw);
        Ok(out)
    }

    /// Importance-sample the direction towards the light for viewer directions `wo` `(N, 3)` with
    /// uniform numbers `u` `(N, 3)` in [0, 1): a mixture of the NDF's own sampler (mirror
    /// reflection of `wo` about a drawn normal) and cosine-weighted directions
    /// (`meso_core::importance`). Returns `(wi, pdf)`: `(N, 3)` directions and `(N,)` densities in
    /// 1/sr; a declined draw has `wi = 0` and `pdf = 0`.
    fn sample<'py>(&self, py: Python<'py>, wo: Arr<'py>, u: Arr<'py>) -> PyResult<Sampled<'py>> {
        let o = directions("wo", &wo)?;
        let u = uniforms("u", &u, 3)?;
        same_rows(("wo", o.len()), ("u", u.len() / 3))?;
        let m = &*self.inner;
        let out = par_rows(py, o.len(), |k| {
            let uk = [u[3 * k], u[3 * k + 1], u[3 * k + 2]];
            match meso_core::importance::sample_incident(m, o[k], uk) {
                Some(i) => (
                    [i.x, i.y, i.z],
                    meso_core::importance::sample_pdf(m, o[k], i),
                ),
                None => ([0.0; 3], 0.0),
            }
        });
        let (dirs, pdfs): (Vec<[f64; 3]>, Vec<f64>) = out.into_iter().unzip();
        Ok((array_n3(py, &dirs)?, array_n(py, pdfs)))
    }

    /// The density (1/sr) with which `sample` draws `wi` for the viewer direction `wo`; both
    /// `(N, 3)`; returns `(N,)`.
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        wo: Arr<'py>,
        wi: Arr<'py>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let o = directions("wo", &wo)?;
        let i = directions("wi", &wi)?;
        same_rows(("wo", o.len()), ("wi", i.len()))?;
        let m = &*self.inner;
        let p = par_rows(py, o.len(), |k| {
            meso_core::importance::sample_pdf(m, o[k], i[k])
        });
        Ok(array_n(py, p))
    }

    fn __repr__(&self) -> String {
        format!(
            "meso.Material(name={}, ndf={:?}, form={:?})",
            // As Python writes the `name` attribute: a string, or None.
            self.inner
                .name
                .as_deref()
                .map_or_else(|| "None".to_string(), |n| format!("{n:?}")),
            self.inner.ndf.kind(),
            self.form()
        )
    }
}

/// A normal distribution function, normalised as Eq. 1 (`∫ n(m) dω = 1` over the sphere).
#[pyclass(module = "meso._meso", frozen)]
pub struct Ndf {
    inner: Arc<meso_core::ndf::Ndf>,
}

#[pymethods]
impl Ndf {
    /// The NDF of a material text's `[ndf]` table (a whole material, or just the `[ndf]` table:
    /// a material without `[transfer]` gets a Lambert one, which does not change the NDF).
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = None))]
    fn from_toml(py: Python<'_>, text: &str, base_dir: Option<PathBuf>) -> PyResult<Ndf> {
        let dir = base_dir.unwrap_or_else(|| PathBuf::from("."));
        let has_transfer = text
            .parse::<toml::Table>()
            .map_err(|e| meso_err(format!("not valid TOML: {}", e.message())))?
            .contains_key("transfer");
        let text = if has_transfer {
            text.to_owned()
        } else {
            format!("{text}\n[transfer]\nkind = \"lambert\"\n")
        };
        Ok(Ndf {
            inner: Arc::new(build(py, &text, &dir, None)?.ndf),
        })
    }

    /// An NDF from the keys of an `[ndf]` table, e.g. `Ndf.from_params(kind="beckmann",
    /// alpha=0.1)` (docs/material-format.md, "`[ndf]` kinds").
    #[staticmethod]
    #[pyo3(signature = (base_dir = None, **keys))]
    fn from_params(
        py: Python<'_>,
        base_dir: Option<PathBuf>,
        keys: Option<&Bound<'_, pyo3::types::PyDict>>,
    ) -> PyResult<Ndf> {
        // A Lambert facet, as `from_toml` adds to a bare `[ndf]` table: it does not change the NDF.
        let kwargs = pyo3::types::PyDict::new(py);
        kwargs.set_item("ndf", keys)?;
        let lambert = pyo3::types::PyDict::new(py);
        lambert.set_item("kind", "lambert")?;
        kwargs.set_item("transfer", lambert)?;
        let text: String = py
            .import("meso")?
            .getattr("material_toml")?
            .call((), Some(&kwargs))?
            .extract()?;
        Ndf::from_toml(py, &text, base_dir)
    }

    /// The kind, as in the material format (`"beckmann"`, `"phong-peaks"`, …).
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind()
    }

    /// True for NDFs without a density (deltas, a cylinder): `eval` and `pdf` are 0.
    #[getter]
    fn singular(&self) -> bool {
        self.inner.is_singular()
    }

    /// The density `n(m)` in 1/sr at unit normals `m` `(N, 3)`; returns `(N,)`.
    fn eval<'py>(&self, py: Python<'py>, m: Arr<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let m = directions("m", &m)?;
        let n = &*self.inner;
        Ok(array_n(py, par_rows(py, m.len(), |k| n.eval(m[k]))))
    }

    /// Draw normals with uniform numbers `u` `(N, 2)` in [0, 1); returns `(N, 3)` unit normals
    /// whose density is `pdf`.
    fn sample<'py>(&self, py: Python<'py>, u: Arr<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let u = uniforms("u", &u, 2)?;
        let n = &*self.inner;
        let m = par_rows(py, u.len() / 2, |k| {
            let d: DVec3 = n.sample([u[2 * k], u[2 * k + 1]]);
            [d.x, d.y, d.z]
        });
        array_n3(py, &m)
    }

    /// The density (1/sr) of `sample` at unit normals `m` `(N, 3)`; returns `(N,)`.
    fn pdf<'py>(&self, py: Python<'py>, m: Arr<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let m = directions("m", &m)?;
        let n = &*self.inner;
        Ok(array_n(py, par_rows(py, m.len(), |k| n.pdf(m[k]))))
    }

    /// Moments by quadrature: `{"integral": ∫n dω (1 by Eq. 1), "mean_normal": [x, y, z]}`.
    fn stats(&self, py: Python<'_>) -> PyResult<Py<pyo3::types::PyDict>> {
        let n = self.inner.clone();
        let s = py.detach(move || n.stats());
        let d = pyo3::types::PyDict::new(py);
        d.set_item("integral", s.integral)?;
        d.set_item(
            "mean_normal",
            [s.mean_normal.x, s.mean_normal.y, s.mean_normal.z],
        )?;
        Ok(d.unbind())
    }

    fn __repr__(&self) -> String {
        format!("meso.Ndf(kind={:?})", self.inner.kind())
    }
}
