//! Light between facets (issue #11 item 6): `[shadowing] kind = "visibility"` with
//! `interreflection = true` (Lambert facets) against the gonioreflectometer following 8
//! bounces, on creased surfaces where the second and later bounces add a large share. Relative
//! RMSE over the far-field pairs (θ ≤ 60°), as in `tests/visibility.rs`. `IR_DEBUG=1` prints
//! the table.

use meso_core::material::Material;
use meso_maps::{fixtures, Border, Gonio, GonioParams, HeightMap, MapsResolver};
use std::path::Path;

const LAMBERT: &str = "[transfer]\nkind = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]\n";

fn rel_rmse(f: &[f64], g: &[f64]) -> f64 {
    let num: f64 = f.iter().zip(g).map(|(a, b)| (a - b) * (a - b)).sum();
    let den: f64 = g.iter().map(|b| b * b).sum();
    (num / den).sqrt()
}

/// (single-bounce error, inter-reflected error, gain of 8 bounces over 1 in the truth), each
/// relative RMSE against `meso gonio --bounces 8`.
fn errors(name: &str, map: &HeightMap) -> (f64, f64, f64) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("interreflection");
    std::fs::create_dir_all(&dir).unwrap();
    let (png, scale) = map.encode_png16().unwrap();
    std::fs::write(dir.join(format!("{name}.png")), png).unwrap();
    let mat = |ir: bool| {
        let text = format!(
            "[ndf]\nkind = \"heightmap\"\nfile = \"{name}.png\"\ntexel_size = {}\nheight_scale = {scale}\n\
             {LAMBERT}[shadowing]\nkind = \"visibility\"\ninterreflection = {ir}\n",
            map.texel_size()
        );
        let p = dir.join(format!("{name}.{ir}.toml"));
        std::fs::write(&p, text).unwrap();
        Material::from_file(&p, &MapsResolver::new()).unwrap()
    };
    let (single, multi) = (mat(false), mat(true));
    let loaded = HeightMap::load(
        &dir.join(format!("{name}.png")),
        map.texel_size(),
        scale,
        Border::Wrap,
    )
    .unwrap();
    let g = Gonio::new(&loaded).unwrap();
    let pairs = fixtures::farfield_pairs();
    let trace = |bounces| -> Vec<f64> {
        let p = GonioParams {
            rays_per_side: 192,
            bounces,
            ..GonioParams::default()
        };
        pairs
            .iter()
            .map(|&(i, o)| g.measure(&single.transfer, i, o, &p)[0])
            .collect()
    };
    let (t1, t8) = (trace(1), trace(8));
    let f1: Vec<f64> = pairs.iter().map(|&(i, o)| single.brdf(i, o)[0]).collect();
    let f8: Vec<f64> = pairs.iter().map(|&(i, o)| multi.brdf(i, o)[0]).collect();
    let gain = t8.iter().sum::<f64>() / t1.iter().sum::<f64>() - 1.0;
    let out = (rel_rmse(&f1, &t8), rel_rmse(&f8, &t8), gain);
    if std::env::var_os("IR_DEBUG").is_some() {
        eprintln!(
            "{name}: 8 bounces add {:.1}%; vs gonio --bounces 8: single bounce {:.1}%, with interreflection {:.1}%",
            100.0 * out.2,
            100.0 * out.0,
            100.0 * out.1
        );
    }
    out
}

#[test]
fn interreflection_against_eight_bounces_on_creased_surfaces() {
    let s = 1.0 / 64.0;
    let maps = [
        ("vgrooves", fixtures::v_grooves(64, 16, 0.25, s).unwrap()),
        (
            "cylinders",
            fixtures::half_cylinders(64, 16, s, 1.0).unwrap(),
        ),
        (
            "grooves",
            fixtures::half_cylinders(64, 16, s, -1.0).unwrap(),
        ),
        ("weave", fixtures::woven(64, 16, 0.06, s).unwrap()),
    ];
    for (name, map) in &maps {
        let (single, multi, gain) = errors(name, map);
        // The estimate must close most of the gap that single bounce leaves.
        assert!(
            multi < 0.5 * single || multi < 0.02,
            "{name}: single {single:.3}, interreflected {multi:.3} (8 bounces add {gain:.3})"
        );
    }
}
