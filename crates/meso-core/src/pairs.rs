//! The direction-pair CSV that `meso brdf` reads: header `theta_i,phi_i,theta_o,phi_o`, angles in
//! degrees in the material's local frame, both directions above the surface (θ ≤ 90°).

use crate::frame::spherical_direction_deg;
use glam::DVec3;

/// One query: incident and outgoing directions as given (degrees) and as unit vectors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionPair {
    /// `[theta_i, phi_i, theta_o, phi_o]` in degrees, as read.
    pub degrees: [f64; 4],
    /// Unit direction towards the light.
    pub i: DVec3,
    /// Unit direction towards the viewer.
    pub o: DVec3,
}

/// A problem in a pairs file, with its 1-based line number where it has one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct PairsError(pub String);

/// The header every pairs file starts with.
pub const PAIRS_HEADER: [&str; 4] = ["theta_i", "phi_i", "theta_o", "phi_o"];

/// Largest number of pairs accepted in one file.
pub const MAX_PAIRS: usize = 10_000_000;

/// Parse a pairs CSV. Blank lines are skipped; `#` starts a comment line.
///
/// # Errors
/// A missing or different header, wrong column counts, non-numbers, NaN/∞, θ outside [0, 90]°,
/// or more than [`MAX_PAIRS`] rows — each naming the line.
pub fn parse_pairs(text: &str) -> Result<Vec<DirectionPair>, PairsError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((hl, header)) = lines.next() else {
        return Err(PairsError(
            "the pairs file is empty (expected the header theta_i,phi_i,theta_o,phi_o)".into(),
        ));
    };
    let cols: Vec<&str> = header
        .trim()
        .trim_start_matches('\u{feff}')
        .split(',')
        .map(str::trim)
        .collect();
    if cols != PAIRS_HEADER {
        return Err(PairsError(format!(
            "line {}: expected the header theta_i,phi_i,theta_o,phi_o, got `{}`",
            hl + 1,
            header.trim().chars().take(80).collect::<String>()
        )));
    }
    let mut out = Vec::new();
    for (ln, line) in lines {
        if out.len() >= MAX_PAIRS {
            return Err(PairsError(format!(
                "more than {MAX_PAIRS} pairs: split the file"
            )));
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 4 {
            return Err(PairsError(format!(
                "line {}: expected 4 comma-separated numbers, got {} fields",
                ln + 1,
                fields.len()
            )));
        }
        let mut d = [0.0; 4];
        for (k, f) in fields.iter().enumerate() {
            let v: f64 = f.parse().map_err(|_| {
                PairsError(format!(
                    "line {}: {} = `{}` is not a number",
                    ln + 1,
                    PAIRS_HEADER[k],
                    f.chars().take(40).collect::<String>()
                ))
            })?;
            if !v.is_finite() {
                return Err(PairsError(format!(
                    "line {}: {} is {v} (must be finite)",
                    ln + 1,
                    PAIRS_HEADER[k]
                )));
            }
            d[k] = v;
        }
        for k in [0, 2] {
            if !(0.0..=90.0).contains(&d[k]) {
                return Err(PairsError(format!(
                    "line {}: {} = {} is outside [0, 90] degrees (both directions must be above the surface)",
                    ln + 1,
                    PAIRS_HEADER[k],
                    crate::display::Num(d[k])
                )));
            }
        }
        out.push(DirectionPair {
            degrees: d,
            i: spherical_direction_deg(d[0], d[1]),
            o: spherical_direction_deg(d[2], d[3]),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_rejects() {
        let p = parse_pairs("theta_i,phi_i,theta_o,phi_o\n30,0,30,180\n\n0, 0, 45, 90\n").unwrap();
        assert_eq!(p.len(), 2);
        assert!((p[0].i.z - 30f64.to_radians().cos()).abs() < 1e-12);
        for bad in [
            "",
            "a,b,c,d\n1,2,3,4",
            "theta_i,phi_i,theta_o,phi_o\n1,2,3",
            "theta_i,phi_i,theta_o,phi_o\n1,2,x,4",
            "theta_i,phi_i,theta_o,phi_o\nNaN,2,3,4",
            "theta_i,phi_i,theta_o,phi_o\n100,2,3,4",
            "theta_i,phi_i,theta_o,phi_o\n10,2,-3,4",
        ] {
            assert!(parse_pairs(bad).is_err(), "{bad:?}");
        }
    }
}
