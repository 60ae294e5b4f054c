//! `meso.export`: engine-ready maps (GGX roughness and normal mip chains as KTX2 and PNG, a glTF 2.0
//! preview) from a height map, a normal map or a material file, as `meso export` writes them
//! (docs/export.md): the same checks and loaders (`meso_export::prepare`), the same bytes.

use crate::error::{meso_err, require_exists, value_err};
use meso_export::export::{self as ex_lib, Inputs, Roughness};
use meso_export::prepare;
use meso_maps::{Border, HeightMap, NormalConvention};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// `alpha`'s default: the CLI's `--alpha` default.
const DEFAULT_ALPHA: f64 = 0.1;

/// Export `path` (a tangent-space normal map; a height map when `texel_size` and
/// `height_scale` are given; or a material file, `.toml`, as its engine parameters on a flat
/// map, with no other option) into the directory `out`, with the options of `meso export`:
/// `convention` ("gl", the default, or "dx"), `alpha` (default 0.1), `roughness_map`,
/// `metallic` (default 0), `base_color`, `anisotropic` (KHR_materials_anisotropy lobes) and
/// `lobes` (a lobe pyramid's map file, written as lobe textures and shader functions). Returns
/// `(files, levels, warnings)`: the written paths, one dict per mip level (`level`, `width`,
/// `height`, `mean_alpha`, `mean_error_pct`, `max_error_pct`, `mean_plain_error_pct`, and for an
/// anisotropic export `mean_alpha_t`, `mean_strength`, `iso_fit_error_pct`,
/// `iso_fit_max_error_pct`) and the warnings the CLI would print (a material file: the line
/// describing its engine parameters).
#[pyfunction]
#[pyo3(signature = (path, out, texel_size = None, height_scale = None, convention = None, alpha = None, roughness_map = None, metallic = None, base_color = None, anisotropic = false, lobes = None))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn export<'py>(
    py: Python<'py>,
    path: PathBuf,
    out: PathBuf,
    texel_size: Option<f64>,
    height_scale: Option<f64>,
    convention: Option<&str>,
    alpha: Option<f64>,
    roughness_map: Option<PathBuf>,
    metallic: Option<f64>,
    base_color: Option<PathBuf>,
    anisotropic: bool,
    lobes: Option<PathBuf>,
) -> PyResult<(Vec<String>, Vec<Bound<'py, PyDict>>, Vec<String>)> {
    require_exists(&path)?;
    for p in roughness_map
        .iter()
        .chain(base_color.iter())
        .chain(lobes.iter())
    {
        require_exists(p)?;
    }
    let conv = match convention.unwrap_or("gl") {
        "gl" => NormalConvention::Gl,
        "dx" => NormalConvention::Dx,
        other => {
            return Err(value_err(format!(
                "convention = {other:?}: must be \"gl\" or \"dx\""
            )))
        }
    };
    let material = prepare::is_material_file(&path);
    if !material && texel_size.is_some() != height_scale.is_some() {
        return Err(value_err(
            "a height map needs both texel_size and height_scale",
        ));
    }
    let given: Vec<&str> = [
        ("texel_size", texel_size.is_some()),
        ("height_scale", height_scale.is_some()),
        ("convention", convention.is_some()),
        ("alpha", alpha.is_some()),
        ("roughness_map", roughness_map.is_some()),
        ("metallic", metallic.is_some()),
        ("base_color", base_color.is_some()),
        ("anisotropic", anisotropic),
        ("lobes", lobes.is_some()),
    ]
    .into_iter()
    .filter_map(|(n, g)| g.then_some(n))
    .collect();
    let (files, stats, warnings) = py
        .detach(|| -> Result<_, String> {
            let s = |e: meso_export::ExportError| e.to_string();
            prepare::check_out_dir(&out).map_err(s)?;
            let mut warnings = Vec::new();
            let inputs = if material {
                prepare::refuse_material_options(&path, &given).map_err(s)?;
                let (inputs, line) = prepare::material_inputs(&path).map_err(s)?;
                warnings.push(line);
                inputs
            } else {
                prepare::check_export(
                    &path,
                    texel_size.is_some(),
                    roughness_map.as_deref(),
                    base_color.as_deref(),
                    anisotropic,
                    lobes.as_deref(),
                )
                .map_err(s)?;
                if texel_size.is_some() && conv == NormalConvention::Dx {
                    return Err(format!(
                        "{}: convention applies to a normal-map input; a height map has no \
                         green channel to read (the exported normal map is always OpenGL / \
                         glTF: green = +Y = up)",
                        path.display()
                    ));
                }
                let alpha = alpha.unwrap_or(DEFAULT_ALPHA);
                let mut inputs = match (texel_size, height_scale) {
                    (Some(ts), Some(h)) => {
                        let map = HeightMap::load(&path, ts, h, Border::Wrap)
                            .map_err(|e| e.to_string())?;
                        warnings.extend(map.warnings().iter().cloned());
                        Inputs::from_heightmap(&map, alpha)
                    }
                    _ => {
                        let map = prepare::load_normal_map(&path, conv).map_err(s)?;
                        warnings.extend(map.warnings());
                        Inputs::from_normal_map(&map, alpha)
                    }
                };
                if let Some(r) = &roughness_map {
                    let (alphas, w) =
                        ex_lib::load_roughness(r, inputs.width, inputs.height).map_err(s)?;
                    warnings.extend(w);
                    inputs.roughness = Roughness::Map(alphas);
                }
                if let Some(c) = &base_color {
                    let (bc, w) = ex_lib::load_base_color(c).map_err(s)?;
                    warnings.extend(w);
                    inputs.base_color = Some(bc);
                }
                inputs.metallic = metallic.unwrap_or(0.0);
                inputs.anisotropic = anisotropic;
                inputs
            };
            // The lobe pyramid read, checked and packed before the fit, as the CLI does.
            let lobe_files = lobes
                .as_ref()
                .map(|l| prepare::lobe_files(l, inputs.width, inputs.height))
                .transpose()
                .map_err(s)?;
            let mut ex = ex_lib::build(&inputs).map_err(|e| format!("{}: {e}", path.display()))?;
            if let Some((files, _line)) = lobe_files {
                ex.files.extend(files);
            }
            let inputs: Vec<&std::path::Path> = [
                Some(&path),
                base_color.as_ref(),
                roughness_map.as_ref(),
                lobes.as_ref(),
            ]
            .into_iter()
            .flatten()
            .map(std::path::PathBuf::as_path)
            .collect();
            let files = ex_lib::write(&ex, &out, &inputs).map_err(s)?;
            if let Some(w) = ex_lib::stale_warning(&ex, &out) {
                warnings.push(format!("{}: {w}", out.display()));
            }
            Ok((files, ex.stats, warnings))
        })
        .map_err(meso_err)?;
    let mut levels = Vec::new();
    for st in &stats {
        let d = PyDict::new(py);
        d.set_item("level", st.level)?;
        d.set_item("width", st.width)?;
        d.set_item("height", st.height)?;
        d.set_item("mean_alpha", st.mean_alpha)?;
        d.set_item("mean_error_pct", st.mean_error_pct)?;
        d.set_item("max_error_pct", st.max_error_pct)?;
        d.set_item("mean_plain_error_pct", st.mean_plain_error_pct)?;
        if let Some(a) = &st.aniso {
            d.set_item("mean_alpha_t", a.mean_alpha_t)?;
            d.set_item("mean_strength", a.mean_strength)?;
            d.set_item("iso_fit_error_pct", a.mean_iso_error_pct)?;
            d.set_item("iso_fit_max_error_pct", a.max_iso_error_pct)?;
        }
        levels.push(d);
    }
    Ok((
        files.iter().map(|p| p.display().to_string()).collect(),
        levels,
        warnings,
    ))
}
