//! The zoom sequence of `meso figures`: from visible bumps to the averaged surface without a
//! pop. The displaced surface's mean luminance in an orthographic view is a property of the
//! surface, not of the distance, so the NDF-mapped frames must keep it: neighbouring frames
//! within 2% while the level of detail climbs the whole pyramid, every frame near the displaced
//! geometry's own value (`meso_maps::Gonio`, rays on the mesh, which the renderer never reads)
//! and the far frames, where the footprint holds many facets and view weighting counts them as
//! the geometry does, close to it; and the frames' scene files give the same pictures through
//! `meso render`'s path.

use meso_figures::{bump_map, bump_surface, mean_luminance, plane_sun, plane_view, run, Options};
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
    // The geometry's mean luminance in this view: the height map's effective BRDF (facets of
    // the surface's transfer) by rays on the displaced mesh, plus the surface's diffuse term
    // `albedo/π` (a base under the facets, as `Material::brdf` adds it), times the irradiance.
    let (l, e) = plane_sun();
    let o = plane_view();
    let surface = bump_surface().material().expect("surface");
    let gonio = meso_maps::Gonio::new(&bump_map().expect("map")).expect("gonio");
    let params = meso_maps::GonioParams {
        rays_per_side: 256,
        ..meso_maps::GonioParams::default()
    };
    let spec = gonio.measure(&surface.transfer, l, o, &params);
    let lum = [0.2126, 0.7152, 0.0722];
    let truth: f64 = (0..3)
        .map(|c| lum[c] * (spec[c] + surface.diffuse[c] / std::f64::consts::PI) * e[c] * l.z)
        .sum();
    let off: Vec<f64> = z.iter().map(|f| f.mean_luminance / truth - 1.0).collect();
    eprintln!("geometry {truth:.5}; frames against it: {off:.4?}");
    for (f, d) in z.iter().zip(&off) {
        assert!(d.abs() < 0.04, "frame off the geometry by {d:.4} ({z:?})");
        if f.lod >= 3.0 {
            assert!(
                d.abs() < 0.0075,
                "far frame off the geometry by {d:.4} ({z:?})"
            );
        }
    }
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
