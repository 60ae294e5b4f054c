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
