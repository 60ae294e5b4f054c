//! Inputs at and beyond meso's limits through the binary: files without a size (devices, FIFOs),
//! absurd but finite values, sizes and budgets (the CLI audit's findings).

mod common;
use common::{heightmap_material, ok, one_pair_csv, run, s, stderr, tmpdir};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn fails_with(o: &Output, what: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "status {:?}: {e}", o.status);
    assert!(!e.contains("panicked"), "{e}");
    assert!(e.starts_with("meso: error: "), "{e}");
    for w in what {
        assert!(e.contains(w), "expected {w:?} in: {e}");
    }
}

/// A 16×16 grey 16-bit PNG of a gentle slope.
fn slope_png(path: &Path) {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(16, 16, |x, y| {
        image::Luma([(x * 1000 + y * 300) as u16])
    });
    img.save(path).unwrap();
}

/// `/dev/zero` as a map file, a height map (extract, export) or a material's height map is read
/// with a limit from the memory budget, and refused naming the file.
#[cfg(unix)]
#[test]
fn endless_device_inputs_are_refused_within_the_budget() {
    let d = tmpdir("limits", "devzero");
    let m = d.join("z.toml");
    std::fs::write(
        &m,
        heightmap_material(
            "/dev/zero",
            1.0,
            1.0,
            "[transfer]\nkind = \"phong\"\nexponent = 50.0\nspecular = [1.0, 1.0, 1.0]\n",
        ),
    )
    .unwrap();
    let out = d.join("o.map");
    let (exp, plot) = (d.join("exp"), d.join("p.png"));
    let runs: [Vec<&str>; 4] = [
        vec!["map", "info", "/dev/zero"],
        vec![
            "extract",
            "/dev/zero",
            "--out",
            s(&out),
            "--texel-size",
            "1",
            "--height-scale",
            "1",
        ],
        vec!["export", "/dev/zero", "--out", s(&exp)],
        vec!["ndf", "plot", s(&m), "--out", s(&plot)],
    ];
    for args in runs {
        let mut all = vec!["--memory-budget", "64M"];
        all.extend(args.iter());
        let o = run(&all);
        fails_with(&o, &["/dev/zero", "memory budget"]);
        assert!(!out.exists() && !exp.exists() && !plot.exists());
    }
}

/// A PNG given through a FIFO is read once and extracted (it used to be read twice: "Invalid PNG
/// signature").
#[cfg(unix)]
#[test]
fn a_png_through_a_fifo_is_extracted() {
    let d = tmpdir("limits", "fifo");
    let png = d.join("h.png");
    slope_png(&png);
    let bytes = std::fs::read(&png).unwrap();
    let fifo = d.join("ff.png");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success());
    let f2 = fifo.clone();
    let writer = std::thread::spawn(move || std::fs::write(&f2, bytes));
    let out = d.join("o.map");
    let o = run(&[
        "extract",
        s(&fifo),
        "--out",
        s(&out),
        "--texel-size",
        "1",
        "--height-scale",
        "1",
    ]);
    ok(&o);
    writer.join().unwrap().unwrap();
    let o = run(&["map", "info", s(&out)]);
    ok(&o);
}

const MATERIAL: &str = "[ndf]\nkind = \"phong-peaks\"\nlobes = [{ axis = [0.0, 0.0], weight = 1.0, exponent = 40.0 }]\n\
[transfer]\nkind = \"phong\"\nexponent = 50.0\nspecular = [1.0, 1.0, 1.0]\n";

/// A scene of one plane under `light` (a `[[light]]` table's body).
fn scene(d: &Path, light: &str) -> PathBuf {
    std::fs::write(d.join("m.toml"), MATERIAL).unwrap();
    let p = d.join("s.toml");
    plane_scene(&p, "m.toml", light, 8);
    p
}

/// Write at `path` a scene of one plane of `material` (a file name beside it), seen from above by
/// an orthographic camera in `pixels × pixels` at 1 spp, under `light` (a `[[light]]` table's
/// body).
fn plane_scene(path: &Path, material: &str, light: &str, pixels: u32) {
    std::fs::write(
        path,
        format!(
            "[camera]\nkind = \"orthographic\"\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\
             up = [0.0, 1.0, 0.0]\nwidth = 2.0\n[image]\nwidth = {pixels}\nheight = {pixels}\nspp = 1\n\
             [[object]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\
             material = \"{material}\"\n[[light]]\n{light}\n"
        ),
    )
    .unwrap();
}

/// A light of 1e300 rendered infinite pixels with exit 0: lights are bounded, and the message
/// writes the vector as numbers (not Rust's `DVec3(…)`).
#[test]
fn absurd_light_values_are_refused() {
    let d = tmpdir("limits", "light");
    let out = d.join("r.png");
    let p = scene(
        &d,
        "kind = \"directional\"\ndirection = [0.0, 0.0, 1.0]\nirradiance = [1.0, 1.0, 1.0]",
    );
    ok(&run(&["render", s(&p), "--out", s(&out)]));
    std::fs::remove_file(&out).unwrap();
    for light in [
        "kind = \"directional\"\ndirection = [0.0, 0.0, 1.0]\nirradiance = [1e300, 1e300, 1e300]",
        "kind = \"point\"\nposition = [0.0, 0.0, 1.0]\nintensity = [1.0, 2e12, 1.0]",
    ] {
        let p = scene(&d, light);
        let o = run(&["render", s(&p), "--out", s(&out)]);
        fails_with(&o, &["s.toml", "at most 1e12 in every channel"]);
        assert!(!stderr(&o).contains("DVec3"), "{}", stderr(&o));
        assert!(!out.exists());
    }
}

/// BRDF values near `f64`'s range made `meso fit` write a material with infinite errors:
/// refused, naming the file and the value.
#[test]
fn fit_refuses_brdf_values_beyond_representation() {
    let d = tmpdir("limits", "fit");
    let csv = d.join("huge.csv");
    std::fs::write(
        &csv,
        "theta_i,phi_i,theta_o,phi_o,r,g,b\n30,0,30,180,1e300,0.1,0.1\n10,0,20,180,0.5,0.5,0.5\n",
    )
    .unwrap();
    let out = d.join("f.toml");
    let o = run(&["fit", s(&csv), "--out", s(&out), "--lobes", "1"]);
    fails_with(&o, &["huge.csv", "BRDF value 1e300 is above 1e12"]);
    assert!(!out.exists());
}

/// `meso ndf plot --size 4096` took 1.3 GB whatever the budget, and `meso figures` ran under a
/// 1 KiB budget: both are checked against the budget first.
#[test]
fn plots_and_figures_are_budgeted() {
    let d = tmpdir("limits", "plotbudget");
    let m = d.join("gx.toml");
    std::fs::write(&m, MATERIAL).unwrap();
    let out = d.join("big.png");
    let o = run(&[
        "--memory-budget",
        "1M",
        "ndf",
        "plot",
        s(&m),
        "--out",
        s(&out),
        "--size",
        "4096",
    ]);
    fails_with(
        &o,
        &[
            "gx.toml",
            "plotting the NDF at --size 4096",
            "memory budget",
        ],
    );
    assert!(!out.exists());
    let figs = d.join("figs");
    let o = run(&["--memory-budget", "1K", "figures", "--out", s(&figs)]);
    fails_with(&o, &["meso figures", "memory budget"]);
    assert!(!figs.exists());
}

/// `--size 64` passed the parser and failed drawing ("area 85×64 too small for a polar plot",
/// no file named): the accepted range is what draws.
#[test]
fn ndf_plot_sizes_accepted_are_sizes_that_draw() {
    let d = tmpdir("limits", "plotsize");
    let m = d.join("m.toml");
    std::fs::write(&m, MATERIAL).unwrap();
    let out = d.join("p.png");
    for size in ["64", "127"] {
        let o = run(&["ndf", "plot", s(&m), "--out", s(&out), "--size", size]);
        let e = stderr(&o);
        assert!(!o.status.success() && !e.contains("panicked"), "{e}");
        assert!(e.contains("--size") && e.contains("128..=4096"), "{e}");
        assert!(!out.exists());
    }
    ok(&run(&[
        "ndf",
        "plot",
        s(&m),
        "--out",
        s(&out),
        "--size",
        "128",
    ]));
    assert!(out.exists());
}

/// `--texel-size -1` was clap's "unexpected argument '-1'" (only `--texel-size=-1` reached the
/// range check): negative numbers are option values.
#[test]
fn negative_option_values_reach_the_range_checks() {
    let d = tmpdir("limits", "negative");
    let png = d.join("h.png");
    slope_png(&png);
    let out = d.join("o.map");
    let o = run(&[
        "extract",
        s(&png),
        "--out",
        s(&out),
        "--texel-size",
        "-1",
        "--height-scale",
        "1",
    ]);
    fails_with(&o, &["texel_size"]);
    assert!(
        !stderr(&o).contains("unexpected argument"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}

/// `meso export` of a material whose NDF comes from a map or a height map says what to run
/// instead, and what it says runs.
#[test]
fn export_of_a_mapped_material_gives_advice_that_works() {
    let d = tmpdir("limits", "exportadvice");
    let png = d.join("h.png");
    slope_png(&png);
    let map = d.join("h.map");
    ok(&run(&[
        "extract",
        s(&png),
        "--out",
        s(&map),
        "--texel-size",
        "1",
        "--height-scale",
        "0.5",
    ]));
    let transfer = "[transfer]\nkind = \"phong\"\nexponent = 10.0\n";
    let mapm = d.join("mapm.toml");
    std::fs::write(
        &mapm,
        format!("[ndf]\nkind = \"map\"\nfile = \"h.map\"\n{transfer}"),
    )
    .unwrap();
    let o = run(&["export", s(&mapm), "--out", s(&d.join("e1"))]);
    let want = format!(
        "meso export IMAGE --texel-size S --height-scale H --lobes {} --out DIR",
        map.display()
    );
    fails_with(&o, &["mapm.toml", &want]);
    ok(&run(&[
        "export",
        s(&png),
        "--texel-size",
        "1",
        "--height-scale",
        "0.5",
        "--lobes",
        s(&map),
        "--out",
        s(&d.join("e2")),
    ]));
    let hm = d.join("hm.toml");
    std::fs::write(&hm, heightmap_material("h.png", 1.0, 0.5, transfer)).unwrap();
    let o = run(&["export", s(&hm), "--out", s(&d.join("e3"))]);
    let want = format!(
        "meso export {} --texel-size 1 --height-scale 0.5 --out DIR",
        png.display()
    );
    fails_with(&o, &["hm.toml", &want]);
    ok(&run(&[
        "export",
        s(&png),
        "--texel-size",
        "1",
        "--height-scale",
        "0.5",
        "--out",
        s(&d.join("e4")),
    ]));
}

/// An environment map or OBJ mesh that is a directory was "file not found": it says what it is.
#[test]
fn a_directory_given_as_an_environment_map_or_mesh_is_named_so() {
    let d = tmpdir("limits", "envdir");
    std::fs::create_dir(d.join("sky.exr")).unwrap();
    std::fs::create_dir(d.join("mesh.obj")).unwrap();
    let out = d.join("r.png");
    let light = "kind = \"directional\"\ndirection = [0.0, 0.0, 1.0]\nirradiance = [1.0, 1.0, 1.0]";
    let p = scene(&d, &format!("{light}\n[environment]\nfile = \"sky.exr\""));
    let o = run(&["render", s(&p), "--out", s(&out)]);
    fails_with(&o, &["sky.exr", "is a directory, not a file"]);
    let p = scene(
        &d,
        &format!(
            "{light}\n[[object]]\nkind = \"mesh\"\nfile = \"mesh.obj\"\nmaterial = \"m.toml\""
        ),
    );
    let o = run(&["render", s(&p), "--out", s(&out)]);
    fails_with(&o, &["mesh.obj", "is a directory, not a file"]);
    assert!(!out.exists());
}

/// `meso brdf` echoes the pairs' angles; an absurd `phi` was echoed with 300 digits: exponent
/// notation, the same value.
#[test]
fn brdf_echoes_absurd_angles_in_exponent_notation() {
    let d = tmpdir("limits", "phiecho");
    let m = d.join("m.toml");
    std::fs::write(&m, MATERIAL).unwrap();
    let pairs = d.join("pairs.csv");
    std::fs::write(
        &pairs,
        "theta_i,phi_i,theta_o,phi_o\n30,0,30,1e300\n30,0,30,180\n",
    )
    .unwrap();
    let out = d.join("b.csv");
    ok(&run(&[
        "brdf",
        s(&m),
        "--pairs",
        s(&pairs),
        "--out",
        s(&out),
    ]));
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[1].starts_with("30,0,30,1e300,"), "{text}");
    assert!(lines[2].starts_with("30,0,30,180,"), "{text}");
    assert!(text.len() < 300, "{text}");
}

/// A material whose height map is a FIFO written once: the cache must not hash it (that read
/// would consume the stream and leave the load waiting for a writer that is gone); the BRDF is
/// computed from the one read. Fails by timing out (60 s) if the stream is read twice.
#[cfg(unix)]
#[test]
fn a_material_height_map_through_a_fifo_is_read_once() {
    let d = tmpdir("limits", "fifo-material");
    let png = d.join("h.png");
    slope_png(&png);
    let bytes = std::fs::read(&png).unwrap();
    let fifo = d.join("ff.png");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    std::fs::write(
        d.join("m.toml"),
        heightmap_material(
            "ff.png",
            1.0,
            1.0,
            "[transfer]\nkind = \"microfacet\"\nalpha = 0.2\n",
        ),
    )
    .unwrap();
    let pairs = one_pair_csv(d.join("p.csv"));
    let f2 = fifo.clone();
    let writer = std::thread::spawn(move || std::fs::write(&f2, bytes));
    let mut child = common::cmd()
        .args(["brdf", s(&d.join("m.toml")), "--pairs", s(&pairs)])
        .env("MESO_CACHE_DIR", d.join("cache"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(60) {
            child.kill().unwrap();
            // Unblock the writer, if it still waits for a reader (a non-blocking open for
            // reading never waits for a writer itself).
            use std::os::unix::fs::OpenOptionsExt;
            drop(
                std::fs::OpenOptions::new()
                    .read(true)
                    .custom_flags(libc::O_NONBLOCK)
                    .open(&fifo),
            );
            panic!("meso brdf still waits on the FIFO after 60 s: it was read twice");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let o = child.wait_with_output().unwrap();
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).lines().count() == 2);
    writer.join().unwrap().unwrap();
}

/// Write a `represent = "facets"` material over `h.png` with `border` and the facets `transfer`
/// (TOML of a `[transfer]` table) asking for `interreflection = true`, and a one-plane scene
/// that uses it; run `meso brdf` on it and `meso render` on the scene; return their standard
/// errors.
fn interreflection_warnings(
    d: &Path,
    pairs: &Path,
    border: &str,
    transfer: &str,
) -> (String, String) {
    let m = d.join(format!("{border}.toml"));
    std::fs::write(
        &m,
        heightmap_material(
            "h.png",
            1.0,
            1.0,
            &format!(
                "represent = \"facets\"\nborder = \"{border}\"\n{transfer}\
                 [shadowing]\nkind = \"visibility\"\ninterreflection = true\n"
            ),
        ),
    )
    .unwrap();
    let o = common::cmd()
        .args(["brdf", s(&m), "--pairs", s(pairs)])
        .env("MESO_CACHE_DIR", d.join("cache"))
        .output()
        .unwrap();
    ok(&o);
    let brdf = stderr(&o);
    let sc = d.join(format!("{border}.scene.toml"));
    plane_scene(
        &sc,
        &format!("{border}.toml"),
        "kind = \"directional\"\ndirection = [0.0, 0.0, 1.0]\nirradiance = [1.0, 1.0, 1.0]",
        4,
    );
    let o = common::cmd()
        .args([
            "render",
            s(&sc),
            "--out",
            s(&d.join(format!("{border}.png"))),
        ])
        .env("MESO_CACHE_DIR", d.join("cache"))
        .output()
        .unwrap();
    ok(&o);
    (brdf, stderr(&o))
}

/// `interreflection = true` on a map whose light between facets cannot be traced (a clamped
/// map) says that the coarser sky-view estimate is used, naming the material; on a wrapped map
/// it is traced and nothing is said.
#[test]
fn estimated_interreflection_is_reported() {
    let d = tmpdir("limits", "interreflection");
    slope_png(&d.join("h.png"));
    let pairs = one_pair_csv(d.join("p.csv"));
    for border in ["clamp", "wrap"] {
        let (e, r) =
            interreflection_warnings(&d, &pairs, border, "[transfer]\nkind = \"lambert\"\n");
        let said = e.contains("interreflection = true") && e.contains("sky views");
        assert_eq!(said, border == "clamp", "{border}: {e}");
        if said {
            assert!(e.contains(&format!("{border}.toml: warning")), "{e}");
        }
        // meso render says it once for the scene's material.
        assert_eq!(
            r.matches("sky views").count(),
            usize::from(border == "clamp"),
            "render, {border}: {r}"
        );
    }
}

/// `interreflection = true` with glossy facets: `meso brdf` traces the light between them on a
/// wrapped map and says nothing; on a clamped map it says the light is left out; `meso render`
/// (whose interactive evaluation leaves it out) says so once.
#[test]
fn glossy_interreflection_is_traced_or_reported() {
    let d = tmpdir("limits", "glossy-interreflection");
    slope_png(&d.join("h.png"));
    let pairs = one_pair_csv(d.join("p.csv"));
    for border in ["clamp", "wrap"] {
        let (e, r) = interreflection_warnings(
            &d,
            &pairs,
            border,
            "[transfer]\nkind = \"microfacet\"\nalpha = 0.1\nfresnel = \"none\"\n",
        );
        let said = e.contains("interreflection = true") && e.contains("only the single bounce");
        assert_eq!(said, border == "clamp", "{border}: {e}");
        assert!(!e.contains("sky views"), "{border}: {e}");
        let wanted = if border == "clamp" {
            "only the single bounce"
        } else {
            "renderer leaves out the light between glossy facets"
        };
        assert_eq!(r.matches(wanted).count(), 1, "render, {border}: {r}");
    }
}
