//! `meso.extract`, `meso.extract_file` and `meso.Pyramid`: height maps (numpy arrays or image files)
//! filtered into NDF pyramids of fitted Phong lobes (TR-92-41), whose levels read as numpy arrays.

use crate::arrays::Arr;
use crate::error::{meso_err, require_exists, value_err};
use meso_maps::fit::MergeLevels;
use meso_maps::{
    Baseline, Border, ExtractParams, HeightMap, InputKind, Method, NormalConvention, NormalMode,
};
use numpy::{PyArray1, PyArray2, PyArray3, PyArray4, PyArrayMethods};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// The extraction parameters named as the CLI's `meso extract` options.
fn params(
    max_lobes: Option<usize>,
    normals: &str,
    method: &str,
    merge_levels: &str,
) -> PyResult<ExtractParams> {
    if let Some(k) = max_lobes {
        if !(1..=meso_maps::limits::MAX_LOBES).contains(&k) {
            return Err(value_err(format!(
                "max_lobes = {k}: must be between 1 and {}",
                meso_maps::limits::MAX_LOBES
            )));
        }
    }
    let mut p = ExtractParams {
        normal_mode: match normals {
            "triangles" => NormalMode::Triangles,
            "central" => NormalMode::CentralDifferences,
            other => {
                return Err(value_err(format!(
                    "normals = {other:?}: must be \"triangles\" or \"central\""
                )))
            }
        },
        method: match method {
            "lobes" => Method::Lobes,
            "toksvig" => Method::Baseline(Baseline::Toksvig),
            "lean" => Method::Baseline(Baseline::Lean),
            "vmf" => Method::Baseline(Baseline::Vmf),
            "mip" => Method::Baseline(Baseline::MipNormal),
            other => {
                return Err(value_err(format!(
                    "method = {other:?}: must be one of \"lobes\", \"toksvig\", \"lean\", \"vmf\", \"mip\""
                )))
            }
        },
        ..ExtractParams::default()
    };
    if let Some(k) = max_lobes {
        p = p.with_max_lobes(k);
    }
    p.fit.merge_levels = MergeLevels::from_name(merge_levels).ok_or_else(|| {
        let names: Vec<String> = MergeLevels::NAMES
            .iter()
            .map(|(_, n)| format!("{n:?}"))
            .collect();
        value_err(format!(
            "merge_levels = {merge_levels:?}: must be one of {}",
            names.join(", ")
        ))
    })?;
    Ok(p)
}

fn border(name: &str) -> PyResult<Border> {
    match name {
        "wrap" => Ok(Border::Wrap),
        "clamp" => Ok(Border::Clamp),
        other => Err(value_err(format!(
            "border = {other:?}: must be \"wrap\" or \"clamp\""
        ))),
    }
}

fn run_extract(
    py: Python<'_>,
    source: &meso_maps::Input,
    params: &ExtractParams,
) -> PyResult<meso_maps::Pyramid> {
    py.detach(|| meso_maps::extract(source.source(), params, &mut |_| {}))
        .map_err(meso_err)
}

/// Extract the NDF pyramid of a height field given as a `(rows, cols)` float64 array of heights
/// in image order (row 0 is the top of the image, as an image reader returns it; meso's +y is up
/// in the image); heights are `heights · height_scale`, so codes in
/// [0, 1] with `height_scale = H` equal `meso extract` of the same image), samples `texel_size`
/// apart (same length unit). The other parameters are `meso extract`'s options
/// (`merge_levels`: `--merge-levels`).
#[pyfunction]
#[pyo3(signature = (heights, texel_size, height_scale = 1.0, max_lobes = None, border = "wrap", normals = "triangles", method = "lobes", merge_levels = "plain"))]
#[allow(clippy::too_many_arguments)]
pub fn extract(
    py: Python<'_>,
    heights: Arr<'_>,
    texel_size: f64,
    height_scale: f64,
    max_lobes: Option<usize>,
    border: &str,
    normals: &str,
    method: &str,
    merge_levels: &str,
) -> PyResult<Pyramid> {
    let p = params(max_lobes, normals, method, merge_levels)?;
    if !(height_scale.is_finite() && height_scale > 0.0) {
        return Err(value_err(format!(
            "height_scale = {height_scale}: must be a positive number"
        )));
    }
    // `meso extract`'s range checks (1e-12 to 1e12, slope ratio at most 1e6): beyond them the
    // normals overflow to NaN.
    meso_maps::heightmap::check_scales(std::path::Path::new("heights"), texel_size, height_scale)
        .map_err(|e| value_err(e.to_string()))?;
    let a = heights.as_array();
    let (rows, cols) = (a.shape()[0], a.shape()[1]);
    if let Some(k) = a.iter().position(|v| !v.is_finite()) {
        return Err(value_err(format!(
            "heights[{}, {}] = {}: not a finite number",
            k / cols.max(1),
            k % cols.max(1),
            a.iter().nth(k).copied().unwrap_or(f64::NAN)
        )));
    }
    meso_core::budget::check_named(
        "heights",
        "extracting the NDF pyramid",
        meso_maps::extract_bytes(cols, rows, 2, rows * cols),
    )
    .map_err(meso_err)?;
    // Array row 0 is the top of the image; meso's map row 0 (y = 0) is its bottom row (+y is up
    // in the image, docs/conventions.md), as the image loader of `meso extract` reads it.
    let h: Vec<f64> = (0..rows)
        .rev()
        .flat_map(|r| a.row(r).to_vec())
        .map(|v| v * height_scale)
        .collect();
    let map = HeightMap::from_heights(cols, rows, h, texel_size, self::border(border)?)
        .map_err(meso_err)?;
    let pyr = run_extract(py, &meso_maps::Input::Heights(map), &p)?;
    Ok(Pyramid::new(pyr))
}

/// Extract the NDF pyramid of an image file and write it as a map file, exactly as
/// `meso extract PATH --out OUT` does (same loader, budget, warnings and bytes): a height map
/// needs `texel_size` and `height_scale`; `normal_map=True` reads a tangent-space normal map in the
/// `convention` `"gl"` (OpenGL/glTF: green = +Y = up in the image) or `"dx"`. Returns the pyramid
/// and the warnings the CLI would print.
#[pyfunction]
#[pyo3(signature = (path, out, texel_size = None, height_scale = None, max_lobes = None, normal_map = false, convention = "gl", border = "wrap", normals = "triangles", method = "lobes", merge_levels = "plain"))]
#[allow(clippy::too_many_arguments)]
pub fn extract_file(
    py: Python<'_>,
    path: PathBuf,
    out: PathBuf,
    texel_size: Option<f64>,
    height_scale: Option<f64>,
    max_lobes: Option<usize>,
    normal_map: bool,
    convention: &str,
    border: &str,
    normals: &str,
    method: &str,
    merge_levels: &str,
) -> PyResult<(Pyramid, Vec<String>)> {
    let p = params(max_lobes, normals, method, merge_levels)?;
    require_exists(&path)?;
    // The map file must not replace the image it is made from (as `meso extract` refuses).
    meso_core::io::check_not_input(&out, &[&path]).map_err(|e| value_err(e.to_string()))?;
    let kind = if normal_map {
        if texel_size.is_some() || height_scale.is_some() {
            return Err(value_err(
                "texel_size and height_scale do not apply to a normal map (normal_map=True)",
            ));
        }
        InputKind::Normals(match convention {
            "gl" => NormalConvention::Gl,
            "dx" => NormalConvention::Dx,
            other => {
                return Err(value_err(format!(
                    "convention = {other:?}: must be \"gl\" or \"dx\""
                )))
            }
        })
    } else {
        let (Some(texel_size), Some(height_scale)) = (texel_size, height_scale) else {
            return Err(value_err("a height map needs texel_size and height_scale"));
        };
        InputKind::Heights {
            texel_size,
            height_scale,
            border: self::border(border)?,
        }
    };
    let (pyr, warnings) = py
        .detach(|| -> Result<_, String> {
            let (input, warnings) =
                meso_maps::input::load(&path, kind, &p).map_err(|e| e.to_string())?;
            let pyr = meso_maps::extract(input.source(), &p, &mut |_| {})
                .map_err(|e| format!("{}: {e}", path.display()))?;
            // The bytes `meso extract` streams (map format 4), checked, written atomically.
            pyr.write(&out).map_err(|e| e.to_string())?;
            Ok((pyr, warnings))
        })
        .map_err(meso_err)?;
    Ok((Pyramid::new(pyr), warnings))
}

/// A height-map image read as `meso extract` reads it (grey PNG 8/16-bit, JPEG, TGA, 16-bit
/// TIFF, float EXR; budget, checks, 8-bit dequantisation and the warnings that say so):
/// `(heights, warnings)`, `heights` a `(rows, cols)` float64 array in image order (row 0 the
/// top of the image, as `extract` takes it) of the codes in [0, 1] (an EXR's values as they
/// are), so that `extract(heights, texel_size, height_scale=H)` is `meso extract` of the image
/// with `--height-scale H`. For a user without an image library, and to see what meso reads.
#[pyfunction]
#[pyo3(signature = (path, border = "wrap"))]
pub fn read_heights<'py>(
    py: Python<'py>,
    path: PathBuf,
    border: &str,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Vec<String>)> {
    require_exists(&path)?;
    let border = self::border(border)?;
    let map = py
        .detach(|| HeightMap::load(&path, 1.0, 1.0, border))
        .map_err(meso_err)?;
    let (cols, rows) = (map.width(), map.height());
    let h = map.heights();
    // meso's row 0 (y = 0) is the image's bottom row: image order is the rows reversed.
    let v: Vec<f64> = (0..rows)
        .rev()
        .flat_map(|r| h[r * cols..(r + 1) * cols].iter().copied())
        .collect();
    let warnings = map
        .warnings()
        .iter()
        .map(|w| format!("{}: {w}", path.display()))
        .collect();
    Ok((PyArray1::from_vec(py, v).reshape([rows, cols])?, warnings))
}

/// An NDF pyramid: level 0 is the finest (one texel per height-map cell), each coarser level
/// halves the texels, the last (`top`) is one texel for the whole map. Read with
/// `Pyramid.read(path)`, write with `write(path)` (the map format of docs/map-format.md).
#[pyclass(module = "meso._meso", frozen)]
pub struct Pyramid {
    inner: Arc<meso_maps::Pyramid>,
    /// What each lobe stands for ([`meso_maps::lobe_stats`] with horizons), computed on first
    /// use by any level and shared by all.
    stats: Arc<OnceLock<meso_maps::LobeStats>>,
}

impl Pyramid {
    fn new(p: meso_maps::Pyramid) -> Pyramid {
        Pyramid {
            inner: Arc::new(p),
            stats: Arc::default(),
        }
    }

    fn level(&self, index: usize) -> Level {
        Level {
            pyramid: self.inner.clone(),
            stats: self.stats.clone(),
            index,
        }
    }
}

#[pymethods]
impl Pyramid {
    /// Read a map file written by `meso extract`, held as compactly as the memory budget asks
    /// (as `meso render` reads it: lobes in their stored codes, level 0 of a big map by band
    /// from the mapped file); every value is the file's.
    #[staticmethod]
    fn read(py: Python<'_>, path: PathBuf) -> PyResult<Pyramid> {
        require_exists(&path)?;
        let p = py
            .detach(|| meso_maps::Pyramid::read_compact(&path))
            .map_err(meso_err)?;
        Ok(Pyramid::new(p))
    }

    /// Write the map file (atomically: a temporary file renamed into place).
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write(&path)).map_err(meso_err)
    }

    /// Samples across the height map.
    #[getter]
    fn width(&self) -> usize {
        self.inner.width
    }

    /// Samples down the height map.
    #[getter]
    fn height(&self) -> usize {
        self.inner.height
    }

    /// Distance between samples, length units.
    #[getter]
    fn texel_size(&self) -> f64 {
        self.inner.texel_size
    }

    /// Largest number of lobes per texel.
    #[getter]
    fn max_lobes(&self) -> usize {
        self.inner.max_lobes
    }

    /// The levels, finest first.
    #[getter]
    fn levels(&self) -> Vec<Level> {
        (0..self.inner.levels.len())
            .map(|index| self.level(index))
            .collect()
    }

    /// The coarsest level (one texel).
    #[getter]
    fn top(&self) -> Level {
        self.level(self.inner.levels.len() - 1)
    }

    fn __len__(&self) -> usize {
        self.inner.levels.len()
    }

    fn __repr__(&self) -> String {
        format!(
            // Named, as the levels' rows and cols are (width is the array's cols).
            "meso.Pyramid(width={}, height={}, {} levels, max_lobes={})",
            self.inner.width,
            self.inner.height,
            self.inner.levels.len(),
            self.inner.max_lobes
        )
    }
}

/// The map's texel index of texel `t` in image order (row 0 at the top of the image; the map's
/// row 0 is the image's bottom row).
fn map_texel(l: &meso_maps::Level, t: usize) -> usize {
    let (r, c) = (t / l.cols, t % l.cols);
    (l.rows - 1 - r) * l.cols + c
}

/// One level of a pyramid: `rows × cols` texels, each a sum of up to `max_lobes` Phong lobes
/// (Eq. 12). Arrays are in image order (row 0 at the top of the image) and padded with
/// zero-weight lobes where a texel has fewer; lobe axes are in meso's frame (+y up in the image).
#[pyclass(module = "meso._meso", frozen)]
pub struct Level {
    pyramid: Arc<meso_maps::Pyramid>,
    stats: Arc<OnceLock<meso_maps::LobeStats>>,
    index: usize,
}

impl Level {
    fn level(&self) -> &meso_maps::Level {
        &self.pyramid.levels[self.index]
    }

    /// The pyramid's lobe statistics (computed once, outside the GIL).
    ///
    /// # Errors
    /// A map file's level 0 held by band that changed in place meanwhile.
    fn stats(&self, py: Python<'_>) -> PyResult<&meso_maps::LobeStats> {
        if let Some(s) = self.stats.get() {
            return Ok(s);
        }
        let s = py.detach(|| meso_maps::lobe_stats(&self.pyramid, true));
        self.pyramid.check_mapped().map_err(meso_err)?;
        Ok(self.stats.get_or_init(|| s))
    }

    /// `(rows, cols, K)` array of a per-lobe value `f(index of its texel in the level, index
    /// of the lobe in the level)`, zero-padded.
    fn per_lobe_index<'py>(
        &self,
        py: Python<'py>,
        f: impl Fn(usize, usize) -> f64,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let l = self.level();
        let k = self.pyramid.max_lobes;
        let mut v = vec![0.0; l.rows * l.cols * k];
        for t in 0..l.rows * l.cols {
            let m = map_texel(l, t);
            let (a, b) = (l.lobe_start[m] as usize, l.lobe_start[m + 1] as usize);
            for (j, i) in (a..b).enumerate().take(k) {
                v[t * k + j] = f(m, i);
            }
        }
        PyArray1::from_vec(py, v).reshape([l.rows, l.cols, k])
    }

    /// `(rows, cols, K, n)` array of a per-lobe quantity, zero-padded.
    fn per_lobe<'py, const N: usize>(
        &self,
        py: Python<'py>,
        f: impl Fn(&meso_core::ndf::PhongLobe) -> [f64; N],
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let l = self.level();
        let k = self.pyramid.max_lobes;
        let mut v = vec![0.0; l.rows * l.cols * k * N];
        for t in 0..l.rows * l.cols {
            let m = map_texel(l, t);
            let (a, b) = (l.lobe_start[m] as usize, l.lobe_start[m + 1] as usize);
            for (j, lobe) in l.lobes.range(a, b).enumerate().take(k) {
                let at = (t * k + j) * N;
                v[at..at + N].copy_from_slice(&f(&lobe));
            }
        }
        // A map file's level 0 held by band that changed in place meanwhile.
        self.pyramid.check_mapped().map_err(meso_err)?;
        Ok(PyArray1::from_vec(py, v))
    }
}

#[pymethods]
impl Level {
    /// Texels across.
    #[getter]
    fn cols(&self) -> usize {
        self.level().cols
    }

    /// Texels down.
    #[getter]
    fn rows(&self) -> usize {
        self.level().rows
    }

    /// Height-map cells per texel side.
    #[getter]
    fn span(&self) -> usize {
        self.level().span
    }

    /// `(rows, cols)` int64 array: the number of lobes of each texel.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let l = self.level();
        let v: Vec<i64> = (0..l.rows * l.cols)
            .map(|t| {
                let m = map_texel(l, t);
                i64::from(l.lobe_start[m + 1] - l.lobe_start[m])
            })
            .collect();
        PyArray1::from_vec(py, v).reshape([l.rows, l.cols])
    }

    /// `(rows, cols, K, 3)` float64: unit lobe axes in the local frame (normal +z).
    #[getter]
    fn axes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray4<f64>>> {
        let l = self.level();
        self.per_lobe(py, |p| [p.axis.x, p.axis.y, p.axis.z])?
            .reshape([l.rows, l.cols, self.pyramid.max_lobes, 3])
    }

    /// `(rows, cols, K)` float64: lobe weights (each texel's sum to 1).
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let l = self.level();
        self.per_lobe(py, |p| [p.weight])?
            .reshape([l.rows, l.cols, self.pyramid.max_lobes])
    }

    /// `(rows, cols, K)` float64: Phong exponents η of `cos^η(α/2)`.
    #[getter]
    fn exponents<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let l = self.level();
        self.per_lobe(py, |p| [p.exponent])?
            .reshape([l.rows, l.cols, self.pyramid.max_lobes])
    }

    /// The mean NDF residual of this level (the fit's error, docs/heightmaps.md).
    #[getter]
    fn residual(&self) -> f64 {
        self.level().residual.mean
    }

    /// The largest NDF residual among the texels this level measured.
    #[getter]
    fn residual_max(&self) -> f64 {
        self.level().residual.max
    }

    /// The mean shading error of this level's lobes as a fraction of each texel's peak (0.01 =
    /// 1 %; the lobes against the footprint's normals through a facet kernel, RMS over the half
    /// vectors, as `meso map info` prints it in %), or `None` for a map file that did not
    /// record it.
    #[getter]
    fn shading_error(&self) -> Option<f64> {
        self.level().residual.shading_mean
    }

    /// The largest shading error among the texels this level measured (fraction of the peak),
    /// or `None` as for `shading_error`.
    #[getter]
    fn shading_error_max(&self) -> Option<f64> {
        self.level().residual.shading_max
    }

    /// `(rows, cols, K)` float64: each lobe's share of its texel's projected area, from the
    /// level-0 normals it stands for (`meso_maps::lobe_stats`: a coarse texel hands each fine
    /// normal's projected area to its lobes by the mixture's posterior; a texel's shares sum to
    /// 1, or are all 0 when nothing faces up). Zero-padded like `weights`. Computed for the whole
    /// pyramid on first use (about a second for a 512² map).
    #[getter]
    fn lobe_shares<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let shares = &self.stats(py)?.shares[self.index];
        self.per_lobe_index(py, |_, i| shares[i])
    }

    /// `(rows, cols, K)` float64: per lobe, the fraction of the cells it stands for from which
    /// the unit `direction` (meso's frame: +z the surface normal, +y up in the image) is above
    /// the horizon: the visibility `V_j(ω)` the renderer's NDF-mapped shading multiplies that
    /// lobe by (docs/heightmaps.md, "Visibility per lobe"); from level 2 on its mean over the
    /// lobe's facets, where the renderer reads each of the lobe's nodes by its own normal
    /// (docs "The light read by each lobe node's normal"). With `view` (a unit vector too), the
    /// fraction from which both are: shadowing and masking together, `G_j(i, o)`, as the
    /// renderer reads them with view weighting (`meso_maps::HorizonCdf::joint_visibility_along`:
    /// from level 2 on each lobe's joint distribution for azimuths 90°–180° apart; docs
    /// "Light and viewer together per lobe"). On level 0 each lobe reads its cell's horizons
    /// point by point (`meso_maps::CellHorizon`), with or without `view`, as the renderer
    /// does. `None` for a pyramid without horizon statistics (one extracted from a normal
    /// map). Zero-padded like `weights`.
    #[pyo3(signature = (direction, view = None))]
    fn lobe_visibility<'py>(
        &self,
        py: Python<'py>,
        direction: [f64; 3],
        view: Option<[f64; 3]>,
    ) -> PyResult<Option<Bound<'py, PyArray3<f64>>>> {
        // Normalised, as `Material.brdf` does its directions.
        let unit = |d: [f64; 3]| {
            let w = glam::DVec3::from_array(d);
            if w.is_finite() && w.length() > 1e-12 {
                Ok(w.normalize())
            } else {
                Err(value_err(format!(
                    "direction {d:?}: not a direction (zero length or not finite)"
                )))
            }
        };
        let w = unit(direction)?;
        let o = view.map(unit).transpose()?;
        let stats = self.stats(py)?;
        let Some(h) = stats.horizon.as_ref() else {
            return Ok(None);
        };
        let h = &h[self.index];
        let a = meso_maps::HorizonDirection::new(w);
        // Level 0 as the renderer reads it: each lobe its cell's horizons, point by point.
        if let (0, Some(cells)) = (self.index, stats.cells.as_ref()) {
            return match o {
                None => self.per_lobe_index(py, |t, _| cells[t].visibility_along(&a)),
                Some(o) => {
                    let b = meso_maps::HorizonDirection::new(o);
                    self.per_lobe_index(py, |t, _| cells[t].joint_visibility_along(&a, &b))
                }
            }
            .map(Some);
        }
        match o {
            None => self.per_lobe_index(py, |_, i| h[i].visibility(w)).map(Some),
            Some(o) => {
                let joint = stats.joint.as_ref().map(|j| &j[self.index]);
                let b = meso_maps::HorizonDirection::new(o);
                self.per_lobe_index(py, |_, i| {
                    h[i].joint_visibility_along(joint.and_then(|j| j.get(i)), &a, &b)
                })
                .map(Some)
            }
        }
    }

    fn __repr__(&self) -> String {
        let l = self.level();
        format!(
            "meso.Level(index={}, rows={}, cols={}, lobes={})",
            self.index,
            l.rows,
            l.cols,
            l.lobes.len()
        )
    }
}
