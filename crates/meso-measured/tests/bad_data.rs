//! Issue 13, acceptance: bad data given to `meso fit` (through [`job::load`], what the CLI and
//! `meso.fit` call) is refused with a message that names the file and says what is wrong:
//! a truncated MERL table, NaN in a MERL table and in a sample CSV, negative values, all-zero
//! data.

use meso_measured::csv::CsvError;
use meso_measured::job::{self, LoadError};
use meso_measured::merl::{self, MerlError};
use std::path::PathBuf;

/// A directory of one test's files, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Scratch {
        let d = std::env::temp_dir().join(format!("meso-bad-data-{}-{test}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        Scratch(d)
    }

    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The error and its causes, `: `-separated, as the CLI prints them.
fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut c = e.source();
    while let Some(x) = c {
        s.push_str(": ");
        s.push_str(&x.to_string());
        c = x.source();
    }
    s
}

/// A whole MERL file whose stored value at flat index `k` (channel-major) is `value(k)`.
fn merl_bytes(value: impl Fn(usize) -> f64) -> Vec<u8> {
    let mut b = Vec::with_capacity(merl::MERL_FILE_BYTES as usize);
    for d in [90i32, 90, 180] {
        b.extend_from_slice(&d.to_le_bytes());
    }
    for k in 0..3 * merl::N_CELLS {
        b.extend_from_slice(&value(k).to_le_bytes());
    }
    b
}

const HEADER: &str = "theta_i,phi_i,theta_o,phi_o,r,g,b";

#[test]
fn truncated_merl_is_refused_naming_the_file_and_sizes() {
    let s = Scratch::new("truncated");
    let full = merl_bytes(|_| 1.0);
    for (name, len) in [
        ("half.binary", full.len() / 2),
        ("one-short.binary", full.len() - 1),
        ("header-only.binary", 12),
    ] {
        let p = s.write(name, &full[..len]);
        let e = job::load(&p, 1000).unwrap_err();
        assert!(
            matches!(e, LoadError::Merl(MerlError::BadSize { .. })),
            "{name}: {e:?}"
        );
        let msg = chain(&e);
        assert!(msg.contains(&p.display().to_string()), "{msg}");
        assert!(
            msg.contains(&format!(
                "is {len} bytes, expected {}",
                merl::MERL_FILE_BYTES
            )) && msg.contains("truncated"),
            "{msg}"
        );
    }
    // Shorter than the header, with the MERL extension.
    let p = s.write("stub.binary", &full[..5]);
    let msg = chain(&job::load(&p, 1000).unwrap_err());
    assert!(
        msg.contains(&p.display().to_string()) && msg.contains("too short"),
        "{msg}"
    );
    // Trailing data.
    let mut long = full;
    long.push(0);
    let p = s.write("long.binary", &long);
    let msg = chain(&job::load(&p, 1000).unwrap_err());
    assert!(msg.contains("trailing data"), "{msg}");
}

#[test]
fn nan_and_infinity_in_a_merl_table_are_refused_with_their_cell() {
    let s = Scratch::new("merl-nan");
    // Channel 2 (blue), cell (θh 3, θd 4, φd 5).
    let at = 2 * merl::N_CELLS + (3 * 90 + 4) * 180 + 5;
    for (bad, shown) in [(f64::NAN, "NaN"), (f64::INFINITY, "inf")] {
        let p = s.write(
            "nan.binary",
            &merl_bytes(|k| if k == at { bad } else { 0.5 }),
        );
        let e = job::load(&p, 1000).unwrap_err();
        assert!(
            matches!(
                e,
                LoadError::Merl(MerlError::NonFinite {
                    channel: 2,
                    ih: 3,
                    id: 4,
                    ip: 5,
                    ..
                })
            ),
            "{e:?}"
        );
        let msg = chain(&e);
        assert!(
            msg.contains(&p.display().to_string())
                && msg.contains(&format!("non-finite value {shown} in channel 2")),
            "{msg}"
        );
    }
}

#[test]
fn nan_in_a_sample_csv_is_refused_naming_file_line_and_column() {
    let s = Scratch::new("csv-nan");
    for (text, want) in [
        (
            format!("{HEADER}\n30,0,30,180,0.1,0.2,0.3\n30,0,40,180,0.1,NaN,0.3\n"),
            "line 3, column g: value is not finite",
        ),
        (
            format!("{HEADER}\n30,0,30,180,inf,0.2,0.3\n"),
            "line 2, column r: value is not finite",
        ),
        (
            format!("{HEADER}\n30,nan,30,180,0.1,0.2,0.3\n"),
            "line 2, column phi_i: value is not finite",
        ),
    ] {
        let p = s.write("nan.csv", text.as_bytes());
        let e = job::load(&p, 0).unwrap_err();
        assert!(
            matches!(
                e,
                LoadError::Csv {
                    source: CsvError::NonFinite { .. },
                    ..
                }
            ),
            "{e:?}"
        );
        let msg = chain(&e);
        assert!(
            msg.starts_with(&format!("{}: not a valid sample CSV", p.display()))
                && msg.contains(want),
            "{msg}"
        );
    }
}

#[test]
fn negative_values_are_refused_in_a_csv_and_are_missing_cells_in_a_merl_table() {
    let s = Scratch::new("negative");
    // CSV: a negative BRDF value is an error naming the line, column and value.
    let p = s.write(
        "neg.csv",
        format!("{HEADER}\n30,0,30,180,0.1,0.2,0.3\n30,0,30,180,0.1,0.2,-0.25\n").as_bytes(),
    );
    let e = job::load(&p, 0).unwrap_err();
    assert!(
        matches!(
            e,
            LoadError::Csv {
                source: CsvError::Negative { line: 3, .. },
                ..
            }
        ),
        "{e:?}"
    );
    let msg = chain(&e);
    assert!(
        msg.contains(&p.display().to_string())
            && msg.contains("line 3, column b: negative BRDF value -0.25"),
        "{msg}"
    );

    // MERL: a negative stored value is the format's "not measured" (MERL's own files mark the
    // unmeasured cells so); such cells are skipped and counted in the description.
    let every = 7;
    let p = s.write(
        "some-negative.binary",
        &merl_bytes(|k| if k.is_multiple_of(every) { -1.0 } else { 0.5 }),
    );
    let d = job::load(&p, 1000).unwrap();
    assert!(d
        .samples
        .samples
        .iter()
        .all(|s| s.rgb.iter().all(|&v| v > 0.0)));
    assert!(
        d.description.contains("cells not measured"),
        "{}",
        d.description
    );
    let missing: usize = d
        .description
        .split("; ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{}", d.description));
    let expect = (0..merl::N_CELLS)
        .filter(|c| (0..3).any(|ch| (ch * merl::N_CELLS + c).is_multiple_of(every)))
        .count();
    assert_eq!(missing, expect, "{}", d.description);

    // Every value negative: nothing measured, refused naming the file.
    let p = s.write("all-negative.binary", &merl_bytes(|_| -1.0));
    let e = job::load(&p, 1000).unwrap_err();
    assert!(matches!(e, LoadError::NoMerlCells { .. }), "{e:?}");
    let msg = chain(&e);
    assert!(
        msg.starts_with(&format!("{}: no measured cells", p.display()))
            && msg.contains(&format!("{} missing", merl::N_CELLS)),
        "{msg}"
    );
}

#[test]
fn all_zero_sample_csv_is_refused() {
    let s = Scratch::new("zero");
    let mut text = format!("{HEADER}\n");
    for k in 0..300 {
        let t = 5 + (k * 7) % 70;
        text.push_str(&format!(
            "{t},{},{},{},0,0,0\n",
            (k * 37) % 360,
            (t * 3) % 80,
            (k * 37 + 180) % 360
        ));
    }
    let p = s.write("zero.csv", text.as_bytes());
    let e = job::load(&p, 0).unwrap_err();
    assert!(
        matches!(
            e,
            LoadError::Csv {
                source: CsvError::AllZero { samples: 300 },
                ..
            }
        ),
        "{e:?}"
    );
    let msg = chain(&e);
    assert!(
        msg.starts_with(&format!("{}: not a valid sample CSV", p.display()))
            && msg.contains("all 300 samples have r = g = b = 0"),
        "{msg}"
    );
    // One non-zero channel of one sample is data: accepted.
    let p = s.write(
        "almost-zero.csv",
        text.replacen(",0,0,0\n", ",0,0.01,0\n", 1).as_bytes(),
    );
    assert!(job::load(&p, 0).is_ok());
}

#[test]
fn all_zero_merl_table_is_refused() {
    let s = Scratch::new("zero-merl");
    let p = s.write("zero.binary", &merl_bytes(|_| 0.0));
    let e = job::load(&p, 2000).unwrap_err();
    assert!(matches!(e, LoadError::AllZero { .. }), "{e:?}");
    let msg = chain(&e);
    assert!(
        msg.starts_with(&format!("{}: every measured cell is 0", p.display())),
        "{msg}"
    );
    // One non-zero cell is data: accepted.
    let p = s.write(
        "one.binary",
        &merl_bytes(|k| if k == 90 * 180 * 10 + 5 { 1.0 } else { 0.0 }),
    );
    assert!(job::load(&p, 2000).is_ok());
}
