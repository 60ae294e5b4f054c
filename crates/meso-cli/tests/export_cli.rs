//! End-to-end tests of `meso export`'s inputs and refusals: the base colour factor with a base
//! colour texture, `--lobes` pyramids whose levels are not the mip chain's, map options given with
//! a material file, and the messages for a map file, a height map read as a normal map and an
//! `--out` that is a file.

mod common;
use common::{ok, run, s, tmpdir};

use std::path::Path;
use std::process::Output;

/// A failed command: non-zero exit, exactly one error line, no output folder; the error line.
fn fails(o: &Output, out: &Path, what: &str) -> String {
    assert!(!o.status.success(), "{what}: should fail");
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(err.trim_end().lines().count(), 1, "{what}: stderr {err:?}");
    assert!(err.starts_with("meso: error:"), "{what}: {err}");
    assert!(!out.exists(), "{what}: left {}", out.display());
    err
}

/// A bumpy tangent-space normal map (8-bit RGB, OpenGL) of `w × h` texels.
fn normal_png(path: &Path, w: u32, h: u32) {
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        let (sx, sy) = (
            0.3 * (x as f64 * 1.7).sin(),
            0.3 * (y as f64 * 2.3 + 0.5).cos(),
        );
        let n = [sx, sy, 1.0];
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        image::Rgb(n.map(|c| ((c / l * 0.5 + 0.5) * 255.0).round() as u8))
    });
    img.save(path).unwrap();
}

/// A smooth periodic 8-bit grey height map of `n × n` samples, codes 28–228 (mid-grey, 128,
/// included).
fn height_png(path: &Path, n: u32) {
    let img = image::GrayImage::from_fn(n, n, |x, y| {
        let t = std::f64::consts::TAU / n as f64;
        let v = 128.0 + 60.0 * (t * x as f64).sin() + 40.0 * (2.0 * t * y as f64).cos();
        image::Luma([v.round() as u8])
    });
    img.save(path).unwrap();
}

/// With `--base-color` the glTF factor is 1 (glTF multiplies texture and factor; the 0.8 grey is
/// only the colour of an export without a texture).
#[test]
fn a_base_color_texture_has_factor_one() {
    let d = tmpdir("export-cli", "base-color");
    let (n, c) = (d.join("n.png"), d.join("color.png"));
    normal_png(&n, 8, 8);
    image::RgbImage::from_pixel(8, 8, image::Rgb([200, 100, 50]))
        .save(&c)
        .unwrap();
    let factor = |out: &Path| -> Vec<f64> {
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("scene.gltf")).unwrap()).unwrap();
        let pbr = &doc["materials"][0]["pbrMetallicRoughness"];
        pbr["baseColorFactor"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    let with = d.join("with");
    ok(&run(&[
        "export",
        s(&n),
        "--base-color",
        s(&c),
        "--out",
        s(&with),
    ]));
    assert_eq!(factor(&with), vec![1.0; 4]);
    let without = d.join("without");
    ok(&run(&["export", s(&n), "--out", s(&without)]));
    assert_eq!(factor(&without), vec![0.8, 0.8, 0.8, 1.0]);
}

/// `--lobes` with a pyramid whose levels are not the export's mip levels is refused before the
/// fit, naming the map file and the sizes: a 5 × 3 map (pyramid 5×3, 3×2, 2×1, 1×1; KTX2 chain
/// 5×3, 2×1, 1×1) and a `--clamp` pyramid (63 × 63 cells) of a 64² map. A 64² wrapped pyramid
/// is accepted and writes one lobe level per mip level.
#[test]
fn lobes_must_match_the_mip_chain() {
    let d = tmpdir("export-cli", "lobes");
    let odd = d.join("odd.png");
    normal_png(&odd, 5, 3);
    let odd_map = d.join("odd.map");
    ok(&run(&[
        "extract",
        s(&odd),
        "--normal-map",
        "--out",
        s(&odd_map),
    ]));
    let out = d.join("odd-out");
    let o = run(&["export", s(&odd), "--lobes", s(&odd_map), "--out", s(&out)]);
    let err = fails(&o, &out, "5 × 3 lobes");
    assert!(err.contains("odd.map"), "{err}");
    assert!(
        err.contains("level 1 is 3 × 2 in the pyramid") && err.contains("2 × 1 in the mip chain"),
        "{err}"
    );
    assert!(
        err.contains("4 levels") && err.contains("3 levels"),
        "{err}"
    );
    // Refused up front: no fit table was printed.
    assert!(o.stdout.is_empty());

    let h = d.join("h.png");
    height_png(&h, 64);
    let clamped = d.join("clamped.map");
    ok(&run(&[
        "extract",
        s(&h),
        "--texel-size",
        "1",
        "--height-scale",
        "4",
        "--clamp",
        "--max-lobes",
        "1",
        "--out",
        s(&clamped),
    ]));
    let out = d.join("clamped-out");
    let o = run(&[
        "export",
        s(&h),
        "--texel-size",
        "1",
        "--height-scale",
        "4",
        "--lobes",
        s(&clamped),
        "--out",
        s(&out),
    ]);
    let err = fails(&o, &out, "clamped lobes");
    assert!(
        err.contains("clamped.map") && err.contains("63 × 63") && err.contains("64 × 64"),
        "{err}"
    );
    assert!(err.contains("without --clamp"), "{err}");

    let wrapped = d.join("wrapped.map");
    ok(&run(&[
        "extract",
        s(&h),
        "--texel-size",
        "1",
        "--height-scale",
        "4",
        "--max-lobes",
        "1",
        "--out",
        s(&wrapped),
    ]));
    let out = d.join("wrapped-out");
    ok(&run(&[
        "export",
        s(&h),
        "--texel-size",
        "1",
        "--height-scale",
        "4",
        "--lobes",
        s(&wrapped),
        "--out",
        s(&out),
    ]));
    for l in 0..7 {
        let (w, _) = image::image_dimensions(out.join(format!("normal_mip{l}.png"))).unwrap();
        let (lw, _) = image::image_dimensions(out.join(format!("lobes0_mip{l}.png"))).unwrap();
        assert_eq!((w, lw), (64 >> l, 64 >> l));
    }
    assert!(!out.join("lobes0_mip7.png").exists());
}

/// Every map option given with a material file is refused, named, including values equal to
/// the map defaults (`--alpha 0.1`, `--metallic 0`) and `--convention`.
#[test]
fn a_material_file_refuses_every_map_option() {
    let d = tmpdir("export-cli", "material");
    let m = d.join("ggx.toml");
    std::fs::write(
        &m,
        "form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha = 0.2\n[transfer]\nkind = \"mirror\"\n\
         fresnel = \"schlick\"\nf0 = [0.5, 0.5, 0.5]\n[shadowing]\nkind = \"smith\"\n",
    )
    .unwrap();
    let out = d.join("out");
    for (args, names) in [
        (vec!["--convention", "dx"], vec!["--convention"]),
        (vec!["--convention", "gl"], vec!["--convention"]),
        (
            vec!["--alpha", "0.1", "--metallic", "0"],
            vec!["--alpha", "--metallic"],
        ),
        (vec!["--anisotropic"], vec!["--anisotropic"]),
    ] {
        let mut a = vec!["export", s(&m), "--out", s(&out)];
        a.extend(&args);
        let err = fails(&run(&a), &out, &format!("material with {args:?}"));
        assert!(err.contains("ggx.toml"), "{err}");
        for n in names {
            assert!(err.contains(n), "{args:?}: {err}");
        }
    }
    ok(&run(&["export", s(&m), "--out", s(&out)]));
}

/// The messages: a map file given as the image (export and extract), a grey height map without
/// `--texel-size`/`--height-scale`, and `--out` naming a file.
#[test]
fn messages_say_what_to_do() {
    let d = tmpdir("export-cli", "messages");
    let h = d.join("d64.png");
    height_png(&h, 16);
    let map = d.join("h.map");
    ok(&run(&[
        "extract",
        s(&h),
        "--texel-size",
        "1",
        "--height-scale",
        "4",
        "--max-lobes",
        "1",
        "--out",
        s(&map),
    ]));
    let out = d.join("out");
    let err = fails(
        &run(&["export", s(&map), "--out", s(&out)]),
        &out,
        "map as export input",
    );
    assert!(
        err.contains("h.map is a meso map file (written by `meso extract`), not an image")
            && err.contains("--lobes")
            && !err.contains("PNG"),
        "{err}"
    );
    let out_map = d.join("again.map");
    let err = fails(
        &run(&[
            "extract",
            s(&map),
            "--texel-size",
            "1",
            "--height-scale",
            "1",
            "--out",
            s(&out_map),
        ]),
        &out_map,
        "map as extract input",
    );
    assert!(
        err.contains("h.map") && err.contains("meso map file") && !err.contains("PNG"),
        "{err}"
    );
    // A grey height map read as a normal map.
    let err = fails(
        &run(&["export", s(&h), "--out", s(&out)]),
        &out,
        "height map as normals",
    );
    assert!(
        err.contains("d64.png")
            && err.contains("height map")
            && err.contains("--texel-size")
            && err.contains("--height-scale")
            && !err.contains("cannot decode"),
        "{err}"
    );
    // The same heights as an RGB image: the mid-grey texels are no directions.
    let rgb = d.join("d64rgb.png");
    image::open(&h).unwrap().to_rgb8().save(&rgb).unwrap();
    let err = fails(
        &run(&["export", s(&rgb), "--out", s(&out)]),
        &out,
        "rgb height map as normals",
    );
    assert!(
        err.contains("height map")
            && err.contains("--texel-size")
            && !err.contains("cannot decode"),
        "{err}"
    );
    // --out naming a file.
    let file = d.join("afile");
    std::fs::write(&file, b"keep").unwrap();
    let o = run(&[
        "export",
        s(&h),
        "--texel-size",
        "1",
        "--height-scale",
        "4",
        "--out",
        s(&file),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("afile") && err.contains("must be a folder") && !err.contains("os error"),
        "{err}"
    );
    assert!(o.stdout.is_empty(), "refused before the fit");
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
}

/// The lobe pyramid's memory is part of the up-front budget check: a map file whose header is a
/// 64² pyramid's and whose size is 64 MB (sparse; estimated 4.8× its size to read) is refused
/// under a 64 MB budget before anything is decoded, while the same export without `--lobes`
/// fits.
#[test]
fn the_lobe_pyramid_counts_in_the_budget() {
    let d = tmpdir("export-cli", "lobes-budget");
    let h = d.join("h.png");
    height_png(&h, 64);
    let big = d.join("big.map");
    let mut head = b"MESOMAP\0".to_vec();
    for v in [4u32, 64, 64, 64, 64] {
        head.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(&big, &head).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&big)
        .unwrap()
        .set_len(64 << 20)
        .unwrap();
    let out = d.join("out");
    let args = |lobes: bool| {
        let mut a = vec![
            "--memory-budget",
            "64M",
            "export",
            s(&h),
            "--texel-size",
            "1",
            "--height-scale",
            "4",
            "--out",
            s(&out),
        ];
        if lobes {
            a.extend(["--lobes", s(&big)]);
        }
        a
    };
    let o = run(&args(true));
    let err = fails(&o, &out, "lobes above the budget");
    assert!(
        err.contains("h.png") && err.contains("reading the lobe pyramid") && err.contains("budget"),
        "{err}"
    );
    assert!(o.stdout.is_empty(), "refused before the fit");
    ok(&run(&args(false)));
}

/// A second export into the folder of an earlier, larger one (a 64² normal map, then a 16²
/// one): the earlier export's extra mip levels (`normal_mip5.png`, `normal_mip6.png`, …) are left
/// untouched (nothing of the user's is removed) and named in one warning line, since the new
/// `scene.gltf` does not use them; an export into a fresh folder, or again at the same size,
/// warns of nothing.
#[test]
fn a_second_export_names_the_earlier_ones_files_it_left() {
    let d = tmpdir("export-cli", "stale");
    let (big, small) = (d.join("big.png"), d.join("small.png"));
    normal_png(&big, 64, 64);
    normal_png(&small, 16, 16);
    let out = d.join("out");
    let first = run(&["export", s(&big), "--out", s(&out)]);
    ok(&first);
    assert!(!String::from_utf8_lossy(&first.stderr).contains("warning"));
    assert!(out.join("normal_mip6.png").exists());
    let o = run(&["export", s(&small), "--out", s(&out)]);
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    let line = err
        .lines()
        .find(|l| l.contains("warning"))
        .unwrap_or_else(|| panic!("no warning: {err}"));
    assert!(
        line.starts_with(&format!("{}: warning: ", out.display()))
            && line.contains("earlier export")
            && line.contains("normal_mip5.png")
            && line.contains("normal_mip6.png")
            && line.contains("metallic_roughness_mip6.png")
            && !line.contains("normal_mip4.png"),
        "{line}"
    );
    // Left as they were, and not in the new glTF.
    assert!(out.join("normal_mip6.png").exists());
    let gltf = std::fs::read_to_string(out.join("scene.gltf")).unwrap();
    assert!(!gltf.contains("mip5") && !gltf.contains("mip6"));
    let again = run(&["export", s(&small), "--out", s(&d.join("fresh"))]);
    ok(&again);
    assert!(!String::from_utf8_lossy(&again.stderr).contains("warning"));
}
