//! The stream-shading path (tiles shaded light by light, `eval_pairs`) against the per-hit
//! path (each hit shaded on its own, `eval_many`): the two must give the same image, to f32
//! rounding, on scenes that exercise every shape, every kind of light, shadows, several
//! materials and several samples per pixel.

use glam::{DVec2, DVec3};
use meso_core::material::Material;
use meso_render::*;
use std::sync::Arc;

/// Fig. 2d's multiple surface of seven normals (`meso_core::catalogue`).
fn seven_normals() -> Material {
    meso_core::catalogue::seven_normals().material()
}

fn ggx() -> Material {
    Material::from_toml_str(
        "form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha_x = 0.3\nalpha_y = 0.15\n\
         [transfer]\nkind = \"mirror\"\n",
    )
    .expect("valid material")
}

fn lobes() -> PhongLobes {
    let mut l = vec![(DVec3::Z, 0.4, 40.0)];
    for k in 0..6 {
        let a = std::f64::consts::PI * f64::from(k) / 3.0;
        l.push((
            DVec3::new(0.35 * a.cos(), 0.35 * a.sin(), 1.0).normalize(),
            0.1,
            20.0 + 5.0 * f64::from(k),
        ));
    }
    PhongLobes::new(&l, [1.0, 0.9, 0.8]).expect("lobes")
}

/// A tilted grid mesh with UVs (generated tangents).
fn grid() -> Mesh {
    let n = 6;
    let mut pos = Vec::new();
    let mut uv = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (
                -1.0 + 2.0 * f64::from(i) / f64::from(n),
                -1.0 + 2.0 * f64::from(j) / f64::from(n),
            );
            pos.push(DVec3::new(x + 1.2, 0.2 * (2.0 * x).sin() - 0.9, z));
            uv.push(DVec2::new(x, z));
        }
    }
    let mut idx = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            idx.push([a, a + n + 1, a + 1]);
            idx.push([a + 1, a + n + 1, a + n + 2]);
        }
    }
    Mesh::new(pos, None, Some(uv), None, idx).expect("mesh")
}

fn scene(spp: u32, with_env: bool) -> Scene {
    let cam = Camera::new(
        Projection::Perspective { fov_deg: 50.0 },
        DVec3::new(0.3, 1.5, 4.0),
        DVec3::new(0.0, -0.3, 0.0),
        DVec3::Y,
    )
    .expect("camera");
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            width: 67,
            height: 45,
            spp,
            background: [0.05, 0.1, 0.2],
        },
    );
    let m_seven = b.material(Arc::new(MaterialShader::new(&seven_normals())));
    let m_ggx = b.material(Arc::new(MaterialShader::new(&ggx())));
    let m_lobes = b.material(Arc::new(lobes()));
    let m_white = b.material(Arc::new(Lambert {
        albedo: [0.8, 0.7, 0.6],
    }));
    b.sphere(DVec3::new(-0.6, 0.0, 0.0), 0.7, DVec3::Y, m_seven)
        .expect("sphere");
    b.sphere(DVec3::new(0.7, 0.1, -0.4), 0.5, DVec3::X, m_ggx)
        .expect("sphere");
    b.quad(
        DVec3::new(-0.4, -0.5, 1.0),
        DVec3::new(0.6, 0.0, 0.0),
        DVec3::new(0.0, 0.5, 0.2),
        m_lobes,
    )
    .expect("quad");
    b.plane(DVec3::new(0.0, -1.0, 0.0), DVec3::Y, DVec3::X, 1.0, m_white)
        .expect("plane");
    b.mesh(Arc::new(grid()), m_lobes);
    for l in [
        Light::Point {
            position: DVec3::new(2.0, 3.0, 2.0),
            intensity: DVec3::splat(12.0),
        },
        Light::Directional {
            direction: DVec3::new(-0.3, 0.8, 0.5).normalize(),
            irradiance: DVec3::new(0.8, 0.7, 0.6),
        },
        Light::Sphere {
            center: DVec3::new(-2.0, 2.0, 1.0),
            radius: 0.4,
            radiance: DVec3::splat(3.0),
        },
        Light::Rectangle {
            corner: DVec3::new(-0.5, 2.5, -1.0),
            edge_u: DVec3::new(1.0, 0.0, 0.0),
            edge_v: DVec3::new(0.0, 0.0, 0.8),
            radiance: DVec3::splat(2.0),
            two_sided: true,
        },
        Light::Linear {
            start: DVec3::new(1.5, 1.0, 2.0),
            end: DVec3::new(2.5, 1.0, 0.5),
            intensity: DVec3::splat(4.0),
        },
    ] {
        b.light(l).expect("light");
    }
    if with_env {
        b.environment(
            Arc::new(EnvironmentMap::constant([0.2, 0.25, 0.3]).expect("env")),
            true,
        );
    }
    b.build().expect("scene")
}

fn assert_same(a: &Image, b: &Image, what: &str) {
    let mut worst = 0.0f32;
    let mut lit = 0;
    for (p, q) in a.pixels().iter().zip(b.pixels()) {
        for c in 0..3 {
            let d = (p[c] - q[c]).abs() / q[c].abs().max(1e-3);
            worst = worst.max(d);
            if q[c] > 1e-3 {
                lit += 1;
            }
        }
    }
    assert!(lit > a.pixels().len(), "{what}: the scene is mostly dark");
    assert!(worst < 2e-5, "{what}: worst relative difference {worst}");
}

/// Render `scene` by the stream path (the default) and by the per-hit path; same image.
fn assert_paths_agree(scene: &Scene, opts: RenderOptions, what: &str) {
    let stream = render(scene, &opts, None);
    let per_hit = render(
        scene,
        &RenderOptions {
            per_hit: true,
            ..opts
        },
        None,
    );
    assert_same(&stream, &per_hit, what);
}

#[test]
fn stream_matches_per_hit_path() {
    for (spp, env) in [(1, false), (4, true), (3, false)] {
        let s = scene(spp, env);
        for seed in [0, 5] {
            let opts = RenderOptions {
                seed,
                tile_size: 16,
                ..RenderOptions::default()
            };
            assert_paths_agree(
                &s,
                opts,
                &format!("spp {spp}, environment {env}, seed {seed}"),
            );
        }
    }
}

#[test]
fn direction_only_shaders_evaluate_pairs_like_eval() {
    let shaders: Vec<Arc<dyn Shader>> = vec![
        Arc::new(MaterialShader::new(&seven_normals())),
        Arc::new(MaterialShader::new(&ggx())),
        Arc::new(lobes()),
        Arc::new(Lambert {
            albedo: [0.5, 0.25, 1.0],
        }),
    ];
    // 37 pairs (not a multiple of the kernel's 8 lanes), some below the horizon.
    let dirs: Vec<(DVec3, DVec3)> = (0..37)
        .map(|k| {
            let a = 0.37 * f64::from(k);
            let wi = DVec3::new(a.cos(), a.sin(), 1.1 - 0.06 * f64::from(k)).normalize();
            let wo = DVec3::new(0.3 * (2.0 * a).sin(), -0.2, 0.9 - 0.03 * f64::from(k)).normalize();
            (wi, wo)
        })
        .collect();
    let soa = |f: fn(&(DVec3, DVec3)) -> DVec3| -> [Vec<f32>; 3] {
        let v: Vec<DVec3> = dirs.iter().map(f).collect();
        [0, 1, 2].map(|c| v.iter().map(|d| d[c] as f32).collect())
    };
    let (wi, wo) = (soa(|p| p.0), soa(|p| p.1));
    let sp = meso_render::material::local_point(DVec2::ZERO, 0.0);
    for s in &shaders {
        assert!(s.direction_only());
        let mut out = [vec![0.0f32; 37], vec![0.0f32; 37], vec![0.0f32; 37]];
        let [o0, o1, o2] = &mut out;
        s.eval_pairs(
            [&wi[0], &wi[1], &wi[2]],
            [&wo[0], &wo[1], &wo[2]],
            [o0, o1, o2],
        );
        let mut nonzero = 0;
        for (k, (i, o)) in dirs.iter().enumerate() {
            // The pairs are given in f32: evaluate the reference at the same rounded directions.
            let r = |v: DVec3| DVec3::new(v.x as f32 as f64, v.y as f32 as f64, v.z as f32 as f64);
            let want = s.eval(&sp, r(*i), r(*o));
            for c in 0..3 {
                let got = out[c][k];
                assert!(
                    (got - want[c]).abs() <= 1e-4 * want[c].abs().max(1e-3),
                    "pair {k} channel {c}: {got} vs {}",
                    want[c]
                );
                if want[c] > 0.0 {
                    nonzero += 1;
                }
            }
        }
        assert!(nonzero > 30, "too few lit pairs: {nonzero}");
    }
}

/// Spheres only (the vectorised camera-ray path of sphere-only scenes): overlapping spheres,
/// one seen from inside (the camera sits in it), one with its pole straight at the camera
/// (the tangent frame's fallback at the pixel through the pole), shadows between them.
fn spheres_only(spp: u32, projection: Projection) -> Scene {
    let cam =
        Camera::new(projection, DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y).expect("camera");
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            // Odd sizes: the middle pixel's ray runs through the centre of the image.
            width: 71,
            height: 65,
            spp,
            background: [0.05, 0.1, 0.2],
        },
    );
    let m_seven = b.material(Arc::new(MaterialShader::new(&seven_normals())));
    let m_lobes = b.material(Arc::new(lobes()));
    let m_white = b.material(Arc::new(Lambert {
        albedo: [0.8, 0.7, 0.6],
    }));
    b.sphere(DVec3::ZERO, 0.8, DVec3::Z, m_seven)
        .expect("sphere");
    b.sphere(DVec3::new(0.9, 0.5, -0.3), 0.6, DVec3::X, m_lobes)
        .expect("sphere");
    b.sphere(DVec3::new(-0.8, -0.6, 0.9), 0.35, DVec3::Y, m_lobes)
        .expect("sphere");
    b.sphere(DVec3::new(0.0, 0.0, 1.0), 8.0, DVec3::Y, m_white)
        .expect("sphere");
    for l in [
        Light::Point {
            position: DVec3::new(1.0, 2.0, 3.0),
            intensity: DVec3::splat(12.0),
        },
        Light::Directional {
            direction: DVec3::new(-0.3, 0.8, 0.5).normalize(),
            irradiance: DVec3::new(0.8, 0.7, 0.6),
        },
        Light::Sphere {
            center: DVec3::new(-2.0, 2.0, 2.0),
            radius: 0.4,
            radiance: DVec3::splat(3.0),
        },
    ] {
        b.light(l).expect("light");
    }
    b.build().expect("scene")
}

#[test]
fn stream_matches_per_hit_path_on_sphere_only_scenes() {
    for projection in [
        Projection::Orthographic { width: 3.0 },
        Projection::Perspective { fov_deg: 45.0 },
    ] {
        for spp in [1, 3] {
            let s = spheres_only(spp, projection);
            // Wider tiles than a row segment of the sphere path (64 pixels) and narrow ones.
            for tile_size in [7, 70] {
                let opts = RenderOptions {
                    tile_size,
                    ..RenderOptions::default()
                };
                assert_paths_agree(
                    &s,
                    opts,
                    &format!("{projection:?}, spp {spp}, tiles of {tile_size}"),
                );
            }
        }
    }
}
