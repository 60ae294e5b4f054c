//! The picture of docs/heightmaps.md's "Light between glossy facets": the BRDF of glossy facets
//! (rough conductors, Beckmann α = 0.1, no Fresnel loss) on creased surfaces, in the plane
//! across the creases, light at 30°: the NDF's single bounce with its visibility, the same with
//! the light between facets traced (`interreflection = true`), and the ray tracer following 8
//! bounces (`meso gonio --bounces 8`, 384² paths) on the same heights.
//!
//! ```text
//! cargo run --release -p meso-figures --example interreflection_slice
//! ```
//! writes `docs/figures/interreflection/{vgrooves,grooves}.png` and prints the values.

use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;
use meso_maps::{fixtures, Border, Gonio, GonioParams, HeightMap, MapsResolver};
use meso_plot::color::rgb8;
use meso_plot::{LinePlot, Series};
use std::path::Path;

fn main() {
    let out = Path::new("docs/figures/interreflection");
    std::fs::create_dir_all(out).expect("the figures folder");
    let dir = std::env::temp_dir().join(format!("meso-ir-slice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let s = 1.0 / 64.0;
    for (name, title, map) in [
        (
            "vgrooves",
            "63° V-grooves, Beckmann α = 0.1, light 30°",
            fixtures::v_grooves(64, 16, 0.25, s),
        ),
        (
            "grooves",
            "half-cylinder grooves, Beckmann α = 0.1, light 30°",
            fixtures::half_cylinders(64, 16, s, -1.0),
        ),
    ] {
        let map = map.expect("fixture");
        let (png, scale) = map.encode_png16().expect("16-bit PNG");
        std::fs::write(dir.join(format!("{name}.png")), png).expect("write the map");
        let material = |ir: bool| {
            let text = format!(
                "[ndf]\nkind = \"heightmap\"\nfile = \"{name}.png\"\ntexel_size = {s}\n\
                 height_scale = {scale}\n[transfer]\nkind = \"microfacet\"\n\
                 distribution = \"beckmann\"\nalpha = 0.1\nfresnel = \"none\"\n\
                 [shadowing]\nkind = \"visibility\"\ninterreflection = {ir}\n"
            );
            let p = dir.join(format!("{name}-{ir}.toml"));
            std::fs::write(&p, text).expect("write the material");
            Material::from_file(&p, &MapsResolver::new()).expect("the material")
        };
        let (single, multi) = (material(false), material(true));
        let loaded = HeightMap::load(&dir.join(format!("{name}.png")), s, scale, Border::Wrap)
            .expect("the map");
        let gonio = Gonio::new(&loaded).expect("a wrapped map");
        let params = GonioParams {
            rays_per_side: 384,
            bounces: 8,
            ..GonioParams::default()
        };
        // The light across the creases (they run along y), the viewer in the same plane.
        let i = spherical_direction_deg(30.0, 0.0);
        let (mut one, mut traced, mut truth) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..=32 {
            let t = -80.0 + 5.0 * f64::from(k);
            let o = spherical_direction_deg(t.abs(), if t < 0.0 { 180.0 } else { 0.0 });
            let (a, b, g) = (
                single.brdf(i, o)[0],
                multi.brdf(i, o)[0],
                gonio.measure(&single.transfer, i, o, &params)[0],
            );
            println!("{name} θo {t:+.0}°: single {a:.4}, traced {b:.4}, gonio 8 bounces {g:.4}");
            one.push([t, a]);
            traced.push([t, b]);
            truth.push([t, g]);
        }
        // Headroom above the curves for the legend.
        let top = truth
            .iter()
            .chain(&traced)
            .map(|p| p[1])
            .fold(0.0_f64, f64::max);
        let mut plot = LinePlot::new(title);
        plot.y_range = Some((0.0, 1.45 * top));
        plot.x_label = "viewer θo (°; negative: the side opposite the light)".into();
        plot.y_label = "BRDF (1/sr)".into();
        plot.add(
            Series::new("single bounce (NDF + visibility)", one).with_color(rgb8(120, 120, 120)),
        );
        plot.add(
            Series::new("with the traced light between facets", traced)
                .with_color(rgb8(200, 60, 30)),
        );
        plot.add(
            Series::new("meso gonio --bounces 8", truth)
                .with_color(rgb8(30, 90, 200))
                .with_markers(true),
        );
        plot.render(900, 540)
            .expect("plot")
            .write_png(out.join(format!("{name}.png")))
            .expect("write the figure");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
