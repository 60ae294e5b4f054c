//! Issue #12 (hardening) through the binary: outputs aimed at devices, symlinks and inputs
//! (item 1), no partial outputs (item 6), declared limits (item 7), broken pipes and full
//! streams (item 8), messages (item 12).

mod common;
use common::{cmd, heightmap_material, ok, one_pair_csv, run, s, stderr, tmpdir};

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// A failed run: status 1 (never a panic's 101), one error line on stderr containing `what`.
fn fails_with(o: &Output, what: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "status {:?}: {e}", o.status);
    assert!(!e.contains("panicked"), "{e}");
    assert_eq!(e.lines().count(), 1, "one line: {e}");
    assert!(e.starts_with("meso: error: "), "{e}");
    assert!(e.contains(what), "expected {what:?} in: {e}");
}

const PHONG: &str = "[ndf]\nkind = \"phong-peaks\"\nlobes = [{ axis = [0.0, 0.0], weight = 1.0, exponent = 40.0 }]\n\
[transfer]\nkind = \"phong\"\nexponent = 50.0\nspecular = [1.0, 1.0, 1.0]\n";

const PAIRS: &str = "theta_i,phi_i,theta_o,phi_o\n0,0,0,0\n30,0,30,180\n45,0,45,180\n";

/// A material and a pairs file in a fresh directory.
fn brdf_inputs(name: &str) -> (PathBuf, PathBuf, PathBuf) {
    let d = tmpdir("harden", name);
    let m = d.join("m.toml");
    let p = d.join("pairs.csv");
    std::fs::write(&m, PHONG).unwrap();
    std::fs::write(&p, PAIRS).unwrap();
    (d, m, p)
}

/// Names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[cfg(unix)]
#[test]
fn item1_output_to_device_node_is_written_in_place() {
    use std::os::unix::fs::FileTypeExt;
    let (d, m, p) = brdf_inputs("item1-dev");
    let dev = d.join("null");
    let made = Command::new("mknod")
        .arg(&dev)
        .args(["c", "1", "3"])
        .status()
        .unwrap();
    if !made.success() {
        eprintln!("skipped: mknod needs privileges");
        return;
    }
    ok(&run(&["brdf", s(&m), "--pairs", s(&p), "--out", s(&dev)]));
    let ft = std::fs::symlink_metadata(&dev).unwrap().file_type();
    assert!(ft.is_char_device(), "the device stays a device: {ft:?}");
    assert_eq!(names(&d), ["m.toml", "null", "pairs.csv"], "no temp left");
    std::fs::remove_dir_all(&d).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_out_dev_stdout_writes_to_standard_output() {
    let (d, m, p) = brdf_inputs("item1-stdout");
    let o = run(&["brdf", s(&m), "--pairs", s(&p), "--out", "/dev/stdout"]);
    ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.starts_with("theta_i,phi_i,theta_o,phi_o,r,g,b\n"),
        "{text}"
    );
    assert_eq!(text.lines().count(), 4, "{text}");
    // Standard output redirected to a file: the file receives the table, the same inode.
    let file = d.join("redirected.csv");
    let f = std::fs::File::create(&file).unwrap();
    let ino = |p: &Path| std::os::unix::fs::MetadataExt::ino(&std::fs::metadata(p).unwrap());
    let before = ino(&file);
    let st = cmd()
        .args(["brdf", s(&m), "--pairs", s(&p), "--out", "/dev/stdout"])
        .stdout(f)
        .status()
        .unwrap();
    assert!(st.success());
    assert_eq!(ino(&file), before, "written in place, not replaced");
    assert_eq!(std::fs::read_to_string(&file).unwrap().lines().count(), 4);
    std::fs::remove_dir_all(&d).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_existing_output_keeps_its_permissions_and_symlinks_stay() {
    use std::os::unix::fs::PermissionsExt;
    let (d, m, p) = brdf_inputs("item1-perm");
    let out = d.join("out.csv");
    std::fs::write(&out, "old").unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o600)).unwrap();
    let link = d.join("link.csv");
    std::os::unix::fs::symlink("out.csv", &link).unwrap();
    ok(&run(&["brdf", s(&m), "--pairs", s(&p), "--out", s(&link)]));
    let meta = std::fs::metadata(&out).unwrap();
    assert_eq!(meta.permissions().mode() & 0o7777, 0o600);
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read_to_string(&out)
        .unwrap()
        .starts_with("theta_i"));
    std::fs::remove_dir_all(&d).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_output_that_is_an_input_is_refused() {
    let (d, m, p) = brdf_inputs("item1-input");
    let alias = d.join("alias.csv");
    std::os::unix::fs::symlink(&p, &alias).unwrap();
    for out in [&p, &alias] {
        let o = run(&["brdf", s(&m), "--pairs", s(&p), "--out", s(out)]);
        fails_with(&o, "is the same file as the input");
        assert_eq!(std::fs::read_to_string(&p).unwrap(), PAIRS, "input intact");
    }
    let o = run(&["ndf", "plot", s(&m), "--out", s(&m)]);
    fails_with(&o, "is the same file as the input");
    assert_eq!(std::fs::read_to_string(&m).unwrap(), PHONG);
    // A render whose output is one of the scene's materials.
    std::fs::write(d.join("scene.toml"), scene("m.toml")).unwrap();
    let o = run(&["render", s(&d.join("scene.toml")), "--out", s(&m)]);
    // (`m.toml` is not an image extension: aim at the material through a .png symlink.)
    fails_with(&o, "unknown image format");
    let png_alias = d.join("m.png");
    std::os::unix::fs::symlink(&m, &png_alias).unwrap();
    let o = run(&["render", s(&d.join("scene.toml")), "--out", s(&png_alias)]);
    fails_with(&o, "is the same file as the input");
    assert_eq!(std::fs::read_to_string(&m).unwrap(), PHONG);
    // --out and --also naming one file.
    let o = run(&[
        "render",
        s(&d.join("scene.toml")),
        "--out",
        s(&d.join("a.png")),
        "--also",
        s(&d.join(".").join("a.png")),
    ]);
    fails_with(&o, "are the same output file");
    std::fs::remove_dir_all(&d).unwrap();
}

#[cfg(unix)]
#[test]
fn item2_temp_file_of_a_killed_run_is_cleaned() {
    let (d, m, p) = brdf_inputs("item2-killed");
    let out = d.join("out.csv");
    // A meso run killed with SIGKILL while it waits on its input (a FIFO nobody writes): its
    // process id is dead, and the temporary file such a run leaves when killed while writing
    // is `.out.csv.meso-PID.XXXXXX.tmp`.
    let fifo = d.join("slow.toml");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let mut child = cmd()
        .args(["brdf", s(&fifo), "--pairs", s(&p), "--out", s(&out)])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    child.kill().unwrap();
    let status = child.wait().unwrap();
    eprintln!("killed run: {status:?}");
    let pid = child.id();
    let stale = d.join(format!(".out.csv.meso-{pid}.k1LLed.tmp"));
    std::fs::write(&stale, "theta_i,half a table").unwrap();
    // Temporary files that are not this target's, or not of a dead process, stay.
    let live = d.join(format!(".out.csv.meso-{}.Alive1.tmp", std::process::id()));
    std::fs::write(&live, "a live writer's").unwrap();
    let other = d.join(format!(".pairs.csv.meso-{pid}.k1LLed.tmp"));
    std::fs::write(&other, "another target's").unwrap();
    ok(&run(&["brdf", s(&m), "--pairs", s(&p), "--out", s(&out)]));
    assert!(!stale.exists(), "the killed run's temp file is removed");
    assert!(live.exists() && other.exists());
    let table = std::fs::read_to_string(&out).unwrap();
    assert!(table.starts_with("theta_i"), "{table}");
    assert_eq!(table.lines().count(), 4, "{table}");
    let mut expected = vec![
        live.file_name().unwrap().to_str().unwrap().to_string(),
        other.file_name().unwrap().to_str().unwrap().to_string(),
    ];
    expected.extend(["m.toml", "out.csv", "pairs.csv", "slow.toml"].map(String::from));
    expected.sort();
    assert_eq!(names(&d), expected);
    std::fs::remove_dir_all(&d).unwrap();
}

/// A tiny scene (8×8 pixels, 1 spp) with one sphere of `material`.
fn scene(material: &str) -> String {
    format!(
        "[camera]\nkind = \"orthographic\"\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\
         up = [0.0, 1.0, 0.0]\nwidth = 2.5\n[image]\nwidth = 8\nheight = 8\nspp = 1\n\
         [[object]]\nkind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"{material}\"\n\
         [[light]]\nkind = \"directional\"\ndirection = [0.3, 0.4, 0.866]\nirradiance = [1.0, 1.0, 1.0]\n"
    )
}

#[test]
fn item6_render_also_badpath_leaves_no_image() {
    let (d, _m, _p) = brdf_inputs("item6-render");
    std::fs::write(d.join("scene.toml"), scene("m.toml")).unwrap();
    let first = d.join("first.png");
    // A missing directory: refused before rendering.
    let o = run(&[
        "render",
        s(&d.join("scene.toml")),
        "--out",
        s(&first),
        "--also",
        s(&d.join("missing/second.exr")),
    ]);
    fails_with(&o, "does not exist");
    assert!(!first.exists(), "the first image was written");
    // A target that fails only when written (a directory named like an image).
    std::fs::create_dir(d.join("second.exr")).unwrap();
    let o = run(&[
        "render",
        s(&d.join("scene.toml")),
        "--out",
        s(&first),
        "--also",
        s(&d.join("second.exr")),
    ]);
    fails_with(&o, "second.exr");
    assert!(!first.exists(), "the first image was written");
    assert_eq!(
        names(&d),
        ["m.toml", "pairs.csv", "scene.toml", "second.exr"],
        "no temp left"
    );
    ok(&run(&[
        "render",
        s(&d.join("scene.toml")),
        "--out",
        s(&first),
        "--also",
        s(&d.join("second.png")),
    ]));
    assert!(first.exists() && d.join("second.png").exists());
    std::fs::remove_dir_all(&d).unwrap();
}

/// A small sample CSV (a Phong-like peak plus a diffuse term), fitted in well under a second.
fn fit_csv(dir: &Path) -> PathBuf {
    let mut t = String::from("theta_i,phi_i,theta_o,phi_o,r,g,b\n");
    for ti in (0..80).step_by(8) {
        for to in (0..80).step_by(8) {
            for po in (0..360).step_by(45) {
                let (a, b) = ((ti as f64).to_radians(), (to as f64).to_radians());
                let pr = (po as f64).to_radians();
                // Angle between the mirror direction of (θi, 0) and (θo, φo).
                let mirror = [-a.sin(), 0.0, a.cos()];
                let wo = [b.sin() * pr.cos(), b.sin() * pr.sin(), b.cos()];
                let c = (mirror[0] * wo[0] + mirror[1] * wo[1] + mirror[2] * wo[2]).max(0.0);
                let f = 0.1 + 2.0 * c.powi(60);
                t.push_str(&format!("{ti},0,{to},{po},{f},{},{}\n", 0.8 * f, 0.6 * f));
            }
        }
    }
    let p = dir.join("data.csv");
    std::fs::write(&p, t).unwrap();
    p
}

#[test]
fn item6_fit_per_channel_failure_leaves_no_file() {
    let d = tmpdir("harden", "item6-fit");
    let csv = fit_csv(&d);
    // The third per-channel file cannot be written (a directory of that name).
    std::fs::create_dir(d.join("m.blue.toml")).unwrap();
    let o = run(&[
        "fit",
        s(&csv),
        "--lobes",
        "1",
        "--per-channel-lobes",
        "--out",
        s(&d.join("m.toml")),
    ]);
    fails_with(&o, "m.blue.toml");
    assert_eq!(names(&d), ["data.csv", "m.blue.toml"], "nothing left");
    std::fs::remove_dir(d.join("m.blue.toml")).unwrap();
    // The second plot cannot be written: no material either.
    let plots = d.join("plots");
    std::fs::create_dir_all(plots.join("spheres.png")).unwrap();
    let o = run(&[
        "fit",
        s(&csv),
        "--lobes",
        "1",
        "--plot",
        s(&plots),
        "--out",
        s(&d.join("m.toml")),
    ]);
    fails_with(&o, "spheres.png");
    assert_eq!(names(&d), ["data.csv", "plots"], "no material");
    assert_eq!(names(&plots), ["spheres.png"], "no slices");
    // A --plot that is a file: refused before fitting.
    let o = run(&[
        "fit",
        s(&csv),
        "--lobes",
        "1",
        "--plot",
        s(&csv),
        "--out",
        s(&d.join("m.toml")),
    ]);
    fails_with(&o, "needs a directory");
    assert!(!d.join("m.toml").exists());
    // The good case writes all three outputs.
    let fresh = d.join("fresh");
    ok(&run(&[
        "fit",
        s(&csv),
        "--lobes",
        "1",
        "--plot",
        s(&fresh),
        "--out",
        s(&d.join("m.toml")),
    ]));
    assert!(d.join("m.toml").exists());
    assert_eq!(names(&fresh), ["slices.png", "spheres.png"]);
    std::fs::remove_dir_all(&d).unwrap();
}

/// Run `meso args` with standard output on a pipe whose reading end is already closed: every
/// write fails with EPIPE, deterministically.
#[cfg(unix)]
fn run_into_closed_pipe(args: &[&str]) -> Output {
    use std::os::fd::{FromRawFd, OwnedFd};
    let mut fds = [0i32; 2];
    // SAFETY: pipe() fills two new descriptors we own.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    // SAFETY: both descriptors were just created and are owned here only.
    let (read, write) = unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) };
    drop(read);
    cmd()
        .args(args)
        .stdout(Stdio::from(write))
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

/// A material file and a map file written by `meso extract` from a small height map.
fn map_file(dir: &Path) -> PathBuf {
    let n = 32u32;
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(n, n, |x, y| {
        let v = ((x as f64 * 0.7).sin() + (y as f64 * 0.4).cos()) * 3000.0 + 32768.0;
        image::Luma([v as u16])
    });
    let png = dir.join("h.png");
    img.save(&png).unwrap();
    let map = dir.join("h.map");
    ok(&run(&[
        "extract",
        s(&png),
        "--texel-size",
        "0.01",
        "--height-scale",
        "0.05",
        "--max-lobes",
        "2",
        "--out",
        s(&map),
    ]));
    map
}

#[cfg(unix)]
#[test]
fn item8_map_info_piped_into_head_1_does_not_panic() {
    let d = tmpdir("harden", "item8-head");
    let map = map_file(&d);
    let bin = env!("CARGO_BIN_EXE_meso");
    let o = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "set -o pipefail; '{bin}' map info '{}' | head -1",
            map.display()
        ))
        .output()
        .unwrap();
    let e = stderr(&o);
    assert!(
        matches!(o.status.code(), Some(0 | 141)),
        "status {:?}: {e}",
        o.status
    );
    assert!(e.is_empty(), "quiet: {e}");
    assert_eq!(String::from_utf8_lossy(&o.stdout).lines().count(), 1);
    // Deterministically broken: the pipe's reader is gone before the first write.
    for args in [
        vec!["map", "info", s(&map)],
        vec!["ndf", "stats", s(&d.join("m.toml"))],
        vec![
            "brdf",
            s(&d.join("m.toml")),
            "--pairs",
            s(&d.join("pairs.csv")),
        ],
        vec![
            "brdf",
            s(&d.join("m.toml")),
            "--pairs",
            s(&d.join("pairs.csv")),
            "--out",
            "/dev/stdout",
        ],
    ] {
        std::fs::write(d.join("m.toml"), PHONG).unwrap();
        std::fs::write(d.join("pairs.csv"), PAIRS).unwrap();
        let o = run_into_closed_pipe(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(141), "{args:?}: {:?} {e}", o.status);
        assert!(e.is_empty(), "{args:?}: quiet, got {e}");
    }
    // `meso export` prints its table of levels on standard output (its progress and the file
    // count on standard error): the same exit, no panic, and its files are written.
    let out = d.join("exported");
    let png = d.join("h.png");
    let args = [
        "export",
        s(&png),
        "--texel-size",
        "0.01",
        "--height-scale",
        "0.05",
        "--out",
        s(&out),
    ];
    let o = run_into_closed_pipe(&args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(141), "export: {:?} {e}", o.status);
    assert!(!e.contains("panicked"), "export: {e}");
    assert!(out.join("scene.gltf").exists(), "export: {e}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// Run `meso args` with standard output (or standard error) on /dev/full.
#[cfg(unix)]
fn run_full(args: &[&str], stderr_full: bool) -> Output {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let mut c = cmd();
    c.args(args);
    if stderr_full {
        c.stderr(full).stdout(Stdio::piped());
    } else {
        c.stdout(full).stderr(Stdio::piped());
    }
    c.output().unwrap()
}

#[cfg(unix)]
#[test]
fn item8_stdout_on_dev_full_is_an_error_not_a_panic() {
    let d = tmpdir("harden", "item8-full");
    let map = map_file(&d);
    std::fs::write(d.join("m.toml"), PHONG).unwrap();
    std::fs::write(d.join("pairs.csv"), PAIRS).unwrap();
    let csv = fit_csv(&d);
    let out = d.join("fit.toml");
    for args in [
        vec!["map", "info", s(&map)],
        vec!["ndf", "stats", s(&d.join("m.toml"))],
        vec!["ndf", "stats", "--json", s(&d.join("m.toml"))],
        vec![
            "brdf",
            s(&d.join("m.toml")),
            "--pairs",
            s(&d.join("pairs.csv")),
        ],
        vec!["fit", s(&csv), "--lobes", "1", "--out", s(&out)],
    ] {
        let o = run_full(&args, false);
        fails_with(
            &o,
            "cannot write to standard output: No space left on device",
        );
        assert!(!stderr(&o).contains("os error 28): "), "{}", stderr(&o));
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[cfg(unix)]
#[test]
fn item8_stderr_on_dev_full_does_not_panic() {
    let d = tmpdir("harden", "item8-stderr");
    std::fs::write(d.join("m.toml"), PHONG).unwrap();
    std::fs::write(d.join("scene.toml"), scene("m.toml")).unwrap();
    // An error with nowhere to report it: status 1.
    let o = run_full(&["ndf", "stats", s(&d.join("missing.toml"))], true);
    assert_eq!(o.status.code(), Some(1), "{:?}", o.status);
    // Success with a progress line on a full stderr: status 0, the image written.
    let png = d.join("out.png");
    let o = run_full(
        &["render", s(&d.join("scene.toml")), "--out", s(&png)],
        true,
    );
    assert_eq!(o.status.code(), Some(0), "{:?}", o.status);
    assert!(png.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item12_os_errors_are_printed_once() {
    let d = tmpdir("harden", "item12-os");
    let missing = d.join("missing.toml");
    for args in [
        vec!["ndf", "stats", s(&missing)],
        vec!["render", s(&missing), "--out", s(&d.join("x.png"))],
        vec!["map", "info", s(&d.join("missing.map"))],
        vec![
            "fit",
            s(&d.join("missing.csv")),
            "--lobes",
            "1",
            "--out",
            s(&d.join("o.toml")),
        ],
    ] {
        let o = run(&args);
        let e = stderr(&o);
        fails_with(&o, "missing");
        assert_eq!(
            e.matches("No such file or directory").count(),
            1,
            "{args:?}: {e}"
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item5_a_written_map_always_passes_map_info() {
    let d = tmpdir("harden", "item5");
    let n = 16u32;
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(n, n, |x, y| {
        image::Luma([((x * 7 + y * 13) % 64 * 1000) as u16])
    });
    let png = d.join("h.png");
    img.save(&png).unwrap();
    for (texel, height) in [
        ("1e-3", "1e160"),
        ("1e-150", "1e10"),
        ("1e-3", "1e300"),
        ("1e-3", "1e3"),
    ] {
        let map = d.join("h.map");
        let o = run(&[
            "extract",
            s(&png),
            "--texel-size",
            texel,
            "--height-scale",
            height,
            "--out",
            s(&map),
        ]);
        eprintln!("{texel} {height}: {:?} {}", o.status, stderr(&o).trim());
        if o.status.success() {
            let info = run(&["map", "info", s(&map)]);
            ok(&info);
        } else {
            // Refused before reading (scales whose facets overflow `f64`, naming the height
            // map), or not written (NaN lobes, naming the map file).
            let e = stderr(&o);
            fails_with(
                &o,
                if e.contains("h.png:") {
                    "h.png"
                } else {
                    "h.map"
                },
            );
            assert!(
                !map.exists(),
                "{texel} {height}: a failed extract left a map"
            );
        }
        let _ = std::fs::remove_file(&map);
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// A `w × h` 8-bit grey PNG of one value: a few kilobytes on disk whatever its size.
fn flat_png(path: &Path, w: u32, h: u32) {
    let img = image::ImageBuffer::<image::Luma<u8>, Vec<u8>>::from_pixel(w, h, image::Luma([100]));
    img.save(path).unwrap();
}

#[test]
fn item3_extract_above_the_memory_budget_is_refused_from_the_header() {
    let d = tmpdir("harden", "item3-extract");
    let png = d.join("wide.png");
    flat_png(&png, 65536, 256);
    assert!(std::fs::metadata(&png).unwrap().len() < 200_000);
    let map = d.join("wide.map");
    let t = std::time::Instant::now();
    let o = cmd()
        .args([
            "extract",
            s(&png),
            "--texel-size",
            "1",
            "--height-scale",
            "1",
            "--out",
            s(&map),
        ])
        .env_remove("MESO_MEMORY_BUDGET")
        .output()
        .unwrap();
    eprintln!("{}", stderr(&o).trim());
    fails_with(&o, "wide.png: extracting the NDF pyramid needs about");
    assert!(stderr(&o).contains("memory budget of"), "{}", stderr(&o));
    assert!(t.elapsed().as_secs_f64() < 10.0, "refused before the work");
    assert!(!map.exists());
    // A small map under a tiny budget, by option and by environment variable.
    let small = d.join("small.png");
    flat_png(&small, 64, 64);
    let args = [
        "extract",
        s(&small),
        "--texel-size",
        "1",
        "--height-scale",
        "1",
        "--out",
        s(&map),
    ];
    let o = cmd()
        .args(["--memory-budget", "100K"])
        .args(args)
        .output()
        .unwrap();
    fails_with(&o, "small.png: extracting the NDF pyramid needs about");
    assert!(stderr(&o).contains("(--memory-budget;"), "{}", stderr(&o));
    let o = cmd()
        .args(args)
        .env("MESO_MEMORY_BUDGET", "100K")
        .output()
        .unwrap();
    fails_with(&o, "(MESO_MEMORY_BUDGET;");
    let o = cmd()
        .args(args)
        .env("MESO_MEMORY_BUDGET", "lots")
        .output()
        .unwrap();
    fails_with(&o, "MESO_MEMORY_BUDGET=\"lots\": not a size");
    assert!(!map.exists());
    ok(&cmd()
        .args(["--memory-budget", "1G"])
        .args(args)
        .output()
        .unwrap());
    assert!(map.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[cfg(target_os = "linux")]
#[test]
fn item3_memory_capped_run_is_an_error_not_an_abort() {
    if Command::new("prlimit").arg("--version").output().is_err() {
        eprintln!("skipped: no prlimit");
        return;
    }
    let d = tmpdir("harden", "item3-capped");
    let png = d.join("wide.png");
    flat_png(&png, 65536, 256);
    let map = d.join("wide.map");
    // The budget raised far above what the 1 GiB address-space cap allows: the allocation
    // itself fails, and must be an error, not SIGABRT.
    let o = Command::new("prlimit")
        .arg("--as=1073741824")
        .arg(env!("CARGO_BIN_EXE_meso"))
        .args([
            "--memory-budget",
            "100G",
            "extract",
            s(&png),
            "--texel-size",
            "1",
            "--height-scale",
            "1",
            "--out",
            s(&map),
        ])
        .output()
        .unwrap();
    eprintln!("{:?}: {}", o.status, stderr(&o).trim());
    fails_with(&o, "out of memory: cannot allocate");
    assert!(!map.exists());
    // Under the same cap with the default budget (lowered to the cap): refused up front.
    let o = Command::new("prlimit")
        .arg("--as=1073741824")
        .arg(env!("CARGO_BIN_EXE_meso"))
        .args([
            "extract",
            s(&png),
            "--texel-size",
            "1",
            "--height-scale",
            "1",
            "--out",
            s(&map),
        ])
        .env_remove("MESO_MEMORY_BUDGET")
        .output()
        .unwrap();
    fails_with(&o, "memory budget of");
    assert!(!map.exists());
    // An allocation that is no `try_reserve` (the 3 GiB render target) failing under the cap:
    // the binary's allocator turns it into an error too.
    std::fs::write(d.join("m.toml"), PHONG).unwrap();
    std::fs::write(d.join("scene.toml"), scene("m.toml")).unwrap();
    let png = d.join("big.png");
    let o = Command::new("prlimit")
        .arg("--as=2147483648")
        .arg(env!("CARGO_BIN_EXE_meso"))
        .args([
            "--memory-budget",
            "100G",
            "render",
            s(&d.join("scene.toml")),
        ])
        .args(["--width", "16384", "--height", "16384", "--out", s(&png)])
        .output()
        .unwrap();
    eprintln!("{:?}: {}", o.status, stderr(&o).trim());
    fails_with(&o, "out of memory: cannot allocate 3.00 GiB");
    assert!(!png.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item3_render_and_environment_map_above_the_budget_are_refused() {
    let (d, _m, _p) = brdf_inputs("item3-render");
    let sc = d.join("scene.toml");
    std::fs::write(&sc, scene("m.toml")).unwrap();
    let out = d.join("big.png");
    // The largest render the options allow, under the default budget (4 GiB at most).
    let o = cmd()
        .args(["render", s(&sc), "--width", "16384", "--height", "16384"])
        .args(["--out", s(&out)])
        .env_remove("MESO_MEMORY_BUDGET")
        .output()
        .unwrap();
    fails_with(&o, "rendering 16384×16384 pixels needs about");
    assert!(!out.exists());
    // An environment map whose pixels need more than the budget.
    let env = d.join("sky.png");
    let img = image::ImageBuffer::<image::Rgb<u8>, Vec<u8>>::from_pixel(
        2048,
        1024,
        image::Rgb([90, 120, 200]),
    );
    img.save(&env).unwrap();
    let with_env = format!("{}[environment]\nfile = \"sky.png\"\n", scene("m.toml"));
    std::fs::write(&sc, with_env).unwrap();
    let o = cmd()
        .args(["--memory-budget", "64M", "render", s(&sc), "--out", s(&out)])
        .output()
        .unwrap();
    fails_with(&o, "sky.png: loading the environment map needs about");
    assert!(!out.exists());
    ok(&cmd()
        .args(["--memory-budget", "1G", "render", s(&sc), "--out", s(&out)])
        .output()
        .unwrap());
    // An OBJ mesh, from its size.
    std::fs::write(
        d.join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".repeat(40),
    )
    .unwrap();
    let with_mesh = scene("m.toml").replace(
        "kind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\n",
        "kind = \"mesh\"\nfile = \"tri.obj\"\n",
    );
    std::fs::write(&sc, with_mesh).unwrap();
    let o = cmd()
        .args([
            "--memory-budget",
            "10K",
            "render",
            s(&sc),
            "--out",
            s(&d.join("m.png")),
        ])
        .output()
        .unwrap();
    fails_with(&o, "tri.obj: loading the OBJ mesh needs about");
    assert!(!d.join("m.png").exists());
    std::fs::remove_dir_all(&d).unwrap();
}

/// A `w × h` 8-bit RGB PNG of one colour (a flat normal map, `(128, 128, 255)`).
fn flat_rgb_png(path: &Path, w: u32, h: u32) {
    let img = image::ImageBuffer::<image::Rgb<u8>, Vec<u8>>::from_pixel(
        w,
        h,
        image::Rgb([128, 128, 255]),
    );
    img.save(path).unwrap();
}

#[test]
fn item3_export_above_the_memory_budget_is_refused_from_the_header() {
    let d = tmpdir("harden", "item3-export");
    // A normal map of some 150 KB whose header declares 65536 × 256 texels.
    let wide = d.join("wide.png");
    flat_rgb_png(&wide, 65536, 256);
    assert!(std::fs::metadata(&wide).unwrap().len() < 1_000_000);
    let out = d.join("out");
    let t = std::time::Instant::now();
    let o = run(&[
        "--memory-budget",
        "1G",
        "export",
        s(&wide),
        "--out",
        s(&out),
    ]);
    fails_with(&o, "wide.png: exporting 65536 × 256 texels needs about");
    assert!(
        stderr(&o).contains("memory budget of 1.00 GiB"),
        "{}",
        stderr(&o)
    );
    assert!(t.elapsed().as_secs_f64() < 10.0, "refused before the work");
    assert!(!out.exists(), "no output folder");
    // The same file as a height map.
    let o = run(&[
        "--memory-budget",
        "1G",
        "export",
        s(&wide),
        "--texel-size",
        "1",
        "--height-scale",
        "1",
        "--out",
        s(&out),
    ]);
    fails_with(&o, "wide.png: exporting 65536 × 256 texels needs about");
    assert!(!out.exists());
    // A small map with a roughness map and a base colour image whose headers declare 4096²
    // (the largest size allowed).
    let small = d.join("small.png");
    flat_rgb_png(&small, 16, 16);
    let big = d.join("big.png");
    flat_png(&big, 4096, 4096);
    assert!(std::fs::metadata(&big).unwrap().len() < 200_000);
    let budget = ["--memory-budget", "64M", "export"];
    let o = cmd()
        .args(budget)
        .args([s(&small), "--roughness-map", s(&big), "--out", s(&out)])
        .output()
        .unwrap();
    fails_with(&o, "big.png: loading the roughness map needs about");
    assert!(!out.exists());
    let o = cmd()
        .args(budget)
        .args([s(&small), "--base-color", s(&big), "--out", s(&out)])
        .output()
        .unwrap();
    fails_with(&o, "big.png: loading the base colour image needs about");
    assert!(!out.exists());
    // The budget from the environment.
    let o = cmd()
        .args([
            "export",
            s(&small),
            "--base-color",
            s(&big),
            "--out",
            s(&out),
        ])
        .env("MESO_MEMORY_BUDGET", "64M")
        .output()
        .unwrap();
    fails_with(&o, "(MESO_MEMORY_BUDGET;");
    assert!(!out.exists());
    // Above the size limits, from the header too (whatever the budget).
    let huge = d.join("huge.png");
    flat_png(&huge, 8192, 8192);
    for opt in ["--roughness-map", "--base-color"] {
        let o = cmd()
            .args([
                "--memory-budget",
                "100G",
                "export",
                s(&small),
                opt,
                s(&huge),
            ])
            .args(["--out", s(&out)])
            .output()
            .unwrap();
        fails_with(&o, "huge.png is too large: 8192×8192");
        assert!(!out.exists());
    }
    // Within the budget: written.
    let rough = d.join("rough.png");
    flat_png(&rough, 16, 16);
    ok(&cmd()
        .args(budget)
        .args([s(&small), "--roughness-map", s(&rough), "--out", s(&out)])
        .output()
        .unwrap());
    assert!(out.join("normal.ktx2").exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item3_merl_fit_above_the_memory_budget_is_refused() {
    let d = tmpdir("harden", "item3-merl");
    // A valid MERL binary (every cell 0): 35 MB on disk, a fixed 70 MB to read it and a few
    // hundred to sample it.
    let merl = d.join("zero.binary");
    let mut bytes = Vec::with_capacity(34_992_012);
    for dim in [90i32, 90, 180] {
        bytes.extend_from_slice(&dim.to_le_bytes());
    }
    bytes.resize(34_992_012, 0);
    std::fs::write(&merl, &bytes).unwrap();
    drop(bytes);
    let out = d.join("fit.toml");
    let t = std::time::Instant::now();
    let o = run(&[
        "--memory-budget",
        "64M",
        "fit",
        s(&merl),
        "--lobes",
        "1",
        "--out",
        s(&out),
    ]);
    fails_with(&o, "zero.binary: fitting a MERL table needs about");
    assert!(
        stderr(&o).contains("memory budget of 64.0 MiB"),
        "{}",
        stderr(&o)
    );
    assert!(t.elapsed().as_secs_f64() < 10.0, "refused before reading");
    assert!(!out.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item13_extract_and_render_report_each_phase_time() {
    let d = tmpdir("harden", "item13");
    let map = map_file(&d);
    let _ = map;
    // `meso extract` (run by map_file again, to see its report).
    let o = run(&[
        "extract",
        s(&d.join("h.png")),
        "--texel-size",
        "0.01",
        "--height-scale",
        "0.05",
        "--out",
        s(&d.join("h2.map")),
    ]);
    ok(&o);
    let e = stderr(&o);
    let phases = |e: &str, names: &[&str]| {
        for n in names {
            let i = e
                .find(&format!(" {n} "))
                .or_else(|| e.find(&format!("({n} ")))
                .unwrap_or_else(|| panic!("no {n} phase in {e}"));
            let secs: f64 = e[i + n.len() + 2..]
                .split_whitespace()
                .next()
                .unwrap()
                .parse()
                .unwrap_or_else(|_| panic!("no time after {n}: {e}"));
            assert!((0.0..1e4).contains(&secs), "{n} {secs}: {e}");
        }
    };
    // The map is written band by band as the pyramid is fitted (streamed, format 4): its
    // writing is part of the "pyramid" phase.
    phases(&e, &["load", "pyramid"]);
    // A render of a height-map material: the extraction is its own phase, not hidden.
    std::fs::write(
        d.join("m.toml"),
        heightmap_material(
            "h.png",
            0.01,
            0.05,
            "represent = \"lobes\"\n[transfer]\nkind = \"phong\"\nexponent = 50.0\n\
             specular = [1.0, 1.0, 1.0]\n",
        ),
    )
    .unwrap();
    std::fs::write(d.join("scene.toml"), scene("m.toml")).unwrap();
    // A cache folder of this test's own: a pyramid or facet set cached by an earlier run of
    // the same map would skip the phase this test looks for.
    let render = || {
        cmd()
            .env("MESO_CACHE_DIR", d.join("cache"))
            .args([
                "render",
                s(&d.join("scene.toml")),
                "--out",
                s(&d.join("r.png")),
            ])
            .output()
            .expect("run meso")
    };
    let o = render();
    ok(&o);
    let e = stderr(&o);
    assert!(e.starts_with("rendered 8x8 at 1 spp in "), "{e}");
    // The render's own time, then the whole command's (the load and the extraction included).
    let (render_s, all_s): (f64, f64) = {
        let head = &e["rendered 8x8 at 1 spp in ".len()..];
        let render_s = head.split_whitespace().next().unwrap().parse().unwrap();
        let all = &head[head.find('(').unwrap() + 1..];
        assert!(all.contains(" s in all) -> "), "{e}");
        (
            render_s,
            all.split_whitespace().next().unwrap().parse().unwrap(),
        )
    };
    assert!(all_s >= render_s, "{e}");
    phases(&e, &["load", "pyramid", "render", "write"]);
    // The default representation, facets: their horizon march is its own phase.
    let m = std::fs::read_to_string(d.join("m.toml")).unwrap();
    std::fs::write(d.join("m.toml"), m.replace("represent = \"lobes\"\n", "")).unwrap();
    let o = render();
    ok(&o);
    phases(&stderr(&o), &["load", "facets", "render", "write"]);
    std::fs::remove_dir_all(&d).unwrap();
}

/// No output replaces a file the command read, however it was named: a scene's environment
/// map and a texture's height map, a material's height map (`brdf`, `ndf plot`, `render`), and
/// `meso export`'s inputs lying in its output folder under the name of a file it writes. Each
/// is refused with the clash named, exit 1, and the input left byte for byte.
#[test]
fn outputs_never_replace_files_the_inputs_name() {
    let d = tmpdir("harden", "indirect-inputs");
    let n = 16u32;
    let heights = image::ImageBuffer::<image::Luma<u8>, Vec<u8>>::from_fn(n, n, |x, y| {
        image::Luma([((x * 37 + y * 11) % 97 + 60) as u8])
    });
    let h = d.join("h.png");
    heights.save(&h).unwrap();
    let h_bytes = std::fs::read(&h).unwrap();
    let same = |p: &Path| {
        assert_eq!(
            std::fs::read(p).unwrap(),
            h_bytes,
            "{} changed",
            p.display()
        )
    };
    std::fs::write(
        d.join("hm.toml"),
        heightmap_material(
            "h.png",
            0.01,
            0.002,
            "[transfer]\nkind = \"microfacet\"\nalpha = 0.2\n",
        ),
    )
    .unwrap();
    std::fs::write(
        d.join("tex.toml"),
        "[texture]\nkind = \"bump-mapped\"\nfile = \"h.png\"\ntexel_size = 0.0625\n\
         height_scale = 0.01\n[transfer]\nkind = \"phong\"\nexponent = 20.0\n",
    )
    .unwrap();
    one_pair_csv(d.join("pairs.csv"));
    let head = "[camera]\nkind = \"orthographic\"\nposition = [0.0, 0.0, 5.0]\n\
                look_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nwidth = 2.0\n\
                [image]\nwidth = 8\nheight = 8\nspp = 1\n";
    let plane = |m: &str| {
        format!(
            "[[object]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\
             material = \"{m}\"\n"
        )
    };
    std::fs::write(
        d.join("env.scene.toml"),
        format!(
            "{head}[environment]\nfile = \"h.png\"\n{}",
            plane("hm.toml")
        ),
    )
    .unwrap();
    std::fs::write(
        d.join("tex.scene.toml"),
        format!("{head}{}", plane("tex.toml")),
    )
    .unwrap();
    std::fs::write(
        d.join("hm.scene.toml"),
        format!("{head}{}", plane("hm.toml")),
    )
    .unwrap();
    let p = |f: &str| d.join(f);
    for args in [
        vec![
            "brdf",
            s(&p("hm.toml")),
            "--pairs",
            s(&p("pairs.csv")),
            "--out",
            s(&h),
        ],
        vec!["ndf", "plot", s(&p("hm.toml")), "--out", s(&h)],
        vec!["render", s(&p("hm.scene.toml")), "--out", s(&h)],
        vec!["render", s(&p("tex.scene.toml")), "--out", s(&h)],
    ] {
        fails_with(&run(&args), "is the same file as the input");
        same(&h);
    }
    // An environment map must be an EXR: the scene fails on it, but never by replacing it.
    let o = run(&["render", s(&p("env.scene.toml")), "--out", s(&h)]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    same(&h);
    // meso export: the main image, and a base colour, inside the output folder under the
    // names the export writes. The folder is left as it was.
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    let normal = image::RgbImage::from_pixel(n, n, image::Rgb([128, 128, 255]));
    let main = out.join("normal_mip0.png");
    normal.save(&main).unwrap();
    let main_bytes = std::fs::read(&main).unwrap();
    let o = run(&["export", s(&main), "--out", s(&out)]);
    fails_with(&o, "is the same file as the input");
    assert_eq!(std::fs::read(&main).unwrap(), main_bytes);
    assert_eq!(names(&out), ["normal_mip0.png"], "nothing else written");
    let outside = d.join("normal.png");
    normal.save(&outside).unwrap();
    let colour = out.join("base_color.png");
    std::fs::copy(&outside, &colour).unwrap();
    let o = run(&[
        "export",
        s(&outside),
        "--base-color",
        s(&colour),
        "--out",
        s(&out),
    ]);
    fails_with(&o, "base_color.png");
    assert_eq!(std::fs::read(&colour).unwrap(), main_bytes);
    std::fs::remove_dir_all(&d).unwrap();
}
