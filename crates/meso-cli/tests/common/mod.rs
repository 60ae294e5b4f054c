//! Helpers shared by the CLI's integration tests (each test binary includes this module with
//! `mod common;` and uses what it needs).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `meso` binary under test, as a command to add arguments to.
pub fn cmd() -> Command {
    Command::new(env!("CARGO_BIN_EXE_meso"))
}

/// Run `meso` with `args` and collect its output.
pub fn run(args: &[&str]) -> Output {
    cmd().args(args).output().expect("run meso")
}

/// A fresh, empty scratch directory `meso-<group>-<name>-<pid>` under the system's temporary
/// directory (removed first if a previous run left it).
pub fn tmpdir(group: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-{group}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A path as `&str` (the tests' paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The standard error of a run, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Assert that a run succeeded, showing its standard error if not.
pub fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "meso failed ({:?}): {}",
        o.status,
        stderr(o)
    );
}

/// Write the one-pair measurement CSV most BRDF tests query (θ_i = 30°, φ_i = 0, mirror
/// direction θ_o = 30°, φ_o = 180°) to `path`, and return `path`.
pub fn one_pair_csv(path: PathBuf) -> PathBuf {
    std::fs::write(&path, "theta_i,phi_i,theta_o,phi_o\n30,0,30,180\n").unwrap();
    path
}

/// A material whose NDF is `[ndf] kind = "heightmap"` over the image `file` (relative to the
/// material, or absolute) with the given texel size and height scale, followed by `rest`: more
/// `[ndf]` keys and the other tables, each line ending in `\n`. The numbers are written as
/// TOML floats (`1.0`, `0.01`).
pub fn heightmap_material(file: &str, texel_size: f64, height_scale: f64, rest: &str) -> String {
    format!(
        "[ndf]\nkind = \"heightmap\"\nfile = \"{file}\"\ntexel_size = {texel_size:?}\n\
         height_scale = {height_scale:?}\n{rest}"
    )
}
