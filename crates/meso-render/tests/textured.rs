//! Textured materials in scene files (`[texture]`, `meso_render::load_textured`): a height map
//! written to disk, a bump-mapped and an NDF-mapped material file over it, a scene file per
//! material. The NDF-mapped render at 1 spp must agree with the bump-mapped one supersampled at
//! 256 spp (the ground truth) at a zoomed-out view; bad files give errors naming the problem.

use meso_render::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A 32 × 32 egg crate (4 × 4 bumps, slopes up to ≈ 40°) as a float EXR: `h = value · H`.
fn write_fixture(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    let n = 32usize;
    let tau = std::f64::consts::TAU;
    let values: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64 / n as f64, (k / n) as f64 / n as f64);
            ((tau * 4.0 * x).sin() * (tau * 4.0 * y).sin()) as f32
        })
        .collect();
    let exr = meso_maps::fixtures::exr_bytes(n as u32, n as u32, &values).unwrap();
    std::fs::write(dir.join("bumps.exr"), exr).unwrap();
    let surface = "[transfer]\nkind = \"phong\"\nexponent = 20.0\nspecular = [0.6, 0.6, 0.6]\n\
                   [diffuse]\nalbedo = [0.5, 0.4, 0.3]\n";
    for kind in ["ndf-mapped", "bump-mapped"] {
        std::fs::write(
            dir.join(format!("{kind}.toml")),
            format!(
                "[texture]\nkind = \"{kind}\"\nfile = \"bumps.exr\"\ntexel_size = 0.03125\n\
                 height_scale = 0.035\n{surface}"
            ),
        )
        .unwrap();
    }
    std::fs::write(
        dir.join("ndf-box.toml"),
        format!(
            "[texture]\nkind = \"ndf-mapped\"\nfilter = \"box\"\nfile = \"bumps.exr\"\n\
             texel_size = 0.03125\nheight_scale = 0.035\n{surface}"
        ),
    )
    .unwrap();
    std::fs::write(
        dir.join("ndf-detail.toml"),
        format!(
            "[texture]\nkind = \"ndf-mapped\"\nbox_detail = 0\nfile = \"bumps.exr\"\n\
             texel_size = 0.03125\nheight_scale = 0.035\n{surface}"
        ),
    )
    .unwrap();
    std::fs::write(dir.join("plain.toml"), surface).unwrap();
}

/// A plane seen at ≈ 24° from its normal, one map tile per world unit, `width` tiles across
/// the image.
fn scene_text(material: &str, width: f64, spp: u32) -> String {
    format!(
        "[camera]\nkind = \"orthographic\"\nposition = [0.0, -20.0, 45.0]\nlook_at = [0.0, 0.0, 0.0]\n\
         up = [0.0, 1.0, 0.0]\nwidth = {width}\n[image]\nwidth = 64\nheight = 64\nspp = {spp}\n\
         [[object]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\
         tangent = [1.0, 0.0, 0.0]\nmaterial = \"{material}\"\n\
         [[light]]\nkind = \"directional\"\ndirection = [-0.5, 0.3, 0.8]\nirradiance = [2.0, 2.0, 2.0]\n"
    )
}

fn resolver(path: &Path) -> Result<Arc<dyn Shader>, ResolveError> {
    let maps = meso_maps::MapsResolver::new();
    if let Some(s) = load_textured(path, &maps)? {
        return Ok(s);
    }
    let m = meso_core::material::Material::from_file(path, &maps)?;
    Ok(Arc::new(MaterialShader::new(&m)))
}

fn render_file(dir: &Path, material: &str, width: f64, spp: u32) -> Image {
    let p = dir.join(format!("{material}-{spp}.scene.toml"));
    std::fs::write(&p, scene_text(&format!("{material}.toml"), width, spp)).unwrap();
    let scene = Scene::from_toml_file(&p, &resolver).unwrap();
    render(&scene, &RenderOptions::default(), None)
}

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    write_fixture(&d);
    d
}

fn mean(img: &Image) -> f64 {
    img.pixels()
        .iter()
        .map(|p| f64::from(p[0] + p[1] + p[2]))
        .sum::<f64>()
        / img.pixels().len() as f64
}

#[test]
fn ndf_mapped_file_matches_supersampled_bump_mapped_file() {
    let d = dir("textured_match");
    // 20 tiles over 64 px: 10 height-map cells per pixel.
    filtered_matches_texel_by_texel(&d, "ndf-mapped", "bump-mapped");
}

/// At 10 map cells per pixel (20 tiles over 64 px) the NDF-mapped material `ndf` at 1 spp is
/// within 5% (image) and 3% (mean) of the texel-by-texel one `bump` at 256 spp, and the flat
/// surface of the same facets is more than 10% off (the bumps matter).
fn filtered_matches_texel_by_texel(d: &Path, ndf: &str, bump: &str) {
    let (ndf_img, bump_img) = (
        render_file(d, ndf, 20.0, 1),
        render_file(d, bump, 20.0, 256),
    );
    let plain = render_file(d, "plain", 20.0, 1);
    let (mut num, mut den) = (0.0, 0.0);
    for (p, q) in ndf_img.pixels().iter().zip(bump_img.pixels()) {
        for c in 0..3 {
            num += f64::from((p[c] - q[c]).abs());
            den += f64::from(q[c]);
        }
    }
    let err = num / den;
    let ratio = mean(&ndf_img) / mean(&bump_img);
    eprintln!("{ndf} 1 spp vs {bump} 256 spp: error {err:.4}, mean ratio {ratio:.4}");
    assert!(err < 0.05, "image error {err}");
    assert!((ratio - 1.0).abs() < 0.03, "mean ratio {ratio}");
    let flat = mean(&plain) / mean(&bump_img);
    assert!((flat - 1.0).abs() > 0.1, "flat/bumpy {flat}");
}

/// `filter = "box"` (NdfMapped::with_box_filter) reaches the scene file and matches too.
#[test]
fn box_filtered_file_matches_supersampled_bump_mapped_file() {
    let d = dir("textured_box");
    filtered_matches_texel_by_texel(&d, "ndf-box", "bump-mapped");
}

/// `box_detail = 0` (NdfMapped::with_box_detail) reaches the scene file: the image differs from
/// the default's (Phong 20 facets: detail 2), reading two levels coarser, and still matches.
#[test]
fn box_detail_reaches_the_scene_file_and_matches() {
    let d = dir("textured_detail");
    filtered_matches_texel_by_texel(&d, "ndf-detail", "bump-mapped");
    let (a, b) = (
        render_file(&d, "ndf-detail", 20.0, 1),
        render_file(&d, "ndf-box", 20.0, 1),
    );
    let differ = a
        .pixels()
        .iter()
        .zip(b.pixels())
        .filter(|(p, q)| (0..3).any(|c| (p[c] - q[c]).abs() > 1e-4 * q[c].abs().max(1e-3)))
        .count();
    assert!(differ > a.pixels().len() / 2, "{differ} pixels differ");
}

/// View weighting (NdfMapped::with_view_weighting, BumpMapped::with_view_weighting) is the
/// default of a height map with shadowing, and `view_weighting = false` (or `shadowing =
/// false`) turns it off: the descriptions say so, and the steep-walled egg crate seen at ≈ 24°
/// from afar renders differently (each lobe, or sample, counted by the area the viewer sees);
/// the bump map at one sample per pixel renders the same (the weight cancels).
#[test]
fn view_weighting_reaches_the_scene_file() {
    let d = dir("textured_view");
    let with = |from: &str, to: &str, line: &str| {
        let text = std::fs::read_to_string(d.join(format!("{from}.toml"))).unwrap();
        std::fs::write(
            d.join(format!("{to}.toml")),
            text.replace("[texture]\n", &format!("[texture]\n{line}\n")),
        )
        .unwrap();
    };
    with("ndf-box", "ndf-plain", "view_weighting = false");
    with("ndf-box", "ndf-unshadowed", "shadowing = false");
    with(
        "ndf-unshadowed",
        "ndf-unshadowed-view",
        "view_weighting = true",
    );
    with("bump-mapped", "bump-plain", "view_weighting = false");
    let maps = meso_maps::MapsResolver::new();
    let said = |name: &str| {
        load_textured(&d.join(format!("{name}.toml")), &maps)
            .unwrap()
            .unwrap()
            .describe()
            .unwrap()
    };
    for (name, weighted) in [
        ("ndf-box", true),
        ("ndf-plain", false),
        ("ndf-unshadowed", false),
        ("ndf-unshadowed-view", true),
        ("bump-mapped", true),
        ("bump-plain", false),
    ] {
        let s = said(name);
        assert_eq!(s.ends_with(", view-weighted"), weighted, "{name}: {s}");
    }
    // One sample per pixel: the weight cancels; at 16 the pixels differ.
    let (b1, p1) = (
        render_file(&d, "bump-mapped", 20.0, 1),
        render_file(&d, "bump-plain", 20.0, 1),
    );
    assert_eq!(b1.pixels(), p1.pixels());
    let (b16, p16) = (
        mean(&render_file(&d, "bump-mapped", 20.0, 16)),
        mean(&render_file(&d, "bump-plain", 20.0, 16)),
    );
    assert!((b16 / p16 - 1.0).abs() > 1e-3, "{b16} vs {p16}");
    let (a, b) = (
        mean(&render_file(&d, "ndf-box", 20.0, 1)),
        mean(&render_file(&d, "ndf-plain", 20.0, 1)),
    );
    assert!((a / b - 1.0).abs() > 1e-3, "{a} vs {b}");
}

#[test]
fn ordinary_material_files_are_not_textured() {
    let d = dir("textured_plain");
    let r = load_textured(&d.join("plain.toml"), &meso_maps::MapsResolver::new()).unwrap();
    assert!(r.is_none());
}

#[test]
fn bad_texture_tables_are_errors_naming_the_problem() {
    let d = dir("textured_bad");
    let maps = meso_maps::MapsResolver::new();
    let base = "file = \"bumps.exr\"\ntexel_size = 0.03125\nheight_scale = 0.035\n";
    let transfer = "[transfer]\nkind = \"phong\"\nexponent = 20.0\n";
    for (body, want) in [
        (format!("[texture]\nkind = \"stone\"\n{base}{transfer}"), "unknown \"stone\""),
        (format!("[texture]\n{base}{transfer}"), "missing `kind`"),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\ncolour = 3\n{base}{transfer}"),
            "unknown key `colour`",
        ),
        (
            format!(
                "[texture]\nkind = \"ndf-mapped\"\nfile = \"nothing.png\"\ntexel_size = 0.1\n\
                 height_scale = 0.1\n{transfer}"
            ),
            "nothing.png",
        ),
        (
            format!("[texture]\nkind = \"bump-mapped\"\nfile = \"bumps.exr\"\ntexel_size = -1\nheight_scale = 0.1\n{transfer}"),
            "texel_size",
        ),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\n{base}texels_per_uv = 0\n{transfer}"),
            "texels_per_uv",
        ),
        // Audit item 3: 1e20 made the render hang; bounded by MAX_TEXELS_PER_UV.
        (
            format!("[texture]\nkind = \"ndf-mapped\"\n{base}texels_per_uv = 1e20\n{transfer}"),
            "texels_per_uv must be a number > 0 and at most 1e12, got 1e20",
        ),
        (
            format!("[texture]\nkind = \"bump-mapped\"\n{base}texels_per_uv = 1e13\n{transfer}"),
            "at most 1e12, got 1e13",
        ),
        (format!("[texture]\nkind = \"ndf-mapped\"\n{base}"), "[transfer]"),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\nfilter = \"gauss\"\n{base}{transfer}"),
            "unknown \"gauss\"",
        ),
        (
            format!("[texture]\nkind = \"bump-mapped\"\nfilter = \"box\"\n{base}{transfer}"),
            "filter: applies to",
        ),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\nbox_detail = 4\n{base}{transfer}"),
            "box_detail: must be a number 0–3, got 4",
        ),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\nbox_detail = \"fine\"\n{base}{transfer}"),
            "box_detail: must be a number",
        ),
        (
            format!(
                "[texture]\nkind = \"ndf-mapped\"\nfilter = \"trilinear\"\nbox_detail = 1\n\
                 {base}{transfer}"
            ),
            "box_detail: applies to kind = \"ndf-mapped\" with filter = \"box\"",
        ),
        (
            format!("[texture]\nkind = \"bump-mapped\"\nbox_detail = 1\n{base}{transfer}"),
            "box_detail: applies to",
        ),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\nview_weighting = 1\n{base}{transfer}"),
            "view_weighting: expected true or false, got 1",
        ),

        ("texture = 3\n".to_string(), "expected a table"),
    ] {
        let p = d.join("bad.toml");
        std::fs::write(&p, &body).unwrap();
        let e = match load_textured(&p, &maps) {
            Ok(_) => panic!("accepted:\n{body}"),
            Err(e) => e,
        };
        assert!(e.contains("bad.toml"), "names the file: {e}");
        assert!(e.contains(want), "`{want}` in: {e}");
    }
}

/// The egg crate's normals as an 8-bit tangent-space normal map (OpenGL convention).
fn write_normal_map(dir: &Path) {
    let n = 32u32;
    let tau = std::f64::consts::TAU;
    let (a, k) = (0.035, tau * 4.0);
    let mut img = ::image::RgbImage::new(n, n);
    for (x, y, p) in img.enumerate_pixels_mut() {
        let (u, v) = (f64::from(x) / f64::from(n), f64::from(y) / f64::from(n));
        // h = a·sin(ku)·sin(kv) over one world unit.
        let (gx, gy) = (
            a * k * (k * u).cos() * (k * v).sin(),
            a * k * (k * u).sin() * (k * v).cos(),
        );
        let m = glam::DVec3::new(-gx, -gy, 1.0).normalize();
        let enc = |c: f64| ((c * 0.5 + 0.5) * 255.0).round() as u8;
        *p = ::image::Rgb([enc(m.x), enc(m.y), enc(m.z)]);
    }
    img.save(dir.join("normals.png")).unwrap();
    let surface = "[transfer]\nkind = \"phong\"\nexponent = 20.0\nspecular = [0.6, 0.6, 0.6]\n\
                   [diffuse]\nalbedo = [0.5, 0.4, 0.3]\n";
    for kind in ["ndf-mapped", "bump-mapped"] {
        std::fs::write(
            dir.join(format!("normals-{kind}.toml")),
            format!("[texture]\nkind = \"{kind}\"\nnormal_map = \"normals.png\"\n{surface}"),
        )
        .unwrap();
    }
}

#[test]
fn normal_maps_texel_by_texel_and_filtered() {
    let d = dir("textured_normals");
    write_normal_map(&d);
    filtered_matches_texel_by_texel(&d, "normals-ndf-mapped", "normals-bump-mapped");
    // Mistakes name the problem.
    let maps = meso_maps::MapsResolver::new();
    let transfer = "[transfer]\nkind = \"phong\"\nexponent = 20.0\n";
    for (body, want) in [
        (
            format!("[texture]\nkind = \"ndf-mapped\"\nnormal_map = \"normals.png\"\nshadowing = true\n{transfer}"),
            "no heights",
        ),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\nnormal_map = \"normals.png\"\nfile = \"bumps.exr\"\n{transfer}"),
            "exclude each other",
        ),
        (
            format!("[texture]\nkind = \"ndf-mapped\"\nnormal_map = \"normals.png\"\ntexel_size = 0.1\n{transfer}"),
            "applies to height maps",
        ),
        (
            format!("[texture]\nkind = \"bump-mapped\"\nnormal_map = \"normals.png\"\nconvention = \"up\"\n{transfer}"),
            "unknown \"up\"",
        ),
        (
            format!("[texture]\nkind = \"bump-mapped\"\nnormal_map = \"none.png\"\n{transfer}"),
            "none.png",
        ),
    ] {
        let p = d.join("bad-normals.toml");
        std::fs::write(&p, &body).unwrap();
        let e = match load_textured(&p, &maps) {
            Ok(_) => panic!("accepted:\n{body}"),
            Err(e) => e,
        };
        assert!(e.contains("bad-normals.toml") && e.contains(want), "`{want}` in: {e}");
    }
}

/// Textures show the right way up (issue #15 item 1, docs/conventions.md): a grey PNG height
/// map with bumps in its **top** half only (image rows 0 … n/2 − 1) and flat below, on a plane,
/// a quad (`edge_v` up) and an OBJ square (OpenGL `vt`, v up the image, read as glTF's `1 − v`)
/// seen from straight above with +y up the picture over exactly one tile (`uv` ∈ [0, 1]²), must
/// show its bumps in the top half of the rendered picture — bump-mapped and NDF-mapped alike.
/// Measured by the spread of the radiance along each picture row: the flat half is uniform.
#[test]
fn a_texture_shows_the_right_way_up() {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("right_way_up");
    std::fs::create_dir_all(&d).unwrap();
    let n = 32u32;
    let tau = std::f64::consts::TAU;
    let img = ::image::GrayImage::from_fn(n, n, |c, r| {
        let v = if r < n / 2 {
            let (x, y) = (f64::from(c) / f64::from(n), f64::from(r) / f64::from(n));
            0.5 + 0.5 * (tau * 4.0 * x).sin() * (tau * 4.0 * y).sin()
        } else {
            0.5
        };
        ::image::Luma([(v * 255.0).round() as u8])
    });
    img.save(d.join("top_bumps.png")).unwrap();
    let surface = "[transfer]\nkind = \"phong\"\nexponent = 20.0\nspecular = [0.6, 0.6, 0.6]\n\
                   [diffuse]\nalbedo = [0.5, 0.4, 0.3]\n";
    std::fs::write(
        d.join("square.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
         f 1/1 2/2 3/3 4/4\n",
    )
    .unwrap();
    let objects = [
        "kind = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\
         tangent = [1.0, 0.0, 0.0]",
        "kind = \"quad\"\norigin = [0.0, 0.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\n\
         edge_v = [0.0, 1.0, 0.0]",
        "kind = \"mesh\"\nfile = \"square.obj\"",
    ];
    for (kind, object) in ["bump-mapped", "ndf-mapped"]
        .into_iter()
        .flat_map(|k| objects.iter().map(move |o| (k, o)))
    {
        std::fs::write(
            d.join(format!("{kind}.toml")),
            format!(
                "[texture]\nkind = \"{kind}\"\nfile = \"top_bumps.png\"\ntexel_size = 0.03125\n\
                 height_scale = 0.04\n{surface}"
            ),
        )
        .unwrap();
        let scene = d.join(format!("{kind}.scene.toml"));
        std::fs::write(
            &scene,
            format!(
                "[camera]\nkind = \"orthographic\"\nposition = [0.5, 0.5, 10.0]\n\
                 look_at = [0.5, 0.5, 0.0]\nup = [0.0, 1.0, 0.0]\nwidth = 1.0\n\
                 [image]\nwidth = 64\nheight = 64\nspp = 4\n\
                 [[object]]\n{object}\nmaterial = \"{kind}.toml\"\n\
                 [[light]]\nkind = \"directional\"\ndirection = [-0.5, 0.3, 0.8]\n\
                 irradiance = [2.0, 2.0, 2.0]\n"
            ),
        )
        .unwrap();
        let scene = Scene::from_toml_file(&scene, &resolver).unwrap();
        let pic = render(&scene, &RenderOptions::default(), None);
        let (w, h) = (pic.width(), pic.height());
        // Mean over a half of the picture of each row's standard deviation of luminance, over
        // the mean luminance (rows 2 px away from the middle and the edges, where pixels mix
        // the halves or wrap).
        let spread = |rows: std::ops::Range<u32>| {
            let mut sum = 0.0;
            let mut all = 0.0;
            for y in rows {
                let l: Vec<f64> = (0..w)
                    .map(|x| {
                        let p = pic.get(x, y);
                        f64::from(p[0] + p[1] + p[2])
                    })
                    .collect();
                let m = l.iter().sum::<f64>() / f64::from(w);
                let v = l.iter().map(|a| (a - m) * (a - m)).sum::<f64>() / f64::from(w);
                sum += v.sqrt();
                all += m;
            }
            sum / all.max(1e-30)
        };
        let (top, bottom) = (spread(2..h / 2 - 2), spread(h / 2 + 2..h - 2));
        let what = object.lines().next().unwrap_or_default();
        eprintln!(
            "{kind} on {what}: relative spread along rows, top half {top:.4}, bottom half {bottom:.4}"
        );
        assert!(
            top > 0.05 && top > 10.0 * bottom,
            "{kind} on {what}: the bumps (top of the image file) are not at the top of the picture: \
             spread top {top}, bottom {bottom}"
        );
    }
}
