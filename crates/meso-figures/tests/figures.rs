//! The velvet figure's lighting: the lower-right limb is beyond the key light's terminator (black
//! under the key light) and, under the cloth light from near the viewer, shows the velvet's
//! sheen: brighter than the centre of the disc.

use meso_core::catalogue::velvet;
use meso_figures::{cloth_light, key_light, sphere_scene};
use meso_render::{render, MaterialShader, RenderOptions, Shader};
use std::sync::Arc;

/// Red radiance at the lower-right limb (image direction −45°, 0.95 of the radius), where the
/// key light's `N·L` is about −0.5, and at the centre of the disc.
fn limb_and_centre(lights: &[meso_render::Light]) -> (f32, f32) {
    let size = 64u32;
    let shader: Arc<dyn Shader> = Arc::new(MaterialShader::new(&velvet().material()));
    let scene = sphere_scene(shader, size, 1, lights).unwrap();
    let img = render(&scene, &RenderOptions::default(), None);
    // Orthographic, 2.4 world units across: world (0.672, −0.672) is pixel (49.9, 49.9).
    let px = |x: u32, y: u32| img.pixels()[(y * size + x) as usize][0];
    (px(49, 49), px(32, 32))
}

#[test]
fn cloth_light_gives_velvet_its_rim() {
    let (limb_key, _) = limb_and_centre(&[key_light()]);
    let (limb, centre) = limb_and_centre(&[cloth_light()]);
    eprintln!("limb: key light {limb_key}, cloth light {limb}; centre {centre}");
    assert!(
        limb_key < 1e-3,
        "the key light alone does not reach the limb: {limb_key}"
    );
    // The sheen: the limb is brighter than the centre of the disc, which faces the light.
    assert!(limb > 0.05 && limb > centre, "limb {limb}, centre {centre}");
}
