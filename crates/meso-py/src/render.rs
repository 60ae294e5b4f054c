//! `meso.render`: a scene file (docs/scene-format.md) rendered to a float image array, as
//! `meso render` renders it.

use crate::error::{meso_err, require_exists, value_err};
use meso_render::{RenderOptions, Scene};
use numpy::{PyArray1, PyArray3, PyArrayMethods};
use pyo3::prelude::*;
use std::path::PathBuf;

/// Render the scene file `scene` and return linear radiance, W/(m²·sr), as a `(height, width, 3)`
/// float32 array (row 0 at the top of the image). `spp`, `width`, `height` and `seed` override the
/// scene's `[image]` table as the CLI's options do; the result equals `meso render`'s EXR.
#[pyfunction]
#[pyo3(signature = (scene, spp = None, width = None, height = None, seed = 0))]
pub fn render<'py>(
    py: Python<'py>,
    scene: PathBuf,
    spp: Option<u32>,
    width: Option<u32>,
    height: Option<u32>,
    seed: u32,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    require_exists(&scene)?;
    for (name, v) in [("width", width), ("height", height)] {
        if let Some(v) = v {
            if !(1..=16384).contains(&v) {
                return Err(value_err(format!(
                    "{name} must be in 1..=16384 pixels, got {v}"
                )));
            }
        }
    }
    if let Some(s) = spp {
        if !(1..=65536).contains(&s) {
            return Err(value_err(format!("spp must be in 1..=65536, got {s}")));
        }
    }
    let (maps, said) = crate::error::collecting_resolver();
    let img = py
        .detach(|| -> Result<_, String> {
            let resolver = |p: &std::path::Path| meso_render::resolve_material_file(p, &maps);
            let sc = Scene::from_toml_file(&scene, &resolver)
                .map_err(|e| format!("cannot load the scene: {e:#}"))?;
            let w = width.unwrap_or(sc.image.width);
            let h = height.unwrap_or(sc.image.height);
            meso_core::budget::check(
                &scene,
                &format!("rendering {w}×{h} pixels"),
                u64::from(w) * u64::from(h) * 24,
            )
            .map_err(|e| e.to_string())?;
            let opts = RenderOptions {
                width,
                height,
                spp,
                seed,
                ..RenderOptions::default()
            };
            let img = meso_render::render(&sc, &opts, None);
            // A map file read as the render went (level 0 held by band) that changed
            // meanwhile: the image is not the file's (as `meso render`).
            sc.check_sources()?;
            Ok(img)
        })
        .map_err(meso_err)?;
    crate::error::emit_warnings(py, &said)?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let flat: Vec<f32> = img.pixels().iter().flatten().copied().collect();
    PyArray1::from_vec(py, flat).reshape([h, w, 3])
}
