//! `meso_core::io`: atomic writes (temporary files, symlinks, devices, FIFOs, permissions), the
//! temporary files' name pattern and their clean-up, all-or-nothing commits of several outputs,
//! the output-is-an-input check and limited reads. Test names carry the item of the issue that
//! asked for the behaviour.

use meso_core::io::*;
use std::path::{Path, PathBuf};

fn tmpdir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("meso-io-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn failed_write_leaves_nothing() {
    let dir = tmpdir("failed");
    let p = dir.join("out.bin");
    let r = write_atomic_with(&p, |w| {
        w.write_all(b"half")?;
        Err(std::io::Error::other("boom"))
    });
    assert!(r.is_err());
    assert!(!p.exists());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "temp file removed"
    );
    write_atomic(&p, b"whole").unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"whole");
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "no temp left");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_output_to_device_node_is_written_in_place() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tmpdir("item1-dev");
    let dev = dir.join("null");
    // A character device copy of /dev/null (major 1, minor 3).
    let made = std::process::Command::new("mknod")
        .arg(&dev)
        .args(["c", "1", "3"])
        .status();
    if !matches!(made, Ok(s) if s.success()) {
        eprintln!("skipped: mknod needs privileges");
        return;
    }
    write_atomic(&dev, b"into the device").unwrap();
    let ft = std::fs::symlink_metadata(&dev).unwrap().file_type();
    assert!(ft.is_char_device(), "still a character device: {ft:?}");
    // Through a symlink too.
    let link = dir.join("link");
    std::os::unix::fs::symlink(&dev, &link).unwrap();
    write_atomic(&link, b"again").unwrap();
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::metadata(&dev)
        .unwrap()
        .file_type()
        .is_char_device());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2, "no temp left");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_output_to_fifo_is_written_in_place() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tmpdir("item1-fifo");
    let fifo = dir.join("fifo");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(ok.success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    write_atomic(&fifo, b"through the pipe").unwrap();
    assert_eq!(reader.join().unwrap(), b"through the pipe");
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_symlink_to_file_replaces_the_file_not_the_link() {
    let dir = tmpdir("item1-link");
    let sub = dir.join("real");
    std::fs::create_dir(&sub).unwrap();
    let target = sub.join("data.csv");
    std::fs::write(&target, b"old").unwrap();
    let link = dir.join("link.csv");
    std::os::unix::fs::symlink("real/data.csv", &link).unwrap();
    write_atomic(&link, b"new").unwrap();
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&target).unwrap(), b"new");
    // A dangling link creates the file it names.
    let dangling = dir.join("dangling.csv");
    std::os::unix::fs::symlink("real/new.csv", &dangling).unwrap();
    write_atomic(&dangling, b"fresh").unwrap();
    assert_eq!(std::fs::read(sub.join("new.csv")).unwrap(), b"fresh");
    assert_eq!(std::fs::read_dir(&sub).unwrap().count(), 2, "no temp left");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_existing_file_keeps_its_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tmpdir("item1-perm");
    let p = dir.join("secret.toml");
    std::fs::write(&p, b"old").unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o600)).unwrap();
    write_atomic(&p, b"new").unwrap();
    let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o7777;
    assert_eq!(mode, 0o600);
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o640)).unwrap();
    write_atomic(&p, b"newer").unwrap();
    let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o7777;
    assert_eq!(mode, 0o640);
    assert_eq!(std::fs::read(&p).unwrap(), b"newer");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_new_file_gets_the_usual_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tmpdir("item1-newperm");
    let reference = dir.join("reference");
    std::fs::File::create(&reference).unwrap();
    let p = dir.join("new.csv");
    write_atomic(&p, b"x").unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o7777;
    assert_eq!(
        mode(&p),
        mode(&reference),
        "0666 & !umask, like File::create"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn item1_directory_target_is_refused() {
    let dir = tmpdir("item1-dir");
    let e = write_atomic(&dir, b"x").unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::IsADirectory);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item1_output_that_is_an_input_is_refused() {
    let dir = tmpdir("item1-input");
    let input = dir.join("in.toml");
    std::fs::write(&input, b"input").unwrap();
    let link = dir.join("alias.toml");
    std::os::unix::fs::symlink(&input, &link).unwrap();
    let hard = dir.join("hard.toml");
    std::fs::hard_link(&input, &hard).unwrap();
    let other = dir.join("other.toml");
    std::fs::write(&other, b"other").unwrap();
    for out in [&input, &link, &hard] {
        let e = check_not_input(out, &[&other, &input]).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
        let msg = e.to_string();
        assert!(msg.contains("same file as the input"), "{msg}");
        assert!(msg.contains("in.toml"), "{msg}");
    }
    let dotted = dir.join(".").join("in.toml");
    assert!(check_not_input(&dotted, &[&input]).is_err());
    check_not_input(&other, &[&input]).unwrap();
    check_not_input(&dir.join("missing.toml"), &[&input]).unwrap();
    check_not_input(Path::new("/dev/null"), &[Path::new("/dev/null")]).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item2_planted_symlink_at_the_old_temp_name_is_not_followed() {
    let dir = tmpdir("item2");
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, b"precious").unwrap();
    let out = dir.join("out.csv");
    // The names the old implementation used (`.NAME.tmp-PID`) and plausible variants.
    for name in [
        format!(".out.csv.tmp-{}", std::process::id()),
        ".out.csv.tmp".to_string(),
    ] {
        std::os::unix::fs::symlink(&victim, dir.join(name)).unwrap();
    }
    write_atomic(&out, b"output").unwrap();
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    assert_eq!(std::fs::read(&out).unwrap(), b"output");
    // The planted links are untouched, and no temp file is left.
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names.len(), 4, "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn item2_temp_files_are_created_exclusively_with_random_names() {
    let dir = tmpdir("item2-names");
    let out = dir.join("out.csv");
    let mut seen = Vec::new();
    for _ in 0..2 {
        write_atomic_with(&out, |_| {
            let names: Vec<String> = std::fs::read_dir(&dir)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with(".out.csv."))
                .collect();
            seen.extend(names);
            Ok(())
        })
        .unwrap();
    }
    assert_eq!(seen.len(), 2, "{seen:?}");
    assert_ne!(seen[0], seen[1], "random names");
    // `.NAME.meso-PID.XXXXXX.tmp`: recognisable (target, writer), not predictable.
    let start = format!(".out.csv.meso-{}.", std::process::id());
    for n in &seen {
        assert!(n.starts_with(&start) && n.ends_with(".tmp"), "{n}");
        assert_eq!(n.len(), start.len() + TEMP_RANDOM_CHARS + 4, "{n}");
        assert_eq!(
            temp_file_pid(n.as_ref(), "out.csv".as_ref()),
            Some(std::process::id())
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn item2_temp_name_pattern_is_exact() {
    let pid = |n: &str| temp_file_pid(n.as_ref(), "a.png".as_ref());
    assert_eq!(pid(".a.png.meso-4242.aZ09xy.tmp"), Some(4242));
    for n in [
        ".a.png.meso-4242.aZ09x.tmp",   // 5 random characters
        ".a.png.meso-4242.aZ09xyz.tmp", // 7
        ".a.png.meso-4242.aZ-9xy.tmp",  // not alphanumeric
        ".a.png.meso-04242.aZ09xy.tmp", // leading zero
        ".a.png.meso-.aZ09xy.tmp",      // no PID
        ".a.png.meso--1.aZ09xy.tmp",    // sign
        ".a.png.meso-99999999999.aZ09xy.tmp",
        ".a.png.meso-4242.aZ09xy.tmp~",
        "a.png.meso-4242.aZ09xy.tmp",
        ".b.png.meso-4242.aZ09xy.tmp", // another target
        ".xa.png.meso-4242.aZ09xy.tmp",
        ".a.png.aZ09xy.tmp", // the old random names
        ".a.png.tmp-4242",   // the oldest
        "a.png",
    ] {
        assert_eq!(pid(n), None, "{n}");
    }
}

/// The id of a process that has exited (and been reaped).
#[cfg(unix)]
fn dead_pid() -> u32 {
    let mut c = std::process::Command::new("true").spawn().unwrap();
    let pid = c.id();
    c.wait().unwrap();
    pid
}

#[cfg(unix)]
#[test]
fn item2_stale_temp_files_of_dead_writers_are_removed() {
    let dir = tmpdir("item2-stale");
    let out = dir.join("out.csv");
    let dead = dead_pid();
    let stale = dir.join(format!(".out.csv.meso-{dead}.Ab3dE9.tmp"));
    std::fs::write(&stale, b"half an output").unwrap();
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, b"precious").unwrap();
    // What must stay: a live writer's file (pid 1 always exists; this process's own),
    // another target's, near misses of the pattern, a symlink and a directory named like a
    // stale temp file.
    let keep = [
        ".out.csv.meso-1.Ab3dE9.tmp".to_string(),
        format!(".out.csv.meso-{}.Ab3dE9.tmp", std::process::id()),
        format!(".other.csv.meso-{dead}.Ab3dE9.tmp"),
        format!(".out.csv.meso-{dead}.Ab3dE.tmp"),
        format!(".out.csv.meso-{dead}.Ab3dE9.tmp.bak"),
        format!("out.csv.meso-{dead}.Ab3dE9.tmp"),
    ];
    for k in &keep {
        std::fs::write(dir.join(k), b"keep").unwrap();
    }
    let link = dir.join(format!(".out.csv.meso-{dead}.LinkEd.tmp"));
    std::os::unix::fs::symlink(&victim, &link).unwrap();
    let sub = dir.join(format!(".out.csv.meso-{dead}.Direct.tmp"));
    std::fs::create_dir(&sub).unwrap();
    write_atomic(&out, b"output").unwrap();
    assert!(!stale.exists(), "stale temp file removed");
    assert_eq!(std::fs::read(&out).unwrap(), b"output");
    for k in &keep {
        assert_eq!(std::fs::read(dir.join(k)).unwrap(), b"keep", "{k}");
    }
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    assert!(sub.is_dir());
    // Nothing else: out.csv, victim, the kept files, the link and the directory.
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        2 + keep.len() + 2,
        "no temp left"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn item6_commit_all_writes_all_or_none() {
    let dir = tmpdir("item6");
    let a = dir.join("a.txt");
    let b = dir.join("b.txt");
    let sa = stage_with(&a, |w| w.write_all(b"a")).unwrap();
    let sb = stage_with(&b, |_| Err(std::io::Error::other("second fails")));
    assert!(sb.is_err());
    drop(sa);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "nothing left");
    let sa = stage_with(&a, |w| w.write_all(b"a")).unwrap();
    let sb = stage_with(&b, |w| w.write_all(b"b")).unwrap();
    assert!(!a.exists() && !b.exists(), "not in place before commit");
    commit_all(vec![sa, sb]).unwrap();
    assert_eq!(std::fs::read(&a).unwrap(), b"a");
    assert_eq!(std::fs::read(&b).unwrap(), b"b");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn item4_read_limited_counts_bytes_read() {
    let e = read_limited(Path::new("/dev/zero"), 1000).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::FileTooLarge);
    assert!(e.to_string().contains("1000 bytes"), "{e}");
    let dir = tmpdir("item4");
    let p = dir.join("f");
    std::fs::write(&p, [7u8; 1000]).unwrap();
    assert_eq!(read_limited(&p, 1000).unwrap().len(), 1000);
    assert!(read_limited(&p, 999).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}
