//! A plain CSV of BRDF samples.
//!
//! # Format
//! ```text
//! theta_i,phi_i,theta_o,phi_o,r,g,b
//! 30,0,30,180,0.52,0.48,0.40
//! ```
//! * The first line is exactly the header `theta_i,phi_i,theta_o,phi_o,r,g,b` (spaces around
//!   names are allowed).
//! * Angles in **degrees** in meso's local frame (θ from the normal, φ from the tangent towards
//!   the bitangent; `i` towards the light, `o` towards the viewer); θ must lie in `[0, 90]`.
//! * `r,g,b` are BRDF values in 1/sr (without the cosine factor), finite and non-negative, and
//!   not all zero (a file whose every value is 0 measured nothing and is refused).
//! * Blank lines are skipped; every other line must have exactly seven numeric fields.
//!
//! Errors name the line (1-based) and the column.

use glam::DVec3;
use meso_core::frame::{rad_to_deg, spherical_angles, spherical_direction_deg};
use std::path::Path;

/// The required header line.
pub const CSV_HEADER: &str = "theta_i,phi_i,theta_o,phi_o,r,g,b";
const COLUMNS: [&str; 7] = ["theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b"];

/// One measured sample: a direction pair and its RGB BRDF value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CsvSample {
    /// θi in degrees.
    pub theta_i: f64,
    /// φi in degrees.
    pub phi_i: f64,
    /// θo in degrees.
    pub theta_o: f64,
    /// φo in degrees.
    pub phi_o: f64,
    /// BRDF in 1/sr, per channel.
    pub rgb: [f64; 3],
}

impl CsvSample {
    /// A sample from unit directions (local frame) and a value in 1/sr.
    #[must_use]
    pub fn from_dirs(wi: DVec3, wo: DVec3, rgb: [f64; 3]) -> CsvSample {
        let (ti, pi) = spherical_angles(wi);
        let (to, po) = spherical_angles(wo);
        CsvSample {
            theta_i: rad_to_deg(ti),
            phi_i: rad_to_deg(pi),
            theta_o: rad_to_deg(to),
            phi_o: rad_to_deg(po),
            rgb,
        }
    }

    /// The light direction `wi` (unit, local frame).
    #[must_use]
    pub fn wi(&self) -> DVec3 {
        spherical_direction_deg(self.theta_i, self.phi_i)
    }

    /// The view direction `wo` (unit, local frame).
    #[must_use]
    pub fn wo(&self) -> DVec3 {
        spherical_direction_deg(self.theta_o, self.phi_o)
    }
}

/// Errors reading or writing a sample CSV.
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    /// The file could not be read.
    #[error("cannot read sample file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file is empty (no header).
    #[error("sample file is empty: expected the header `{CSV_HEADER}`")]
    Empty,
    /// The file has a header but no samples.
    #[error("sample file has a header but no samples")]
    NoSamples,
    /// Every BRDF value (r, g, b of every sample) is 0: nothing was measured, nothing to fit.
    #[error("all {samples} samples have r = g = b = 0: no reflectance measured (a zeroed or placeholder file?)")]
    AllZero {
        /// Number of samples.
        samples: usize,
    },
    /// The first line is not the expected header.
    #[error("line 1: bad header `{found}`, expected `{CSV_HEADER}`")]
    BadHeader {
        /// The header found.
        found: String,
    },
    /// A line has the wrong number of fields.
    #[error("line {line}: {found} columns, expected 7 ({CSV_HEADER})")]
    ColumnCount {
        /// 1-based line number.
        line: usize,
        /// Number of fields found.
        found: usize,
    },
    /// A field is not a number.
    #[error("line {line}, column {column}: `{text}` is not a number")]
    NotANumber {
        /// 1-based line number.
        line: usize,
        /// Column name.
        column: &'static str,
        /// The field text.
        text: String,
    },
    /// A field is NaN or infinite.
    #[error("line {line}, column {column}: value is not finite")]
    NonFinite {
        /// 1-based line number.
        line: usize,
        /// Column name.
        column: &'static str,
    },
    /// A BRDF value is negative.
    #[error("line {line}, column {column}: negative BRDF value {value}")]
    Negative {
        /// 1-based line number.
        line: usize,
        /// Column name.
        column: &'static str,
        /// The value.
        value: f64,
    },
    /// A polar angle is outside `[0, 90]` degrees.
    #[error("line {line}, column {column}: polar angle {value}° outside [0, 90]")]
    BadTheta {
        /// 1-based line number.
        line: usize,
        /// Column name.
        column: &'static str,
        /// The value in degrees.
        value: f64,
    },
    /// Writing failed (nothing was left behind).
    #[error("cannot write sample file {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// Parse sample CSV text (see the module docs for the format).
pub fn parse_csv(text: &str) -> Result<Vec<CsvSample>, CsvError> {
    let mut lines = text.lines().enumerate();
    let header = loop {
        match lines.next() {
            None => return Err(CsvError::Empty),
            Some((_, l)) if l.trim().is_empty() => continue,
            Some((_, l)) => break l,
        }
    };
    let names: Vec<&str> = header.trim().split(',').map(str::trim).collect();
    if names != COLUMNS {
        return Err(CsvError::BadHeader {
            found: header.trim().to_string(),
        });
    }
    let mut out = Vec::new();
    for (k, l) in lines {
        let line = k + 1;
        if l.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = l.split(',').collect();
        if fields.len() != 7 {
            return Err(CsvError::ColumnCount {
                line,
                found: fields.len(),
            });
        }
        let mut v = [0.0; 7];
        for (j, f) in fields.iter().enumerate() {
            let t = f.trim();
            let x: f64 = t.parse().map_err(|_| CsvError::NotANumber {
                line,
                column: COLUMNS[j],
                text: t.to_string(),
            })?;
            if !x.is_finite() {
                return Err(CsvError::NonFinite {
                    line,
                    column: COLUMNS[j],
                });
            }
            if j >= 4 && x < 0.0 {
                return Err(CsvError::Negative {
                    line,
                    column: COLUMNS[j],
                    value: x,
                });
            }
            if (j == 0 || j == 2) && !(0.0..=90.0).contains(&x) {
                return Err(CsvError::BadTheta {
                    line,
                    column: COLUMNS[j],
                    value: x,
                });
            }
            v[j] = x;
        }
        out.push(CsvSample {
            theta_i: v[0],
            phi_i: v[1],
            theta_o: v[2],
            phi_o: v[3],
            rgb: [v[4], v[5], v[6]],
        });
    }
    if out.is_empty() {
        return Err(CsvError::NoSamples);
    }
    if out.iter().all(|s| s.rgb == [0.0; 3]) {
        return Err(CsvError::AllZero { samples: out.len() });
    }
    Ok(out)
}

/// Read a sample CSV file.
pub fn read_csv(path: &Path) -> Result<Vec<CsvSample>, CsvError> {
    meso_core::io::note_input(path);
    let text = std::fs::read_to_string(path).map_err(|source| CsvError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse_csv(&text)
}

/// Format samples as CSV text (header first; shortest round-trip decimal representation).
#[must_use]
pub fn format_csv(samples: &[CsvSample]) -> String {
    let mut s = String::with_capacity(64 * (samples.len() + 1));
    s.push_str(CSV_HEADER);
    s.push('\n');
    for x in samples {
        use std::fmt::Write;
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{}",
            x.theta_i, x.phi_i, x.theta_o, x.phi_o, x.rgb[0], x.rgb[1], x.rgb[2]
        );
    }
    s
}

/// Write samples to a CSV file atomically (nothing is left behind on error).
pub fn write_csv(path: &Path, samples: &[CsvSample]) -> Result<(), CsvError> {
    meso_core::io::write_atomic(path, format_csv(samples).as_bytes()).map_err(|source| {
        CsvError::Write {
            path: path.display().to_string(),
            source,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_text() {
        let s = vec![
            CsvSample {
                theta_i: 30.0,
                phi_i: 0.0,
                theta_o: 45.5,
                phi_o: 180.0,
                rgb: [0.1, 0.2, 1e-7],
            },
            CsvSample::from_dirs(
                spherical_direction_deg(10.0, 20.0),
                spherical_direction_deg(70.0, 300.0),
                [3.25, 0.0, 12.0],
            ),
        ];
        let back = parse_csv(&format_csv(&s)).unwrap();
        assert_eq!(back, s);
        assert!((back[1].wo() - spherical_direction_deg(70.0, 300.0)).length() < 1e-12);
    }

    #[test]
    fn errors_name_the_line() {
        let h = CSV_HEADER;
        let cases: Vec<(String, &str)> = vec![
            (String::new(), "empty"),
            ("\n  \n".into(), "empty"),
            (format!("{h}\n"), "no samples"),
            (
                "theta_i,phi_i,theta_o,phi_o,r,g\n1,2,3,4,5,6\n".into(),
                "bad header",
            ),
            (
                format!("{h}\n1,2,3,4,5,6,7\n1,2,3,4,5,6\n"),
                "line 3: 6 columns",
            ),
            (format!("{h}\n1,2,3,4,5,6,7,8\n"), "line 2: 8 columns"),
            (
                format!("{h}\n1,2,3,4,NaN,6,7\n"),
                "line 2, column r: value is not finite",
            ),
            (
                format!("{h}\n1,2,3,4,5,-6,7\n"),
                "line 2, column g: negative",
            ),
            (
                format!("{h}\n1,2,3,4,5,6,x\n"),
                "line 2, column b: `x` is not a number",
            ),
            (format!("{h}\n1,2,93,4,5,6,7\n"), "line 2, column theta_o"),
        ];
        for (text, want) in cases {
            let e = parse_csv(&text).unwrap_err().to_string();
            assert!(e.contains(want), "`{e}` should contain `{want}`");
        }
    }
}
