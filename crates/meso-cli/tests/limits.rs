//! Inputs at and beyond meso's limits through the binary: files without a size (devices, FIFOs),
//! absurd but finite values, sizes and budgets (the CLI audit's findings).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn cmd() -> Command {
    Command::new(env!("CARGO_BIN_EXE_meso"))
}

fn run(args: &[&str]) -> Output {
    cmd().args(args).output().expect("run meso")
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-limits-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn ok(o: &Output) {
    assert!(o.status.success(), "status {:?}: {}", o.status, stderr(o));
}

/// A failed run: status 1 (no panic, no kill), one error line naming each of `what`.
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
    let d = tmpdir("devzero");
    let m = d.join("z.toml");
    std::fs::write(
        &m,
        "[ndf]\nkind = \"heightmap\"\nfile = \"/dev/zero\"\ntexel_size = 1.0\nheight_scale = 1.0\n\
         [transfer]\nkind = \"phong\"\nexponent = 50.0\nspecular = [1.0, 1.0, 1.0]\n",
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
    let d = tmpdir("fifo");
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
