//! `meso.export`: engine-ready maps (GGX roughness and normal mip chains as KTX2 and PNG, a glTF 2.0
//! preview) from a height map or normal map, as `meso export` writes them (docs/export.md).

use crate::error::{meso_err, require_exists, value_err};
use meso_export::export::{self as ex_lib, Inputs, Roughness};
use meso_maps::{Border, HeightMap, NormalConvention, NormalMap};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Export `path` (a tangent-space normal map, or a height map when `texel_size` and
/// `height_scale` are given) into the directory `out`, with the options of `meso export`. Returns
/// `(files, levels, warnings)`: the written paths, one dict per mip level (`level`, `width`,
/// `height`, `mean_alpha`, `mean_error_pct`, `max_error_pct`, `mean_plain_error_pct`) and the
/// warnings the CLI would print.
#[pyfunction]
#[pyo3(signature = (path, out, texel_size = None, height_scale = None, convention = "gl", alpha = 0.1, roughness_map = None, metallic = 0.0, base_color = None))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn export<'py>(
    py: Python<'py>,
    path: PathBuf,
    out: PathBuf,
    texel_size: Option<f64>,
    height_scale: Option<f64>,
    convention: &str,
    alpha: f64,
    roughness_map: Option<PathBuf>,
    metallic: f64,
    base_color: Option<PathBuf>,
) -> PyResult<(Vec<String>, Vec<Bound<'py, PyDict>>, Vec<String>)> {
    require_exists(&path)?;
    for p in roughness_map.iter().chain(base_color.iter()) {
        require_exists(p)?;
    }
    let conv = match convention {
        "gl" => NormalConvention::Gl,
        "dx" => NormalConvention::Dx,
        other => {
            return Err(value_err(format!(
                "convention = {other:?}: must be \"gl\" or \"dx\""
            )))
        }
    };
    if texel_size.is_some() != height_scale.is_some() {
        return Err(value_err(
            "a height map needs both texel_size and height_scale",
        ));
    }
    let (files, stats, warnings) = py
        .detach(|| -> Result<_, String> {
            ex_lib::check_budget(
                &path,
                texel_size.is_some(),
                roughness_map.as_deref(),
                base_color.as_deref(),
            )
            .map_err(|e| e.to_string())?;
            let mut warnings = Vec::new();
            let mut inputs = match (texel_size, height_scale) {
                (Some(s), Some(h)) => {
                    let map =
                        HeightMap::load(&path, s, h, Border::Wrap).map_err(|e| e.to_string())?;
                    warnings.extend(map.warnings().iter().cloned());
                    Inputs::from_heightmap(&map, alpha)
                }
                _ => {
                    let map = NormalMap::load(&path, conv).map_err(|e| e.to_string())?;
                    if map.clamped() > 0 {
                        warnings.push(format!(
                            "{} of {} texels point at or below the horizon; tilted up to it",
                            map.clamped(),
                            map.width() * map.height()
                        ));
                    }
                    Inputs::from_normal_map(&map, alpha)
                }
            };
            if let Some(r) = &roughness_map {
                let (alphas, w) = ex_lib::load_roughness(r, inputs.width, inputs.height)
                    .map_err(|e| e.to_string())?;
                warnings.extend(w);
                inputs.roughness = Roughness::Map(alphas);
            }
            if let Some(c) = &base_color {
                let (bc, w) = ex_lib::load_base_color(c).map_err(|e| e.to_string())?;
                warnings.extend(w);
                inputs.base_color = Some(bc);
            }
            inputs.metallic = metallic;
            let ex = ex_lib::build(&inputs).map_err(|e| format!("{}: {e}", path.display()))?;
            let files = ex_lib::write(&ex, &out).map_err(|e| e.to_string())?;
            Ok((files, ex.stats, warnings))
        })
        .map_err(meso_err)?;
    let mut levels = Vec::new();
    for s in &stats {
        let d = PyDict::new(py);
        d.set_item("level", s.level)?;
        d.set_item("width", s.width)?;
        d.set_item("height", s.height)?;
        d.set_item("mean_alpha", s.mean_alpha)?;
        d.set_item("mean_error_pct", s.mean_error_pct)?;
        d.set_item("max_error_pct", s.max_error_pct)?;
        d.set_item("mean_plain_error_pct", s.mean_plain_error_pct)?;
        levels.push(d);
    }
    Ok((
        files.iter().map(|p| p.display().to_string()).collect(),
        levels,
        warnings,
    ))
}
