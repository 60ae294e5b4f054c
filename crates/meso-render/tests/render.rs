//! Integration tests of meso-render against independent truth: closed-form images and
//! irradiances, convergence, error messages.

use glam::{DVec2, DVec3};
use meso_render::*;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-render-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The test resolver: any existing material file is a white Lambertian (albedo 1).
fn white_resolver(p: &Path) -> Result<Arc<dyn Shader>, ResolveError> {
    if p.is_file() {
        Ok(Arc::new(Lambert { albedo: [1.0; 3] }))
    } else {
        Err(format!("material file {} not found", p.display()).into())
    }
}

const ISSUE_SCENE: &str = r#"
[camera]
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
material = "white.toml"
[[light]]
kind = "directional"
direction = [0.3, 0.4, 0.866]
irradiance = [1.0, 1.0, 1.0]
"#;

#[test]
fn issue_scene_lambert_sphere_matches_the_analytic_image() {
    let dir = tmpdir("issue");
    std::fs::write(
        dir.join("white.toml"),
        "[transfer]\nkind = \"lambert\"\nalbedo = [1, 1, 1]\n",
    )
    .unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(&path, ISSUE_SCENE).unwrap();
    let scene = Scene::from_toml_file(&path, &white_resolver).unwrap();
    let img = render(&scene, &RenderOptions::default(), None);
    assert_eq!((img.width(), img.height()), (256, 256));
    let l = DVec3::new(0.3, 0.4, 0.866).normalize();
    // Analytic pixel average on an 8×8 sub-grid: L = albedo/π · E · max(0, n·l).
    let px = 2.5 / 256.0;
    let (mut max_in, mut max_all, mut sum_r, mut sum_a) = (0.0f64, 0.0f64, 0.0, 0.0);
    for j in 0..256u32 {
        for i in 0..256u32 {
            let (mut acc, mut inside) = (0.0, 0);
            for a in 0..8 {
                for b in 0..8 {
                    let x = -1.25 + (f64::from(i) + (f64::from(a) + 0.5) / 8.0) * px;
                    let y = 1.25 - (f64::from(j) + (f64::from(b) + 0.5) / 8.0) * px;
                    let r2 = x * x + y * y;
                    if r2 < 1.0 {
                        inside += 1;
                        let n = DVec3::new(x, y, (1.0 - r2).sqrt());
                        acc += n.dot(l).max(0.0) / PI;
                    }
                }
            }
            let expect = acc / 64.0;
            let got = img.get(i, j);
            assert!(
                got[0] == got[1] && got[1] == got[2],
                "white light on white stays grey"
            );
            let err = (f64::from(got[0]) - expect).abs();
            // Interior: all four pixel corners inside the disc (it is convex).
            let corner_in = (0..4).all(|c| {
                let x = -1.25 + (f64::from(i) + f64::from(c & 1)) * px;
                let y = 1.25 - (f64::from(j) + f64::from(c >> 1)) * px;
                x * x + y * y < 1.0
            });
            if corner_in {
                assert_eq!(inside, 64);
                max_in = max_in.max(err);
            }
            max_all = max_all.max(err);
            sum_r += f64::from(got[0]);
            sum_a += expect;
        }
    }
    assert!(max_in < 2e-3, "interior pixels: max error {max_in}");
    assert!(max_all < 0.06, "silhouette pixels: max error {max_all}");
    assert!(
        (sum_r / sum_a - 1.0).abs() < 2e-3,
        "image sums {sum_r} vs {sum_a}"
    );
    // The centre pixel and a pixel outside the sphere.
    assert!((f64::from(img.get(128, 128)[0]) - 0.866 / l.length().recip() / PI).abs() < 5e-3);
    assert_eq!(img.get(2, 2), [0.0; 3]);
    // Output files are written and readable.
    img.write_exr(&dir.join("out.exr")).unwrap();
    img.write_png(&dir.join("out.png"), 0.0).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A white Lambertian floor `y = 0` seen from above through an orthographic camera covering
/// `[-1, 1]²` in `x, z`; returns the scene and the world point at the centre of pixel `(i, j)`.
fn floor_scene(n: u32, spp: u32, light: Option<Light>) -> (Scene, impl Fn(u32, u32) -> DVec3) {
    let cam = Camera::new(
        Projection::Orthographic { width: 2.0 },
        DVec3::new(0.0, 5.0, 0.0),
        DVec3::ZERO,
        DVec3::NEG_Z,
    )
    .unwrap();
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            width: n,
            height: n,
            spp,
            background: [0.0; 3],
        },
    );
    let m = b.material(Arc::new(Lambert { albedo: [1.0; 3] }));
    b.quad(
        DVec3::new(-4.0, 0.0, 4.0),
        DVec3::new(8.0, 0.0, 0.0),
        DVec3::new(0.0, 0.0, -8.0),
        m,
    )
    .unwrap();
    if let Some(l) = light {
        b.light(l).unwrap();
    }
    let scene = b.build().unwrap();
    let px = 2.0 / f64::from(n);
    // Right = x, image up = -z (camera up), so y (down the image) grows with +z.
    let at = move |i: u32, j: u32| {
        DVec3::new(
            -1.0 + (f64::from(i) + 0.5) * px,
            0.0,
            -1.0 + (f64::from(j) + 0.5) * px,
        )
    };
    (scene, at)
}

fn rms_rel(img: &Image, exact: impl Fn(u32, u32) -> f64) -> (f64, f64) {
    let (mut s, mut mx, mut n) = (0.0, 0.0f64, 0.0);
    for j in 0..img.height() {
        for i in 0..img.width() {
            let e = exact(i, j);
            let r = (f64::from(img.get(i, j)[0]) - e) / e;
            s += r * r;
            mx = mx.max(r.abs());
            n += 1.0;
        }
    }
    ((s / n).sqrt(), mx)
}

#[test]
fn orthographic_camera_maps_pixels_to_world_points_on_a_floor() {
    let (scene, at) = floor_scene(40, 1, None);
    for (i, j) in [(0, 0), (39, 0), (7, 31), (20, 20)] {
        let rd = scene
            .camera
            .generate_ray(f64::from(i) + 0.5, f64::from(j) + 0.5, 40, 40);
        let sp = scene.intersect(&rd).unwrap();
        assert!(
            (sp.position - at(i, j)).length() < 1e-12,
            "{:?} vs {:?}",
            sp.position,
            at(i, j)
        );
        // Footprint: one pixel is 2/40 world units = 0.05/8 in u (edge_u has length 8).
        assert!((sp.dpdx - DVec3::new(0.05, 0.0, 0.0)).length() < 1e-12);
        assert!((sp.duvdx - DVec2::new(0.05 / 8.0, 0.0)).length() < 1e-12);
        assert!((sp.uv_footprint() - 0.05 / 8.0).abs() < 1e-12);
        assert!((sp.world_footprint() - 0.05).abs() < 1e-12);
    }
}

#[test]
fn point_light_on_a_floor_matches_inverse_square_cosine_law() {
    let lp = DVec3::new(0.2, 1.3, -0.4);
    let (scene, at) = floor_scene(
        32,
        1,
        Some(Light::Point {
            position: lp,
            intensity: DVec3::splat(3.0),
        }),
    );
    let img = render(
        &scene,
        &RenderOptions {
            spp: Some(1),
            ..Default::default()
        },
        None,
    );
    // With one sample the pixel is the radiance at a jittered point: compare against the
    // closed form at that same point is not possible from outside, so use 64 spp instead.
    let img64 = render(
        &scene,
        &RenderOptions {
            spp: Some(64),
            ..Default::default()
        },
        None,
    );
    let exact = |i, j| {
        let d = lp - at(i, j);
        3.0 * d.y / d.length().powi(3) / PI
    };
    let (rms, mx) = rms_rel(&img64, exact);
    assert!(rms < 2e-3 && mx < 1e-2, "rms {rms} max {mx}");
    let (rms1, _) = rms_rel(&img, exact);
    assert!(rms1 < 2e-2, "1 spp rms {rms1}");
}

#[test]
fn spherical_area_light_matches_pi_l_sin2_alpha() {
    let (c, r, l) = (DVec3::new(0.3, 1.5, -0.2), 0.5, 2.0);
    let light = Light::Sphere {
        center: c,
        radius: r,
        radiance: DVec3::splat(l),
    };
    let (scene, at) = floor_scene(32, 64, Some(light));
    let img = render(&scene, &RenderOptions::default(), None);
    // Unoccluded sphere wholly above the horizon: E = π L sin²α cos β, sin α = r/d.
    let exact = |i, j| {
        let d = c - at(i, j);
        let dl = d.length();
        PI * l * (r / dl).powi(2) * (d.y / dl) / PI
    };
    let (rms, mx) = rms_rel(&img, exact);
    assert!(rms < 5e-3 && mx < 2e-2, "rms {rms} max {mx}");
    // Directly below the centre: E = π L sin²α exactly.
    let p = DVec3::new(0.3, 0.0, -0.2);
    let rd = RayDifferential {
        ray: Ray {
            o: p + DVec3::Y * 5.0,
            d: DVec3::NEG_Y,
        },
        dodx: DVec3::ZERO,
        dody: DVec3::ZERO,
        dddx: DVec3::ZERO,
        dddy: DVec3::ZERO,
    };
    let sp = scene.intersect(&rd).unwrap();
    let mut e = DVec3::ZERO;
    for s in 0..4096 {
        e += shade(
            &scene,
            &sp,
            DVec3::Y,
            &sampling::PixelSampler::new(0, 0, 1, s),
        );
    }
    let e = e.x / 4096.0 * PI;
    let exact = PI * l * (r / 1.5).powi(2);
    assert!((e - exact).abs() < 1e-3 * exact, "{e} vs {exact}");
}

/// Irradiance from a uniform polygonal source (Lambert's formula):
/// `E = L/2 · |Σ_i Θ_i (n · Γ_i)|`, `Γ_i = v_i × v_{i+1} / |…|`, `Θ_i` the angle between
/// consecutive unit vectors to the vertices.
fn polygon_irradiance(p: DVec3, n: DVec3, verts: &[DVec3], l: f64) -> f64 {
    let mut s = 0.0;
    for k in 0..verts.len() {
        let a = (verts[k] - p).normalize();
        let b = (verts[(k + 1) % verts.len()] - p).normalize();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        s += theta * n.dot(a.cross(b).normalize());
    }
    0.5 * l * s.abs()
}

fn rect_light() -> (Light, [DVec3; 4]) {
    let corner = DVec3::new(-0.5, 1.0, -0.3);
    let eu = DVec3::new(1.0, 0.0, 0.0);
    let ev = DVec3::new(0.0, 0.3, 0.8);
    (
        Light::Rectangle {
            corner,
            edge_u: eu,
            edge_v: ev,
            radiance: DVec3::splat(1.5),
            two_sided: false,
        },
        [corner, corner + eu, corner + eu + ev, corner + ev],
    )
}

#[test]
fn rectangular_area_light_matches_the_polygon_form_factor() {
    let (light, verts) = rect_light();
    let (scene, at) = floor_scene(24, 256, Some(light));
    let img = render(&scene, &RenderOptions::default(), None);
    let exact = |i, j| polygon_irradiance(at(i, j), DVec3::Y, &verts, 1.5) / PI;
    let (rms, mx) = rms_rel(&img, exact);
    assert!(rms < 1e-2 && mx < 4e-2, "rms {rms} max {mx}");
    // The closed form for a parallel rectangle with a corner above the point agrees with the
    // polygon formula (checks the reference itself).
    let (a, b, h): (f64, f64, f64) = (0.8, 0.6, 0.5);
    let (x, y) = (a / h, b / h);
    let f = (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
        + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan())
        / (2.0 * PI);
    let poly = polygon_irradiance(
        DVec3::ZERO,
        DVec3::Y,
        &[
            DVec3::new(0.0, h, 0.0),
            DVec3::new(a, h, 0.0),
            DVec3::new(a, h, b),
            DVec3::new(0.0, h, b),
        ],
        1.0,
    );
    assert!((poly - PI * f).abs() < 1e-12, "{poly} vs {}", PI * f);
}

#[test]
fn error_falls_as_spp_grows() {
    let (light, verts) = rect_light();
    let (scene, at) = floor_scene(24, 1, Some(light));
    let exact = |i, j| polygon_irradiance(at(i, j), DVec3::Y, &verts, 1.5) / PI;
    let errs: Vec<f64> = [1u32, 4, 16, 64]
        .iter()
        .map(|&spp| {
            rms_rel(
                &render(
                    &scene,
                    &RenderOptions {
                        spp: Some(spp),
                        seed: 3,
                        ..Default::default()
                    },
                    None,
                ),
                exact,
            )
            .0
        })
        .collect();
    for k in 1..errs.len() {
        assert!(errs[k] < 0.6 * errs[k - 1], "rms errors {errs:?}");
    }
}

#[test]
fn constant_environment_gives_pi_l_irradiance() {
    let (scene, _) = floor_scene(16, 256, None);
    let mut scene = scene;
    scene.environment = Some(Arc::new(EnvironmentMap::constant([0.7, 0.7, 0.7]).unwrap()));
    let img = render(&scene, &RenderOptions::default(), None);
    let mean: f64 = img.pixels().iter().map(|p| f64::from(p[0])).sum::<f64>() / 256.0;
    // E = π L on the upward floor; the Lambert floor reflects L_o = E/π = L.
    assert!((mean - 0.7).abs() < 0.01 * 0.7, "{mean}");
}

#[test]
fn environment_map_from_an_exr_file_is_importance_sampled_to_the_analytic_irradiance() {
    // L(d) = 1 + d.y on a 64×32 map, written as EXR and loaded through a scene file.
    let dir = tmpdir("env");
    let (w, h) = (64u32, 32u32);
    let mut map = Image::new(w, h);
    for j in 0..h {
        // The exact mean of 1 + cos θ over the row's solid angle.
        let (t0, t1) = (
            PI * f64::from(j) / f64::from(h),
            PI * f64::from(j + 1) / f64::from(h),
        );
        let mean = 1.0 + 0.5 * (t1.sin().powi(2) - t0.sin().powi(2)) / (t0.cos() - t1.cos());
        for i in 0..w {
            map.set(i, j, [mean as f32; 3]);
        }
    }
    map.write_exr(&dir.join("sky.exr")).unwrap();
    std::fs::write(dir.join("white.toml"), "").unwrap();
    let scene_text = r#"
[camera]
kind = "orthographic"
position = [0.0, 5.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
width = 2.0
[image]
width = 16
height = 16
spp = 256
[[object]]
kind = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "white.toml"
[environment]
file = "sky.exr"
"#;
    std::fs::write(dir.join("s.toml"), scene_text).unwrap();
    let scene = Scene::from_toml_file(&dir.join("s.toml"), &white_resolver).unwrap();
    let img = render(&scene, &RenderOptions::default(), None);
    let mean: f64 = img.pixels().iter().map(|p| f64::from(p[0])).sum::<f64>() / 256.0;
    // E = ∫_{upper} (1 + cos θ) cos θ dω = π + 2π/3; L_o = E/π = 5/3.
    assert!((mean - 5.0 / 3.0).abs() < 0.01 * 5.0 / 3.0, "{mean}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn multiple_surface_equals_the_sum_of_its_single_normal_renders() {
    // Eq. 4: a material whose NDF is a sum of deltas shades as the sum of single-normal shadings.
    let lobes = [
        (DVec3::new(0.3, 0.0, 1.0).normalize(), 0.4, 12.0),
        (DVec3::new(-0.2, 0.4, 1.0).normalize(), 0.3, 30.0),
        (DVec3::new(0.0, -0.5, 1.0).normalize(), 0.3, 5.0),
    ];
    let mk = |ls: &[(DVec3, f64, f64)]| {
        let cam = Camera::new(
            Projection::Perspective { fov_deg: 40.0 },
            DVec3::new(0.0, 0.5, 4.0),
            DVec3::ZERO,
            DVec3::Y,
        )
        .unwrap();
        let mut b = SceneBuilder::new(
            cam,
            ImageSettings {
                width: 48,
                height: 40,
                spp: 4,
                background: [0.0; 3],
            },
        );
        let m = b.material(Arc::new(PhongLobes::new(ls, [1.0, 0.8, 0.6]).unwrap()));
        b.sphere(DVec3::ZERO, 1.0, DVec3::Y, m).unwrap();
        b.light(Light::Point {
            position: DVec3::new(2.0, 3.0, 3.0),
            intensity: DVec3::splat(10.0),
        })
        .unwrap();
        b.light(Light::Linear {
            start: DVec3::new(-2.0, 2.0, 1.0),
            end: DVec3::new(-1.0, 2.5, 2.0),
            intensity: DVec3::splat(3.0),
        })
        .unwrap();
        render(&b.build().unwrap(), &RenderOptions::default(), None)
    };
    let all = mk(&lobes);
    let parts: Vec<Image> = lobes.iter().map(|l| mk(std::slice::from_ref(l))).collect();
    let mut nonzero = 0;
    for (k, p) in all.pixels().iter().enumerate() {
        for (c, &pc) in p.iter().enumerate() {
            let s: f32 = parts.iter().map(|im| im.pixels()[k][c]).sum();
            assert!(
                (pc - s).abs() <= 1e-5 * s.max(1e-3),
                "pixel {k}: {pc} vs {s}"
            );
            if s > 1e-3 {
                nonzero += 1;
            }
        }
    }
    assert!(nonzero > 500);
}

#[test]
fn sphere_tangents_are_orthonormal_and_follow_the_uv_directions() {
    let cam = Camera::new(
        Projection::Perspective { fov_deg: 50.0 },
        DVec3::new(0.5, 0.8, 4.0),
        DVec3::ZERO,
        DVec3::Y,
    )
    .unwrap();
    let mut b = SceneBuilder::new(cam, ImageSettings::default());
    let m = b.material(Arc::new(Lambert { albedo: [1.0; 3] }));
    let pole = DVec3::new(0.2, 1.0, 0.3).normalize();
    b.sphere(DVec3::new(0.1, 0.0, 0.0), 1.0, pole, m).unwrap();
    let scene = b.build().unwrap();
    let mut n = 0;
    for j in 0..32 {
        for i in 0..32 {
            let rd = scene.camera.generate_ray(
                f64::from(i) * 8.0 + 4.0,
                f64::from(j) * 8.0 + 4.0,
                256,
                256,
            );
            let Some(sp) = scene.intersect(&rd) else {
                continue;
            };
            n += 1;
            let f = sp.frame;
            assert!(
                f.t.dot(f.b).abs() < 1e-12
                    && f.t.dot(f.n).abs() < 1e-12
                    && f.b.dot(f.n).abs() < 1e-12
            );
            assert!((f.t.cross(f.b) - f.n).length() < 1e-12);
            assert!(f.t.dot(pole).abs() < 1e-12, "tangent goes around the pole");
            assert!((f.t.dot(sp.dpdu.normalize()) - 1.0).abs() < 1e-12);
            assert!(
                f.b.dot(sp.dpdv) < 0.0,
                "b points up the image, against ∂p/∂v"
            );
            // Finite differences: moving along +t increases u; along +b (towards the pole, up
            // the image) decreases v (glTF's v grows down the image).
            let p = sp.position;
            let probe = |q: DVec3| {
                let c = DVec3::new(0.1, 0.0, 0.0);
                let dir = (q - c).normalize();
                let o = c + dir * 3.0;
                scene.intersect_ray(&Ray { o, d: -dir }).unwrap().1.uv
            };
            let du = probe(p + f.t * 1e-5).x - sp.uv.x;
            let dv = probe(p + f.b * 1e-5).y - sp.uv.y;
            if du.abs() < 0.5 {
                assert!(du > 0.0, "u grows along t");
            }
            assert!(dv < 0.0, "v falls along b");
        }
    }
    assert!(n > 150, "{n} hits");
}

/// A wavy grid mesh as OBJ text, with UVs rotated by 30° relative to the x/z axes and no
/// normals, so tangents must come from the UV derivatives.
fn wavy_obj(nx: usize) -> String {
    let mut s = String::from("# wavy grid\n");
    let (c, sn) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    for j in 0..=nx {
        for i in 0..=nx {
            let x = -1.0 + 2.0 * i as f64 / nx as f64;
            let z = -1.0 + 2.0 * j as f64 / nx as f64;
            let y = 0.15 * (3.0 * x).sin() * (2.0 * z).cos();
            s += &format!("v {x} {y} {z}\n");
            s += &format!("vt {} {}\n", c * x + sn * z, sn * x - c * z);
        }
    }
    for j in 0..nx {
        for i in 0..nx {
            let a = j * (nx + 1) + i + 1;
            let (b, cc, d) = (a + 1, a + nx + 2, a + nx + 1);
            // Counter-clockwise seen from +y.
            s += &format!("f {a}/{a} {d}/{d} {cc}/{cc} {b}/{b}\n");
        }
    }
    s
}

#[test]
fn mesh_tangents_are_orthonormal_and_consistent_with_uvs() {
    let dir = tmpdir("mesh");
    std::fs::write(dir.join("wavy.obj"), wavy_obj(24)).unwrap();
    std::fs::write(dir.join("white.toml"), "").unwrap();
    let text = r#"
[camera]
kind = "orthographic"
position = [0.0, 5.0, 0.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
width = 1.8
[image]
width = 32
height = 32
spp = 1
[[object]]
kind = "mesh"
file = "wavy.obj"
material = "white.toml"
"#;
    std::fs::write(dir.join("s.toml"), text).unwrap();
    let scene = Scene::from_toml_file(&dir.join("s.toml"), &white_resolver).unwrap();
    assert_eq!(scene.primitive_count(), 24 * 24 * 2);
    let mut n = 0;
    for j in 0..32 {
        for i in 0..32 {
            let rd = scene
                .camera
                .generate_ray(f64::from(i) + 0.5, f64::from(j) + 0.5, 32, 32);
            let sp = scene.intersect(&rd).unwrap();
            n += 1;
            let f = sp.frame;
            assert!((f.t.length() - 1.0).abs() < 1e-12 && (f.b.length() - 1.0).abs() < 1e-12);
            assert!(
                f.t.dot(f.n).abs() < 1e-12
                    && f.b.dot(f.n).abs() < 1e-12
                    && f.t.dot(f.b).abs() < 1e-12
            );
            assert!((f.t.cross(f.b) - f.n).length() < 1e-12);
            assert!(f.n.y > 0.0, "faces the camera");
            // The tangent follows ∂p/∂u of the hit triangle (smoothly averaged: within ~10°).
            let dpdu = sp.dpdu.normalize();
            assert!(f.t.dot(dpdu) > 0.98, "t·dpdu = {}", f.t.dot(dpdu));
            // The OBJ's v grows up the image; loaded as glTF's (down the image), ∂p/∂v points
            // down it, and b up it.
            assert!(f.b.dot(sp.dpdv) < 0.0);
            // The projection on the x/z plane of ∂p/∂u is the 30° rotated axis.
            let flat = DVec3::new(dpdu.x, 0.0, dpdu.z).normalize();
            let expect = DVec3::new(30f64.to_radians().cos(), 0.0, 30f64.to_radians().sin());
            assert!(flat.dot(expect) > 1.0 - 1e-9, "{flat:?}");
            // The footprint is one pixel.
            assert!((sp.dpdx.x - 1.8 / 32.0).abs() < 1e-9);
        }
    }
    assert_eq!(n, 1024);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn generated_mesh_tangents_on_a_uv_sphere_follow_the_parallels() {
    // A lat-long sphere mesh (pole +y) with normals and UVs u = φ/2π, v = θ/π (glTF: the
    // image's top row at the pole).
    let (nu, nv) = (48usize, 24usize);
    let (mut pos, mut nrm, mut uv, mut idx) = (vec![], vec![], vec![], vec![]);
    for j in 0..=nv {
        for i in 0..=nu {
            let (u, v) = (i as f64 / nu as f64, j as f64 / nv as f64);
            let (th, ph) = (PI * v, 2.0 * PI * u);
            let p = DVec3::new(th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin());
            pos.push(p);
            nrm.push(p);
            uv.push(DVec2::new(u, v));
        }
    }
    for j in 0..nv {
        for i in 0..nu {
            let a = (j * (nu + 1) + i) as u32;
            let (b, c, d) = (a + 1, a + nu as u32 + 2, a + nu as u32 + 1);
            idx.push([a, d, c]);
            idx.push([a, c, b]);
        }
    }
    let mesh = Mesh::new(pos.clone(), Some(nrm), Some(uv), None, idx).unwrap();
    for (k, (&p, &t)) in pos.iter().zip(mesh.tangents()).enumerate() {
        let along = DVec3::Y.cross(p); // ∂p/∂φ direction for u = φ/2π with z = -sinθ sinφ
        if along.length() < 0.3 {
            continue; // near the poles the parallels shrink
        }
        assert!(
            (t.length() - 1.0).abs() < 1e-12 && t.dot(p).abs() < 1e-9,
            "vertex {k}"
        );
        assert!(
            t.dot(along.normalize()) > 0.99,
            "vertex {k}: {}",
            t.dot(along.normalize())
        );
    }
}

#[test]
fn broken_and_missing_files_give_errors_naming_the_file() {
    let dir = tmpdir("errors");
    std::fs::write(dir.join("white.toml"), "").unwrap();
    std::fs::write(
        dir.join("bad.obj"),
        "v 1.0 2.0 zz\nv 0 0 0\nv 1 0 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(dir.join("sky.exr"), b"this is not an exr file").unwrap();
    let head = ISSUE_SCENE.split("[[object]]").next().unwrap().to_string();
    let cases: Vec<(String, &str)> = vec![
        (format!("{head}[[object]]\nkind = \"mesh\"\nfile = \"bad.obj\"\nmaterial = \"white.toml\"\n"), "bad.obj"),
        (format!("{head}[[object]]\nkind = \"mesh\"\nfile = \"none.obj\"\nmaterial = \"white.toml\"\n"), "none.obj"),
        (format!("{head}[environment]\nfile = \"sky.exr\"\n"), "sky.exr"),
        (format!("{head}[environment]\nfile = \"nosky.exr\"\n"), "nosky.exr"),
        (ISSUE_SCENE.replace("radius = 1.0", "radius = -1.0"), "object[0].radius"),
        (ISSUE_SCENE.replace("radius = 1.0", "radius = 1.0\nradiu = 2.0"), "radiu"),
        (ISSUE_SCENE.replace("white.toml", "black.toml"), "object[0].material"),
        (ISSUE_SCENE.replace("irradiance = [1.0, 1.0, 1.0]", "irradiance = [1.0, -1.0, 1.0]"), "light[0].irradiance"),
        (ISSUE_SCENE.replace("direction = [0.3, 0.4, 0.866]", "direction = [0.0, 0.0, 0.0]"), "light[0].direction"),
        (ISSUE_SCENE.replace("spp = 16", "spp = 0"), "image.spp"),
        (ISSUE_SCENE.replace("kind = \"orthographic\"", "kind = \"fisheye\""), "fisheye"),
        (ISSUE_SCENE.replace("width = 2.5", "width = 0.0"), "camera.width"),
    ];
    for (k, (text, needle)) in cases.iter().enumerate() {
        let p = dir.join(format!("case{k}.toml"));
        std::fs::write(&p, text).unwrap();
        let e = match Scene::from_toml_file(&p, &white_resolver) {
            Ok(_) => panic!("case {k} should fail"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains(needle), "case {k}: `{e}` should name `{needle}`");
        if !needle.contains('.') || needle.ends_with(".obj") || needle.ends_with(".exr") {
            // file errors name the file; schema errors name the scene file
        } else {
            assert!(
                e.contains(&format!("case{k}.toml")),
                "case {k}: `{e}` should name the scene file"
            );
        }
    }
    let e = Scene::from_toml_file(&dir.join("missing.toml"), &white_resolver).unwrap_err();
    assert!(e.to_string().contains("missing.toml"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn progress_reports_every_tile_and_options_override_the_size() {
    let (scene, _) = floor_scene(
        16,
        1,
        Some(Light::Directional {
            direction: DVec3::Y,
            irradiance: DVec3::ONE,
        }),
    );
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let last = std::sync::Mutex::new((0, 0));
    let cb = |d: usize, t: usize| {
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut l = last.lock().unwrap();
        if d > l.0 {
            *l = (d, t);
        }
    };
    let img = render(
        &scene,
        &RenderOptions {
            width: Some(70),
            height: Some(33),
            tile_size: 16,
            ..Default::default()
        },
        Some(&cb),
    );
    assert_eq!((img.width(), img.height()), (70, 33));
    assert_eq!(calls.into_inner(), 5 * 3);
    assert_eq!(*last.lock().unwrap(), (15, 15));
    // The floor under a vertical unit irradiance reflects 1/π everywhere.
    for p in img.pixels() {
        assert!((f64::from(p[0]) - 1.0 / PI).abs() < 1e-6);
    }
}

#[test]
fn more_lights_than_one_batch_add_up() {
    // 37 point lights (more than two batches of LIGHT_BATCH) vs the closed form of their sum.
    let lights: Vec<DVec3> = (0..37)
        .map(|k| {
            let a = 2.0 * PI * f64::from(k) / 37.0;
            DVec3::new(1.5 * a.cos(), 1.0 + 0.02 * f64::from(k), 1.5 * a.sin())
        })
        .collect();
    let (scene, at) = floor_scene(12, 1, None);
    let mut scene = scene;
    scene.lights = lights
        .iter()
        .map(|&p| Light::Point {
            position: p,
            intensity: DVec3::splat(0.5),
        })
        .collect();
    let img = render(
        &scene,
        &RenderOptions {
            spp: Some(16),
            ..Default::default()
        },
        None,
    );
    let exact = |i, j| {
        let q: DVec3 = at(i, j);
        lights
            .iter()
            .map(|&p| {
                let d = p - q;
                0.5 * d.y / d.length().powi(3)
            })
            .sum::<f64>()
            / PI
    };
    let (rms, mx) = rms_rel(&img, exact);
    assert!(rms < 1e-3 && mx < 5e-3, "rms {rms} max {mx}");
    const { assert!(meso_render::render::LIGHT_BATCH < 37) };
}
