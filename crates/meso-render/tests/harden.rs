//! Issue #12 (hardening): input size limits by bytes read (item 4), OBJ files never open their
//! `mtllib` (item 4), non-finite OBJ normals and UVs refused (item 12).

use meso_render::scene::{MAX_ENVIRONMENT_BYTES, MAX_OBJ_BYTES, MAX_SCENE_BYTES};
use meso_render::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("meso-render-harden-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn resolver(_: &Path) -> Result<Arc<dyn Shader>, ResolveError> {
    Ok(Arc::new(Lambert { albedo: [1.0; 3] }))
}

/// A sparse file one byte over `limit` (no disk space used).
fn sparse(path: &Path, limit: u64) {
    std::fs::File::create(path)
        .unwrap()
        .set_len(limit + 1)
        .unwrap();
}

#[test]
fn item4_scene_file_limit_counts_bytes_read() {
    let d = tmpdir("scene");
    let big = d.join("big.toml");
    sparse(&big, MAX_SCENE_BYTES);
    let e = Scene::from_toml_file(&big, &resolver)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("big.toml") && e.contains("limit"), "{e}");
    // /dev/zero reports size 0 and never ends.
    let e = Scene::from_toml_file(Path::new("/dev/zero"), &resolver)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("/dev/zero") && e.contains("limit of 16777216 bytes"),
        "{e}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item4_obj_and_environment_files_have_a_limit() {
    let d = tmpdir("obj-env");
    let obj = d.join("big.obj");
    sparse(&obj, MAX_OBJ_BYTES);
    let e = Mesh::from_obj(&obj).err().unwrap().to_string();
    assert!(e.contains("big.obj") && e.contains("limit"), "{e}");
    let exr = d.join("big.exr");
    sparse(&exr, MAX_ENVIRONMENT_BYTES);
    let e = EnvironmentMap::from_file(&exr, 1.0, 0.0)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("big.exr") && e.contains("limit"), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

#[cfg(unix)]
#[test]
fn item4_obj_loading_does_not_read_mtllib_files() {
    let d = tmpdir("mtllib");
    // A FIFO without a writer: opening it for reading blocks, so reading it would hang.
    let fifo = d.join("trap.mtl");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let obj = d.join("tri.obj");
    std::fs::write(
        &obj,
        format!("mtllib trap.mtl\nmtllib {}\n{TRIANGLE}", fifo.display()),
    )
    .unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let o = obj.clone();
    std::thread::spawn(move || {
        let _ = tx.send(Mesh::from_obj(&o).map(|m| m.indices().len()));
    });
    let got = rx
        .recv_timeout(std::time::Duration::from_secs(20))
        .expect("loading the OBJ opened its mtllib (blocked on the FIFO)");
    assert_eq!(got.unwrap(), 1);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item12_obj_with_nan_normals_or_uvs_is_refused() {
    let d = tmpdir("nan");
    for (name, text, what) in [
        (
            "n.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn nan 0 1\nvn 0 0 1\nf 1//1 2//2 3//3\n",
            "non-finite normal",
        ),
        (
            "uv.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 inf\nvt 0 1\nf 1/1 2/2 3/3\n",
            "non-finite texture coordinate",
        ),
    ] {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        let e = Mesh::from_obj(&p).err().map(|e| e.to_string());
        assert!(
            e.as_deref().is_some_and(|e| e.contains(what)),
            "{name}: {e:?}"
        );
    }
    let p = d.join("ok.obj");
    std::fs::write(&p, TRIANGLE).unwrap();
    assert!(Mesh::from_obj(&p).is_ok());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn item12_scene_toml_error_is_one_short_line() {
    let long = "x".repeat(2_000_000);
    let text = format!("[camera]\nkind = \"orthographic\"\n[image]\nwidth = 8 {long}\n");
    let e = Scene::from_toml_str(&text, Path::new("."), &resolver)
        .err()
        .unwrap()
        .to_string();
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(
        e.len() < 300,
        "{} chars: {}",
        e.len(),
        &e[..300.min(e.len())]
    );
    assert!(e.contains("line 4, column"), "{e}");
    let e = Scene::from_toml_str("[camera\n", Path::new("."), &resolver)
        .err()
        .unwrap()
        .to_string();
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.contains("line 1"), "{e}");
}

/// Found by the `obj` fuzz target: face indices that refer to no element (here a texture index
/// of −1111111111111111) overflowed the OBJ reader's offset arithmetic (a panic with overflow
/// checks, silently wrong UVs without). They are refused with the line; relative indices that
/// do exist still load.
#[test]
fn item4_obj_indices_that_refer_to_nothing_are_refused() {
    let d = tmpdir("indices");
    let obj = d.join("bad.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/-1111111111111111 2/1 3/1\n",
    )
    .unwrap();
    let e = Mesh::from_obj(&obj).err().unwrap().to_string();
    assert!(
        e.contains("bad.obj") && e.contains("line 5") && e.contains("refers to no element"),
        "{e}"
    );
    for (name, text) in [
        ("huge.obj", "v 0 0 0\nf 1 1 99999999999999999999999\n"),
        // The fuzzer's second find: −11 reaches before the first of three `vt`.
        (
            "relative.obj",
            "v 0 0 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/-11/1 1/2 1/3\n",
        ),
        ("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
    ] {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        let e = Mesh::from_obj(&p)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("refers to no element"), "{name}: {e}");
    }
    let ok = d.join("ok.obj");
    std::fs::write(
        &ok,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n# a comment\nf -3/1 -2/1 -1/1\n",
    )
    .unwrap();
    assert_eq!(Mesh::from_obj(&ok).unwrap().indices().len(), 1);
    std::fs::remove_dir_all(&d).unwrap();
}
