//! Tick placement: Heckbert's "nice numbers" for linear axes, decades for log axes, and
//! compact label formatting.

/// Ticks of a linear axis: evenly spaced nice values covering a data range.
#[derive(Debug, Clone, PartialEq)]
pub struct Ticks {
    /// Lower end of the axis (a multiple of `step`, ≤ the data minimum).
    pub min: f64,
    /// Upper end of the axis (a multiple of `step`, ≥ the data maximum).
    pub max: f64,
    /// Spacing of the ticks (1, 2 or 5 × 10^k).
    pub step: f64,
    /// The tick values from `min` to `max` inclusive.
    pub values: Vec<f64>,
}

/// A "nice" number near `x` > 0: 1, 2, 5 or 10 × 10^k; rounded to the nearest if `round`,
/// else the smallest nice number ≥ `x` (Heckbert, Graphics Gems I, 1990).
#[must_use]
pub fn nice_number(x: f64, round: bool) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return 1.0;
    }
    let e = x.log10().floor();
    let p = 10f64.powf(e);
    let f = x / p;
    let nf = if round {
        if f < 1.5 {
            1.0
        } else if f < 3.0 {
            2.0
        } else if f < 7.0 {
            5.0
        } else {
            10.0
        }
    } else if f <= 1.0 + 1e-9 {
        1.0
    } else if f <= 2.0 + 1e-9 {
        2.0
    } else if f <= 5.0 + 1e-9 {
        5.0
    } else {
        10.0
    };
    nf * p
}

/// Nice ticks covering `[lo, hi]` with about `target` intervals ("loose" labelling: the axis is
/// extended to the enclosing ticks). Degenerate or non-finite ranges are widened sensibly.
#[must_use]
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Ticks {
    let (mut lo, mut hi) = if lo.is_finite() && hi.is_finite() {
        (lo.min(hi), lo.max(hi))
    } else if lo.is_finite() {
        (lo, lo)
    } else if hi.is_finite() {
        (hi, hi)
    } else {
        (0.0, 1.0)
    };
    if hi - lo <= f64::EPSILON * hi.abs().max(lo.abs()).max(1e-300) {
        let d = if lo == 0.0 { 1.0 } else { 0.5 * lo.abs() };
        lo -= d;
        hi += d;
    }
    let n = target.max(2) as f64;
    let range = nice_number(hi - lo, false);
    let step = nice_number(range / n, true);
    let min = (lo / step + 1e-9).floor() * step;
    let max = (hi / step - 1e-9).ceil() * step;
    let count = ((max - min) / step).round() as usize;
    let values = (0..=count.min(1000))
        .map(|k| {
            let v = min + k as f64 * step;
            // Snap tiny round-off to zero so that labels read "0", not "-2.8e-17".
            if v.abs() < step * 1e-9 {
                0.0
            } else {
                v
            }
        })
        .collect();
    Ticks {
        min,
        max,
        step,
        values,
    }
}

/// Nice ticks strictly inside `[lo, hi]` (no axis extension), for a fixed range such as a
/// colour bar.
#[must_use]
pub fn ticks_within(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    let t = nice_ticks(lo, hi, target);
    let eps = t.step * 1e-6;
    t.values
        .into_iter()
        .filter(|v| *v >= lo.min(hi) - eps && *v <= hi.max(lo) + eps)
        .collect()
}

/// Decade ticks `10^k` for a positive range: the exponents `k` with `lo ≤ 10^k ≤ hi` after
/// extending the range to whole decades (`floor(log10 lo)..=ceil(log10 hi)`).
#[must_use]
pub fn log_decades(lo: f64, hi: f64) -> Vec<i32> {
    if !(lo > 0.0 && hi > 0.0 && lo.is_finite() && hi.is_finite()) {
        return vec![0];
    }
    let a = lo.min(hi).log10().floor() as i32;
    let b = lo.max(hi).log10().ceil() as i32;
    (a..=b.max(a + 1)).collect()
}

/// Label of a linear tick value given the tick `step`: just enough decimals to tell ticks apart,
/// scientific notation for very large or small magnitudes, and a true minus sign (U+2212).
#[must_use]
pub fn format_tick(v: f64, step: f64) -> String {
    if !v.is_finite() {
        return String::from("?");
    }
    if v == 0.0 {
        return String::from("0");
    }
    let step = if step.is_finite() && step > 0.0 {
        step
    } else {
        v.abs()
    };
    let s = if v.abs() >= 1e5 || step < 1e-4 {
        let e = v.abs().log10().floor() as i32;
        let mant = v / 10f64.powi(e);
        let digits = ((-(step / 10f64.powi(e)).log10()).ceil().max(0.0) as usize).min(6);
        format!("{mant:.digits$}e{e}")
    } else {
        let digits = ((-step.log10()).ceil().max(0.0) as usize).min(10);
        format!("{v:.digits$}")
    };
    s.replace('-', "\u{2212}")
}

/// Label of the decade `10^k`: plain for `-3 ≤ k ≤ 4` (`0.001` … `10000`), else `1e{k}`.
#[must_use]
pub fn format_decade(k: i32) -> String {
    let s = if (0..=4).contains(&k) {
        format!("{}", 10i64.pow(k as u32))
    } else if (-3..0).contains(&k) {
        format!("{:.*}", (-k) as usize, 10f64.powi(k))
    } else {
        format!("1e{k}")
    };
    s.replace('-', "\u{2212}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
    }

    #[test]
    fn nice_ticks_for_known_ranges() {
        let t = nice_ticks(0.0, 1.0, 5);
        assert!(close(&t.values, &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]), "{t:?}");
        let t = nice_ticks(0.0, 90.0, 6);
        assert_eq!(t.step, 20.0);
        assert!(close(&t.values, &[0.0, 20.0, 40.0, 60.0, 80.0, 100.0]));
        let t = nice_ticks(-3.7, 12.2, 5);
        assert_eq!(t.step, 5.0);
        assert!(close(&t.values, &[-5.0, 0.0, 5.0, 10.0, 15.0]));
        let t = nice_ticks(0.013, 0.087, 4);
        assert!((t.step - 0.02).abs() < 1e-12, "{t:?}");
        assert!((t.min - 0.0).abs() < 1e-12 && (t.max - 0.1).abs() < 1e-12);
        let t = nice_ticks(1234.0, 1290.0, 5);
        assert!((t.step - 20.0).abs() < 1e-9 && (t.min - 1220.0).abs() < 1e-9);
        assert!((t.max - 1300.0).abs() < 1e-9);
        // Degenerate and non-finite ranges still give usable axes.
        let t = nice_ticks(5.0, 5.0, 5);
        assert!(t.min < 5.0 && t.max > 5.0 && t.values.len() >= 2);
        let t = nice_ticks(f64::NAN, f64::INFINITY, 5);
        assert!(t.values.len() >= 2);
    }

    #[test]
    fn nice_numbers() {
        assert_eq!(nice_number(0.9, false), 1.0);
        assert_eq!(nice_number(1.1, false), 2.0);
        assert_eq!(nice_number(3.2, false), 5.0);
        assert_eq!(nice_number(7.0, false), 10.0);
        assert_eq!(nice_number(2.4, true), 2.0);
        assert_eq!(nice_number(45.0, true), 50.0);
    }

    #[test]
    fn labels() {
        assert_eq!(format_tick(0.2, 0.2), "0.2");
        assert_eq!(format_tick(20.0, 20.0), "20");
        assert_eq!(format_tick(-5.0, 5.0), "\u{2212}5");
        assert_eq!(format_tick(0.05, 0.025), "0.05");
        assert_eq!(format_tick(2.5e-5, 5e-6), "2.5e\u{2212}5");
        assert_eq!(format_tick(200000.0, 100000.0), "2e5");
        assert_eq!(format_decade(-2), "0.01");
        assert_eq!(format_decade(3), "1000");
        assert_eq!(format_decade(-6), "1e\u{2212}6");
        assert_eq!(log_decades(0.02, 300.0), vec![-2, -1, 0, 1, 2, 3]);
        assert!(close(&ticks_within(0.05, 0.95, 4), &[0.2, 0.4, 0.6, 0.8]));
    }
}
