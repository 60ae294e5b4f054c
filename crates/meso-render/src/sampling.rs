//! Low-discrepancy sample generation and the warps the lights use.
//!
//! * [`PixelSampler`]: an Owen-scrambled Sobol sequence (Burley 2020, via `sobol_burley`), one
//!   independently scrambled sequence per pixel, dimension by dimension. Dimensions beyond the
//!   256 the table provides fall back to a hashed pseudo-random number.
//! * [`Distribution1D`] / [`Distribution2D`]: piecewise-constant distributions sampled by
//!   inverting the (marginal and conditional) CDFs; used for environment-map importance sampling.
//! * Cone and sphere warps with their densities (1/sr).

use glam::DVec3;
use std::f64::consts::PI;

/// The number of Sobol dimensions served by the table; later dimensions are hashed.
pub const SOBOL_DIMENSIONS: u32 = sobol_burley::NUM_DIMENSIONS;

/// The largest sample index the Sobol generator accepts (`2^16` samples per pixel).
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1 << 16;

/// A per-pixel stream of low-discrepancy numbers in `[0, 1)`.
#[derive(Clone, Copy, Debug)]
pub struct PixelSampler {
    seed: u32,
    index: u32,
    /// Dimensions 0–3 (pixel jitter and the first light), computed at once (see `eager`).
    first: [f32; 4],
    /// Whether `first` holds dimensions 0–3; a deferred sampler computes every dimension on
    /// demand (the same values), so pixels that need no random number pay nothing.
    eager: bool,
}

/// A 32-bit integer hash (Wellons' "lowbias32"), used to decorrelate pixels and dimensions.
#[inline]
#[must_use]
pub fn hash_u32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

impl PixelSampler {
    /// The sampler of pixel `(x, y)` for the image-wide `seed`, positioned at sample `index`
    /// (`index < 2^16`).
    #[inline]
    #[must_use]
    pub fn new(x: u32, y: u32, seed: u32, index: u32) -> PixelSampler {
        let s = hash_u32(x.wrapping_mul(0x9e37_79b9) ^ hash_u32(y ^ hash_u32(seed)));
        PixelSampler {
            seed: s,
            index,
            first: sobol_burley::sample_4d(index, 0, s),
            eager: true,
        }
    }

    /// Like [`PixelSampler::new`] but nothing is evaluated until asked for: the renderer's
    /// choice for one sample per pixel, where the pixel centre is used and point and
    /// directional lights need no random numbers. [`PixelSampler::get`] returns the same
    /// values as for [`PixelSampler::new`].
    #[inline]
    #[must_use]
    pub fn deferred(x: u32, y: u32, seed: u32, index: u32) -> PixelSampler {
        let s = hash_u32(x.wrapping_mul(0x9e37_79b9) ^ hash_u32(y ^ hash_u32(seed)));
        PixelSampler {
            seed: s,
            index,
            first: [0.0; 4],
            eager: false,
        }
    }

    /// The value of dimension `dim` for this sample, in `[0, 1)`.
    #[inline]
    #[must_use]
    pub fn get(&self, dim: u32) -> f64 {
        if dim < 4 && self.eager {
            f64::from(self.first[dim as usize])
        } else if dim < SOBOL_DIMENSIONS {
            f64::from(sobol_burley::sample(self.index, dim, self.seed))
        } else {
            let h = hash_u32(
                self.seed ^ hash_u32(dim.wrapping_mul(0x68e3_1da4) ^ hash_u32(self.index)),
            );
            f64::from(h >> 8) * (1.0 / (1u32 << 24) as f64)
        }
    }

    /// Two consecutive dimensions `dim, dim + 1`.
    #[inline]
    #[must_use]
    pub fn get2(&self, dim: u32) -> [f64; 2] {
        [self.get(dim), self.get(dim + 1)]
    }
}

/// A piecewise-constant 1-D distribution over `[0, 1)` with `n` equal cells.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f64>,
    cdf: Vec<f64>,
    integral: f64,
}

impl Distribution1D {
    /// Build from non-negative cell values (negative or non-finite values are treated as 0).
    /// If all values are 0 the distribution is uniform. `func` must not be empty.
    #[must_use]
    pub fn new(func: &[f64]) -> Distribution1D {
        let n = func.len().max(1);
        let func: Vec<f64> = if func.is_empty() {
            vec![1.0]
        } else {
            func.iter()
                .map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 })
                .collect()
        };
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut acc = 0.0;
        for &v in &func {
            acc += v / n as f64;
            cdf.push(acc);
        }
        let integral = acc;
        if integral > 0.0 {
            for c in &mut cdf[1..] {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n as f64;
            }
        }
        cdf[n] = 1.0;
        Distribution1D {
            func,
            cdf,
            integral,
        }
    }

    /// Number of cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always false (a distribution has at least one cell).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// The integral of the piecewise-constant function over `[0, 1)`.
    #[must_use]
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// The density (w.r.t. `[0,1)`) of cell `i`.
    #[inline]
    #[must_use]
    pub fn cell_pdf(&self, i: usize) -> f64 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    /// Sample `x ∈ [0,1)` for `u ∈ [0,1)`: returns `(x, pdf(x), cell index)`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: f64) -> (f64, f64, usize) {
        // Largest i with cdf[i] <= u.
        let n = self.func.len();
        let i = match self.cdf.partition_point(|&c| c <= u) {
            0 => 0,
            k => (k - 1).min(n - 1),
        };
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 1.0 - 1e-12)
        } else {
            0.5
        };
        let x = (i as f64 + du) / n as f64;
        (x, self.cell_pdf(i), i)
    }
}

/// A piecewise-constant 2-D distribution over `[0,1)²` (`nu` columns × `nv` rows), sampled as
/// the marginal over rows `v` followed by the conditional over columns `u`.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// Build from row-major values `func[v * nu + u]`.
    #[must_use]
    pub fn new(func: &[f64], nu: usize, nv: usize) -> Distribution2D {
        let conditional: Vec<Distribution1D> = (0..nv)
            .map(|v| Distribution1D::new(&func[v * nu..(v + 1) * nu]))
            .collect();
        let row_integrals: Vec<f64> = conditional.iter().map(|d| d.integral()).collect();
        Distribution2D {
            conditional,
            marginal: Distribution1D::new(&row_integrals),
        }
    }

    /// Sample a point `(u, v) ∈ [0,1)²` with its density w.r.t. area in `[0,1)²`.
    #[inline]
    #[must_use]
    pub fn sample(&self, r: [f64; 2]) -> ([f64; 2], f64) {
        let (v, pdf_v, iv) = self.marginal.sample(r[1]);
        let (u, pdf_u, _) = self.conditional[iv].sample(r[0]);
        ([u, v], pdf_u * pdf_v)
    }

    /// The density at `(u, v) ∈ [0,1)²`.
    #[inline]
    #[must_use]
    pub fn pdf(&self, uv: [f64; 2]) -> f64 {
        let nv = self.conditional.len();
        let nu = self.conditional[0].len();
        let iv = ((uv[1] * nv as f64) as usize).min(nv - 1);
        let iu = ((uv[0] * nu as f64) as usize).min(nu - 1);
        self.marginal.cell_pdf(iv) * self.conditional[iv].cell_pdf(iu)
    }
}

/// Uniformly sample a direction in the cone of half-angle `acos(cos_max)` around `+z`
/// (local coordinates). Density: `1 / (2π (1 − cos_max))` per steradian.
#[inline]
#[must_use]
pub fn sample_uniform_cone(u: [f64; 2], cos_max: f64) -> DVec3 {
    let cos_t = 1.0 - u[0] * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// The density (1/sr) of [`sample_uniform_cone`].
#[inline]
#[must_use]
pub fn uniform_cone_pdf(cos_max: f64) -> f64 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distribution_1d_inverts_its_cdf() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, 4.0]);
        assert!((d.integral() - 2.0).abs() < 1e-12);
        // Cell 1 has zero mass: never sampled.
        let mut counts = [0usize; 4];
        for k in 0..8000 {
            let (x, pdf, i) = d.sample((k as f64 + 0.5) / 8000.0);
            assert!((0.0..1.0).contains(&x));
            assert_eq!(i, (x * 4.0) as usize);
            assert!(pdf > 0.0);
            counts[i] += 1;
        }
        assert_eq!(counts[1], 0);
        assert_eq!(counts, [1000, 0, 3000, 4000]);
    }

    #[test]
    fn distribution_2d_pdf_matches_sampling_frequencies() {
        let (nu, nv) = (6, 4);
        let f: Vec<f64> = (0..nu * nv).map(|k| 1.0 + (k % 5) as f64).collect();
        let d = Distribution2D::new(&f, nu, nv);
        let total: f64 = f.iter().sum::<f64>() / (nu * nv) as f64;
        let n = 200_000;
        let mut counts = vec![0usize; nu * nv];
        let s = PixelSampler::new(3, 4, 5, 0);
        for k in 0..n {
            let r = [
                f64::from(sobol_burley::sample(k % 65536, 0, k / 65536 + 7)),
                f64::from(sobol_burley::sample(k % 65536, 1, k / 65536 + 7)),
            ];
            let (uv, pdf) = d.sample(r);
            let iu = (uv[0] * nu as f64) as usize;
            let iv = (uv[1] * nv as f64) as usize;
            assert!((pdf - d.pdf(uv)).abs() < 1e-9);
            assert!((pdf - f[iv * nu + iu] / total).abs() < 1e-9);
            counts[iv * nu + iu] += 1;
        }
        let _ = s.get(300); // the hashed fallback is in range
        let lazy = PixelSampler::deferred(3, 4, 5, 0);
        for dim in [0, 1, 2, 3, 4, 9, 300] {
            assert_eq!(lazy.get(dim), s.get(dim), "dimension {dim}");
        }
        assert!((0.0..1.0).contains(&s.get(300)));
        for (c, fv) in counts.iter().zip(&f) {
            let expect = n as f64 * fv / total / (nu * nv) as f64;
            assert!(
                ((*c as f64) - expect).abs() < 0.02 * expect,
                "{c} vs {expect}"
            );
        }
    }

    #[test]
    fn cone_samples_stay_in_the_cone() {
        let cos_max = 0.8;
        for k in 0..1000 {
            let u = [(k as f64 + 0.5) / 1000.0, ((k * 7) % 1000) as f64 / 1000.0];
            let w = sample_uniform_cone(u, cos_max);
            assert!((w.length() - 1.0).abs() < 1e-12 && w.z >= cos_max - 1e-12);
        }
        assert!((uniform_cone_pdf(-1.0) - 1.0 / (4.0 * PI)).abs() < 1e-15);
    }
}
