//! The sphere figures' scene files (`fig*.scene.toml` beside each PNG, for `meso render`) give
//! the figures' pictures again through the scene-file path: the written material files and
//! scene files describe what was rendered.

use meso_figures::{run, Options};
use meso_render::{render, MaterialShader, RenderOptions, ResolveError, Scene, Shader};
use std::sync::Arc;

#[test]
fn sphere_figures_render_again_from_their_scene_files() {
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("scene_files");
    let report = run(
        &Options {
            out: out.clone(),
            size: 80,
            spp: 4,
            zoom_frames: 6,
        },
        &mut |_| {},
    )
    .expect("figures");
    let resolve = |p: &std::path::Path| -> Result<Arc<dyn Shader>, ResolveError> {
        let m = meso_core::material::Material::from_file(p, &meso_maps::MapsResolver::new())?;
        Ok(Arc::new(MaterialShader::new(&m)))
    };
    let scenes: Vec<_> = report
        .files
        .iter()
        .filter(|f| f.to_string_lossy().ends_with(".scene.toml"))
        .filter(|f| {
            f.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("fig"))
        })
        .collect();
    assert_eq!(scenes.len(), 6, "{scenes:?}");
    for path in scenes {
        let scene = Scene::from_toml_file(path, &resolve).expect("scene file");
        let again = out.join("again.png");
        render(&scene, &RenderOptions::default(), None)
            .write_png(&again, 0.0)
            .unwrap();
        let figure = path.to_string_lossy().replace(".scene.toml", ".png");
        let (a, b) = (
            image::open(&figure).unwrap().to_rgb8(),
            image::open(&again).unwrap().to_rgb8(),
        );
        assert_eq!(a.dimensions(), b.dimensions());
        let diff = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(x, y)| f64::from(x.abs_diff(*y)))
            .sum::<f64>()
            / a.as_raw().len() as f64;
        eprintln!("{figure}: mean 8-bit difference {diff:.3}");
        // Measured 0.000 for every figure.
        assert!(diff < 0.5, "{figure}: mean 8-bit difference {diff}");
    }
}
