//! Fast math for inner loops, written once for every kernel: branch-free, vectorisable, no libm
//! calls. f32 for the renderer's kernels ([`fast_pow`], [`fast_exp`], and their generic forms
//! with fused multiply-adds for builds with FMA), f64 for the pyramid's EM fit ([`fast_ln`],
//! [`fast_exp_neg`], ~1e-9). Each states its error and is tested against libm below.

/// `x^y` for `x ≥ 0`, `y ≥ 0` in f32 without libm calls (branch-free, vectorisable):
/// `exp2(y · log2 x)` with `log2` from the `atanh` series on the mantissa reduced to
/// `[√½, √2)` and `exp2` from a degree-7 polynomial on `[−½, ½]`. Relative error about
/// `1.5e-7 · (1 + |y log2 x|)` (the f32 rounding of the exponent dominates). `0^y = 0` for `y > 0` (up to a denormal-size value) and `x^0 = 1`.
#[inline(always)]
#[must_use]
pub fn fast_pow(x: f32, y: f32) -> f32 {
    fast_pow_impl::<false>(x, y)
}

/// `a·b + c`, fused when `FMA` (kernels compiled for AVX2 + FMA pass `true`).
#[inline(always)]
pub fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// `e^x` in f32 without libm calls (branch-free, vectorisable): [`fast_pow`]'s `exp2` on
/// `x·log2 e`; relative error about `1.5e-7 · (1 + |x|)`; 0 below `e^−87`.
#[inline(always)]
#[must_use]
pub fn fast_exp(x: f32) -> f32 {
    exp2_impl::<false>(x * std::f32::consts::LOG2_E)
}

/// `2^z` for `z` clamped to `[−126, 126]`: degree-7 polynomial on the fraction.
#[inline(always)]
pub fn exp2_impl<const FMA: bool>(z: f32) -> f32 {
    let z = z.clamp(-126.0, 126.0);
    // exp2(z) = 2^i · 2^f, i = round(z), f in [-1/2, 1/2]. Rounding by the 1.5·2^23 trick
    // (exact for |z| < 2^22) keeps the conversion in the vector registers.
    const MAGIC: f32 = 12_582_912.0;
    let t = z + MAGIC;
    let i = (t.to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    let f = z - (t - MAGIC);
    let mut q = 0.000_015_252_73;
    for c in [
        0.000_154_035_3,
        0.001_333_355_8,
        0.009_618_129,
        0.055_504_11,
        0.240_226_5,
        std::f32::consts::LN_2,
        1.0,
    ] {
        q = madd::<FMA>(q, f, c);
    }
    q * f32::from_bits(((i + 127) << 23) as u32)
}

/// [`fast_pow`], with fused multiply-adds in the polynomials when `FMA`.
#[inline(always)]
pub fn fast_pow_impl<const FMA: bool>(x: f32, y: f32) -> f32 {
    let x = x.max(1e-30);
    // log2 x = e + log2 m, m in [sqrt(1/2), sqrt(2)).
    let bits = x.to_bits() as i32;
    let mut e = ((bits >> 23) & 0xff) - 127;
    let mut mbits = (bits & 0x007f_ffff) | 0x3f80_0000;
    // If m >= sqrt 2, halve it and bump the exponent.
    let big = (mbits > 0x3fb5_04f3) as i32;
    e += big;
    mbits -= big << 23;
    let m = f32::from_bits(mbits as u32);
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    // 2/ln2 · (s + s³/3 + s⁵/5 + s⁷/7 + s⁹/9)
    let p = s * madd::<FMA>(
        s2,
        madd::<FMA>(
            s2,
            madd::<FMA>(s2, madd::<FMA>(s2, 0.320_598_9, 0.412_198_6), 0.577_078),
            0.961_796_7,
        ),
        2.885_39,
    );
    let l = e as f32 + p;
    exp2_impl::<FMA>(y * l)
}

/// `ln x` for finite `x > 0` to ~1e-9 absolute: exponent split, mantissa folded into
/// `[√½, √2)`, then the atanh series `2(s + s³/3 + … + s⁹/9)` with `s = (m−1)/(m+1)`. meso-maps' EM
/// spends most of its time in `ln` and `exp`; libm's full-precision versions are not needed.
#[inline]
pub fn fast_ln(x: f64) -> f64 {
    let bits = x.to_bits();
    let mut e = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let mut m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    if e == -1023 {
        // Subnormal: rare (x < 2.2e-308); fall back.
        return x.ln();
    }
    if m > std::f64::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let p = s * (2.0 + s2 * (2.0 / 3.0 + s2 * (0.4 + s2 * (2.0 / 7.0 + s2 * (2.0 / 9.0)))));
    e as f64 * std::f64::consts::LN_2 + p
}

/// `exp y` for `y ≤ 0` to ~1e-9 relative (0 below −700): `2^k · e^r`, `|r| ≤ ln2/2`, degree-8
/// Taylor polynomial for `e^r`.
#[inline]
pub fn fast_exp_neg(y: f64) -> f64 {
    if y < -700.0 {
        return 0.0;
    }
    // Nearest integer to y·log₂e (≤ 0) by truncation, one instruction (`round` is a libm call).
    let ki = (y * std::f64::consts::LOG2_E - 0.5) as i64;
    let k = ki as f64;
    let r = y - k * std::f64::consts::LN_2;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0
                            + r * (1.0 / 720.0 + r * (1.0 / 5040.0 + r * (1.0 / 40320.0))))))));
    p * f64::from_bits(((ki + 1023) as u64) << 52)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_pow_matches_powf() {
        for k in 0..2000 {
            let x = (k as f32 + 0.5) / 2000.0;
            for y in [0.0f32, 0.5, 1.0, 2.0, 7.3, 30.0, 100.0, 500.0] {
                let a = fast_pow(x, y);
                let b = x.powf(y);
                if b > 1e-30 {
                    let z = (y * x.log2()).abs();
                    assert!(
                        ((a - b) / b).abs() < 1.5e-7 * (1.0 + z) + 2e-7,
                        "{x}^{y}: {a} vs {b}"
                    );
                } else {
                    assert!(a < 1e-29);
                }
            }
        }
        // The fused variant (used by the AVX2 + FMA kernel) is as accurate.
        for k in 0..500 {
            let x = (k as f32 + 0.5) / 500.0;
            for y in [0.5f32, 7.3, 100.0] {
                let b = x.powf(y);
                if b > 1e-30 {
                    let z = (y * x.log2()).abs();
                    let a = fast_pow_impl::<true>(x, y);
                    assert!(((a - b) / b).abs() < 1.5e-7 * (1.0 + z) + 2e-7, "{x}^{y}");
                }
            }
        }
        assert!(fast_pow(0.0, 3.0) < 1e-30);
        assert_eq!(fast_pow(1.0, 123.0), 1.0);
    }

    #[test]
    fn fast_ln_and_exp_match_libm() {
        let mut x: f64 = 1e-300;
        while x < 1e3 {
            assert!(
                (fast_ln(x) - x.ln()).abs() < 1e-9 * (1.0 + x.ln().abs()),
                "ln {x}"
            );
            x *= 1.37;
        }
        let mut y: f64 = 0.0;
        while y > -745.0 {
            let e = y.exp();
            assert!((fast_exp_neg(y) - e).abs() <= 1e-9 * e + 1e-300, "exp {y}");
            y -= 0.173;
        }
    }
}
