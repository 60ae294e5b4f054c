//! The input log of `meso_core::io` (its own test binary: the log is process-wide).

use meso_core::io::{
    check_not_recorded_input, read_limited, read_limited_unnoted, record_inputs, recorded_inputs,
    stage_with, write_atomic,
};

#[test]
fn a_file_read_as_an_input_is_never_written_while_recording() {
    let d = std::env::temp_dir().join(format!("meso-input-log-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let (input, cache, other) = (d.join("in.toml"), d.join("cache.bin"), d.join("out.txt"));
    for p in [&input, &cache] {
        std::fs::write(p, b"original").unwrap();
    }
    // Not recording: nothing noted, every write allowed.
    read_limited(&input, 100).unwrap();
    assert!(recorded_inputs().is_empty());
    check_not_recorded_input(&input).unwrap();

    record_inputs();
    read_limited(&input, 100).unwrap();
    read_limited_unnoted(&cache, 100).unwrap();
    assert_eq!(recorded_inputs(), vec![input.clone()]);
    // The input, however named (through `.`), is refused by both writers; the file is kept.
    let dotted = d.join(".").join("in.toml");
    let e = write_atomic(&dotted, b"replaced").unwrap_err().to_string();
    assert!(e.contains("is the same file as the input"), "{e}");
    assert!(stage_with(&input, |w| w.write_all(b"replaced")).is_err());
    assert_eq!(std::fs::read(&input).unwrap(), b"original");
    // A hard link to it is the same file too.
    let link = d.join("link.toml");
    std::fs::hard_link(&input, &link).unwrap();
    assert!(write_atomic(&link, b"replaced").is_err());
    // Other files, and a cache entry read without noting it, are written as usual.
    write_atomic(&other, b"new").unwrap();
    write_atomic(&cache, b"refreshed").unwrap();
    assert_eq!(std::fs::read(&cache).unwrap(), b"refreshed");
    // Recording again forgets what was noted.
    record_inputs();
    write_atomic(&input, b"now allowed").unwrap();
    std::fs::remove_dir_all(&d).unwrap();
}
