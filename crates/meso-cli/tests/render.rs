//! `meso render` through the binary: the issue's Lambert sphere against the analytic image,
//! PNG output, and bad input giving an error naming the file, a non-zero exit and no image.

mod common;
use common::{cmd, tmpdir};

const SCENE: &str = r#"[camera]
kind = "orthographic"
position = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
width = 2.5                      # world units across the image
[image]
width = 256
height = 256
spp = 16
[[object]]
kind = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "white.toml"          # e.g. [transfer] kind = "lambert", albedo = [1, 1, 1], delta NDF
[[light]]
kind = "directional"
direction = [0.3, 0.4, 0.866]
irradiance = [1.0, 1.0, 1.0]
"#;

const WHITE: &str = "[ndf]\nkind = \"deltas\"\nlobes = [ { axis = [0.0, 0.0], weight = 1.0 } ]\n\
[transfer]\nkind = \"lambert\"\nalbedo = [1.0, 1.0, 1.0]\n";

/// The issue's scene: radiance = (1/π)·max(0, n·l) at every pixel fully inside the sphere.
#[test]
fn lambert_sphere_matches_analytic_image() {
    let d = tmpdir("cli-render", "lambert");
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    std::fs::write(d.join("white.toml"), WHITE).unwrap();
    let exr = d.join("out.exr");
    let png = d.join("out.png");
    let st = cmd()
        .arg("render")
        .arg(d.join("scene.toml"))
        .arg("-o")
        .arg(&exr)
        .arg("--also")
        .arg(&png)
        .status()
        .unwrap();
    assert!(st.success());
    let img = image::open(&exr).unwrap().into_rgb32f();
    assert_eq!((img.width(), img.height()), (256, 256));
    let l = glam::DVec3::new(0.3, 0.4, 0.866).normalize();
    let px = 2.5 / 256.0;
    let (mut checked, mut worst) = (0, 0.0f64);
    for j in 0..256u32 {
        for i in 0..256u32 {
            let x = -1.25 + (f64::from(i) + 0.5) * px;
            let y = 1.25 - (f64::from(j) + 0.5) * px;
            let r = (x * x + y * y).sqrt();
            if r > 1.0 - 3.0 * px {
                continue;
            }
            let n = glam::DVec3::new(x, y, (1.0 - r * r).sqrt());
            let want = n.dot(l).max(0.0) / std::f64::consts::PI;
            let got = img.get_pixel(i, j);
            for c in 0..3 {
                worst = worst.max((f64::from(got[c]) - want).abs());
            }
            checked += 1;
        }
    }
    assert!(checked > 30_000, "{checked} pixels checked");
    assert!(
        worst < 2e-3,
        "worst absolute error {worst} (radiance up to 0.318)"
    );
    // The background is black and the PNG decodes at the same size.
    assert_eq!(img.get_pixel(0, 0)[0], 0.0);
    let p = image::open(&png).unwrap();
    assert_eq!((p.width(), p.height()), (256, 256));
}

/// Bad scenes and materials: an error naming the file, non-zero exit, no image written.
#[test]
fn bad_inputs_fail_cleanly() {
    let d = tmpdir("cli-render", "bad");
    std::fs::write(d.join("white.toml"), WHITE).unwrap();
    let cases = [
        (
            "missing_material.toml",
            SCENE.replace("white.toml", "nope.toml"),
            "nope.toml",
        ),
        (
            "bad_radius.toml",
            SCENE.replace("radius = 1.0", "radius = -1.0"),
            "radius",
        ),
        (
            "unknown_key.toml",
            SCENE.replace("spp = 16", "spp = 16\nfoo = 1"),
            "foo",
        ),
    ];
    for (name, text, needle) in cases {
        std::fs::write(d.join(name), text).unwrap();
        let out = d.join(format!("{name}.exr"));
        let o = cmd()
            .arg("render")
            .arg(d.join(name))
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{name} should fail");
        assert!(
            err.contains(name),
            "{name}: error does not name the file: {err}"
        );
        assert!(
            err.contains(needle),
            "{name}: error does not name {needle}: {err}"
        );
        assert!(!out.exists(), "{name}: partial image written");
    }
    // Unknown output format.
    std::fs::write(d.join("ok.toml"), SCENE).unwrap();
    let o = cmd()
        .arg("render")
        .arg(d.join("ok.toml"))
        .arg("-o")
        .arg(d.join("x.jpg"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("x.jpg"));
}

/// A scene whose plane wears an NDF-mapped material file (`[texture]`) over a height map: it
/// renders; the same scene with the height map missing fails naming the map, writing nothing.
#[test]
fn textured_material_files_render() {
    let d = tmpdir("cli-render", "textured");
    let n = 16usize;
    let values: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f32 / n as f32, (k / n) as f32 / n as f32);
            (std::f32::consts::TAU * 2.0 * x).sin() * (std::f32::consts::TAU * 2.0 * y).sin()
        })
        .collect();
    std::fs::write(
        d.join("bumps.exr"),
        meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap(),
    )
    .unwrap();
    let material = "[texture]\nkind = \"ndf-mapped\"\nfile = \"bumps.exr\"\ntexel_size = 0.0625\n\
                    height_scale = 0.05\n[transfer]\nkind = \"phong\"\nexponent = 20.0\n";
    std::fs::write(d.join("bumpy.toml"), material).unwrap();
    std::fs::write(
        d.join("broken.toml"),
        material.replace("bumps.exr", "missing-map.exr"),
    )
    .unwrap();
    let scene = "[camera]\nkind = \"orthographic\"\nposition = [0.0, -3.0, 5.0]\n\
                 look_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nwidth = 8.0\n\
                 [image]\nwidth = 48\nheight = 48\nspp = 1\n\
                 [[object]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\
                 material = \"bumpy.toml\"\n\
                 [[light]]\nkind = \"directional\"\ndirection = [0.3, 0.4, 0.866]\n\
                 irradiance = [1.0, 1.0, 1.0]\n";
    std::fs::write(d.join("ok.scene.toml"), scene).unwrap();
    std::fs::write(
        d.join("broken.scene.toml"),
        scene.replace("bumpy.toml", "broken.toml"),
    )
    .unwrap();
    let out = d.join("ok.png");
    let o = cmd()
        .arg("render")
        .arg(d.join("ok.scene.toml"))
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::metadata(&out).unwrap().len() > 0);
    // The material says how it shades: Phong 20 facets read two levels finer than the
    // footprint (the broad facets' box detail, `meso_render::BROAD_BOX_DETAIL`), each lobe
    // shadowed by its horizon statistics.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bumpy.toml: NDF-mapped: ")
            && err.contains(" levels, box filter 2.00 levels finer, horizon shadowing per lobe"),
        "{err}"
    );
    let bad_out = d.join("broken.png");
    let o = cmd()
        .arg("render")
        .arg(d.join("broken.scene.toml"))
        .arg("-o")
        .arg(&bad_out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("missing-map.exr"), "names the map: {err}");
    assert!(!bad_out.exists(), "no image on error");
}
