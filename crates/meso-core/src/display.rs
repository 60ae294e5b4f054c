//! Numbers in messages: [`Num`] prints very large and very small values in exponent notation,
//! so an error about `1e308` says `1e308`, not a 309-digit number.

/// An `f64` for error messages and reports: the shortest round-trip form, in exponent notation
/// (`1e308`, `2.5e-9`) when the magnitude is at least 1e9 or below 1e-6, plain otherwise
/// (`0.25`, `40`); `NaN`, `inf` and `-inf` as Rust prints them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num(pub f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let a = self.0.abs();
        if self.0.is_finite() && a != 0.0 && !(1e-6..1e9).contains(&a) {
            write!(f, "{:e}", self.0)
        } else {
            write!(f, "{}", self.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Num;

    #[test]
    fn item12_huge_and_tiny_numbers_print_short() {
        assert_eq!(Num(1e308).to_string(), "1e308");
        assert_eq!(Num(-1.5e300).to_string(), "-1.5e300");
        assert_eq!(Num(2.5e-9).to_string(), "2.5e-9");
        assert_eq!(
            Num(f64::MAX).to_string().len(),
            "1.7976931348623157e308".len()
        );
        assert_eq!(Num(0.25).to_string(), "0.25");
        assert_eq!(Num(40.0).to_string(), "40");
        assert_eq!(Num(1e7).to_string(), "10000000");
        assert_eq!(Num(0.0).to_string(), "0");
        assert_eq!(Num(f64::NAN).to_string(), "NaN");
        assert_eq!(Num(f64::INFINITY).to_string(), "inf");
    }
}
