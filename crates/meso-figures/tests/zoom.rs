//! The zoom sequence of `meso figures`: from visible bumps to the averaged surface without a
//! pop. The bump map's mean luminance is a property of the surface, not of the distance, so the
//! NDF-mapped frames must keep it: neighbouring frames within 2%, the whole sequence within 3%,
//! while the level of detail climbs the whole pyramid; and the frames' scene files give the same
//! pictures through `meso render`'s path.

use meso_figures::{mean_luminance, run, Options};
use meso_render::{
    load_textured, render, MaterialShader, RenderOptions, ResolveError, Scene, Shader,
};
use std::sync::Arc;

#[test]
fn zoom_sequence_has_no_pop() {
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("zoom_sequence");
    let report = run(
        &Options {
            out: out.clone(),
            size: 96,
            spp: 2,
            zoom_frames: 8,
        },
        &mut |_| {},
    )
    .expect("figures");
    let z = &report.zoom;
    assert_eq!(z.len(), 8);
    assert!(z[0].lod < 0.5, "first frame at the finest level: {z:?}");
    assert!(
        z[7].lod > 5.0,
        "last frame at the top of the pyramid: {z:?}"
    );
    for w in z.windows(2) {
        assert!(w[1].lod >= w[0].lod, "level of detail must not fall: {z:?}");
        let step = (w[1].mean_luminance / w[0].mean_luminance - 1.0).abs();
        assert!(step < 0.02, "pop between frames: {step:.4} ({z:?})");
    }
    let (lo, hi) = z.iter().fold((f64::MAX, 0.0f64), |(lo, hi), f| {
        (lo.min(f.mean_luminance), hi.max(f.mean_luminance))
    });
    assert!(
        hi / lo - 1.0 < 0.03,
        "drift over the sequence: {lo} to {hi} ({z:?})"
    );
    let csv = std::fs::read_to_string(out.join("zoom_luminance.csv")).expect("csv written");
    assert_eq!(csv.lines().count(), 9, "header and one line per frame");

    // The frames' scene files (a textured material over the written 16-bit height map) render
    // the same picture through `meso render`'s path: mean luminance within 1% at a near, a
    // middle and the farthest frame.
    let resolve = |p: &std::path::Path| -> Result<Arc<dyn Shader>, ResolveError> {
        let maps = meso_maps::MapsResolver::new();
        if let Some(s) = load_textured(p, &maps)? {
            return Ok(s);
        }
        let m = meso_core::material::Material::from_file(p, &maps)?;
        Ok(Arc::new(MaterialShader::new(&m)))
    };
    for k in [1usize, 4, 7] {
        let scene = Scene::from_toml_file(&out.join(format!("zoom_{k:02}.scene.toml")), &resolve)
            .expect("scene file");
        let lum = mean_luminance(&render(&scene, &RenderOptions::default(), None));
        let want = z[k].mean_luminance;
        assert!(
            (lum / want - 1.0).abs() < 0.01,
            "frame {k}: scene file {lum}, figure {want}"
        );
    }
}
