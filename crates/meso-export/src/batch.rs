//! The isotropic shaded GGX lobe of [`crate::ggx`] over a whole direction set at once.
//!
//! The pairs' geometry is kept as flat arrays (one per quantity), and the loops over the pairs
//! have no branches, so the compiler turns them into SIMD: 8 pairs per instruction with
//! AVX-512, 4 with AVX2, 2 with SSE2 (chosen at run time). Every lane does exactly the scalar
//! operations of the shaded lobe (`ggx::shaded_parts`, the same functions in the same order; Rust
//! never fuses a multiply and an add), and every sum over pairs or over fine texels is added in
//! the scalar code's order, so the results are the scalar code's bit for bit (unit tests below
//! compare them).
//!
//! Conventions are [`crate::ggx`]'s: unit directions in the tangent frame, α the GGX width, the
//! shaded lobe `s = f(l, v)·(n·l)` in 1/sr.

use crate::ggx::{cos_sin2, shaded_parts, AnisoGgx};
use glam::DVec3;
use std::f64::consts::PI;

/// What the shaded lobe about one normal `n` reads of each pair `(l, v)`, which does not depend
/// on the width: `n·l`, `n·v`, their squares and squared sines ([`cos_sin2`]), `(n·h)²`, and
/// whether the lobe can be non-zero there (1.0) or is 0 at every width (0.0: `l` or `v` below
/// the horizon of `n`, `n·h ≤ 0`, or no half vector).
///
/// Eight arrays of the pairs in one allocation: `nl, nv, nl2, sl2, nv2, sv2, cc, live`.
#[derive(Clone, Debug, Default)]
pub(crate) struct LobeGeometry {
    data: Vec<f64>,
    m: usize,
}

impl LobeGeometry {
    /// The geometry of the lobe about the unit normal `n` at every pair of `pairs` (as
    /// [`PairArrays`]).
    pub(crate) fn new(n: DVec3, pairs: &PairArrays) -> LobeGeometry {
        let m = pairs.len();
        let mut g = LobeGeometry {
            data: vec![0.0; 8 * m],
            m,
        };
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                unsafe { geometry_avx512(&mut g, n, pairs) };
                return g;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                unsafe { geometry_avx2(&mut g, n, pairs) };
                return g;
            }
        }
        geometry_lanes(&mut g, n, pairs);
        g
    }

    /// Number of pairs.
    pub(crate) fn len(&self) -> usize {
        self.m
    }

    /// The eight arrays `nl, nv, nl2, sl2, nv2, sv2, cc, live`, each cut to its first `m`
    /// pairs (`m ≤ len`).
    fn arrays(&self, m: usize) -> [&[f64]; 8] {
        split::<8>(&self.data, self.m).map(|a| &a[..m])
    }

    /// `out[i] = (target[i] − s_i(α))²` with `s_i(α)` the shaded lobe of width `alpha` at pair
    /// `i` (0 where it is dead), for the first `out.len()` pairs.
    pub(crate) fn squared_differences(&self, target: &[f64], alpha: f64, out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                unsafe { sq_diff_avx512(self, target, alpha, out) };
                return;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                unsafe { sq_diff_avx2(self, target, alpha, out) };
                return;
            }
        }
        sq_diff_lanes(self, target, alpha, out);
    }

    /// RMS difference (1/sr) between `target` and the lobe of width `alpha` over all pairs,
    /// `√(Σ (target − s)² / count)` summed in pair order (0 for no pairs); `scratch` is
    /// resized to the number of pairs.
    pub(crate) fn rms(&self, target: &[f64], alpha: f64, scratch: &mut Vec<f64>) -> f64 {
        let m = self.len();
        if m == 0 {
            return 0.0;
        }
        scratch.resize(m.min(target.len()), 0.0);
        self.squared_differences(target, alpha, scratch);
        let s: f64 = scratch.iter().sum();
        (s / m as f64).sqrt()
    }
}

/// The loop of [`LobeGeometry::new`], compiled for each instruction set.
#[inline(always)]
fn geometry_lanes(g: &mut LobeGeometry, n: DVec3, p: &PairArrays) {
    let m = g.m;
    let [lx, ly, lz, vx, vy, vz, hx, hy, hz] = p.components(m);
    let [gnl, gnv, nl2, sl2, nv2, sv2, cc, live] = split_mut::<8>(&mut g.data, m);
    for i in 0..m {
        // glam's `dot`: (n.x·w.x + n.y·w.y) + n.z·w.z.
        let nl = n.x * lx[i] + n.y * ly[i] + n.z * lz[i];
        let nv = n.x * vx[i] + n.y * vy[i] + n.z * vz[i];
        let c = n.x * hx[i] + n.y * hy[i] + n.z * hz[i];
        // A zero half vector gives c = 0: dead like a half vector below the horizon.
        let ok = nl > 0.0 && nv > 0.0 && c > 0.0;
        gnl[i] = nl;
        gnv[i] = nv;
        (nl2[i], sl2[i]) = cos_sin2(nl);
        (nv2[i], sv2[i]) = cos_sin2(nv);
        cc[i] = c * c;
        live[i] = if ok { 1.0 } else { 0.0 };
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn geometry_avx512(g: &mut LobeGeometry, n: DVec3, p: &PairArrays) {
    geometry_lanes(g, n, p);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn geometry_avx2(g: &mut LobeGeometry, n: DVec3, p: &PairArrays) {
    geometry_lanes(g, n, p);
}

/// Number of widths [`LobeGeometry::rms_of_widths`] evaluates at once.
pub(crate) const WIDTH_LANES: usize = 8;

impl LobeGeometry {
    /// [`LobeGeometry::rms`] at [`WIDTH_LANES`] widths at once (one width per lane; each
    /// width's sum over the pairs in pair order, as `rms` adds them).
    pub(crate) fn rms_of_widths(
        &self,
        target: &[f64],
        alphas: &[f64; WIDTH_LANES],
    ) -> [f64; WIDTH_LANES] {
        let m = self.len();
        if m == 0 {
            return [0.0; WIDTH_LANES];
        }
        let mut sums = [-0.0; WIDTH_LANES];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                unsafe { widths_avx512(self, target, alphas, &mut sums) };
            } else if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                unsafe { widths_avx2(self, target, alphas, &mut sums) };
            } else {
                widths_lanes(self, target, alphas, &mut sums);
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        widths_lanes(self, target, alphas, &mut sums);
        sums.map(|s| (s / m as f64).sqrt())
    }
}

/// The loop of [`LobeGeometry::rms_of_widths`]: `sums[j] += (target − s(α_j))²` pair by pair.
#[inline(always)]
fn widths_lanes(
    g: &LobeGeometry,
    target: &[f64],
    alphas: &[f64; WIDTH_LANES],
    sums: &mut [f64; WIDTH_LANES],
) {
    let m = g.len().min(target.len());
    let [nl, nv, nl2, sl2, nv2, sv2, cc, live] = g.arrays(m);
    let target = &target[..m];
    let a2: [f64; WIDTH_LANES] = alphas.map(|a| a * a);
    for i in 0..m {
        let (nl, nv, l2, v2, cc, live, t) = (
            nl[i],
            nv[i],
            (nl2[i], sl2[i]),
            (nv2[i], sv2[i]),
            cc[i],
            live[i],
            target[i],
        );
        for j in 0..WIDTH_LANES {
            let s = shaded_parts(nl, nv, l2, v2, cc, a2[j]);
            let s = if live != 0.0 { s } else { 0.0 };
            let d = t - s;
            sums[j] += d * d;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn widths_avx512(
    g: &LobeGeometry,
    target: &[f64],
    alphas: &[f64; WIDTH_LANES],
    sums: &mut [f64; WIDTH_LANES],
) {
    widths_lanes(g, target, alphas, sums);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn widths_avx2(
    g: &LobeGeometry,
    target: &[f64],
    alphas: &[f64; WIDTH_LANES],
    sums: &mut [f64; WIDTH_LANES],
) {
    widths_lanes(g, target, alphas, sums);
}

/// The loop of [`LobeGeometry::squared_differences`], compiled for each instruction set.
#[inline(always)]
fn sq_diff_lanes(g: &LobeGeometry, target: &[f64], alpha: f64, out: &mut [f64]) {
    let m = out.len();
    let [nl, nv, nl2, sl2, nv2, sv2, cc, live] = g.arrays(m);
    let t = &target[..m];
    let a2 = alpha * alpha;
    for i in 0..m {
        let s = shaded_parts(nl[i], nv[i], (nl2[i], sl2[i]), (nv2[i], sv2[i]), cc[i], a2);
        let s = if live[i] != 0.0 { s } else { 0.0 };
        let d = t[i] - s;
        out[i] = d * d;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn sq_diff_avx512(g: &LobeGeometry, target: &[f64], alpha: f64, out: &mut [f64]) {
    sq_diff_lanes(g, target, alpha, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sq_diff_avx2(g: &LobeGeometry, target: &[f64], alpha: f64, out: &mut [f64]) {
    sq_diff_lanes(g, target, alpha, out);
}

/// Direction pairs as flat arrays: the components of `l`, `v` and the half vector
/// `h = normalize(l + v)` (zero when `l = −v`), one array of the pairs per component, all in
/// one allocation (`lx, ly, lz, vx, vy, vz, hx, hy, hz`).
#[derive(Clone, Debug, Default)]
pub(crate) struct PairArrays {
    data: Vec<f64>,
    m: usize,
}

/// `K` consecutive arrays of `m` values at the start of `data`.
fn split<const K: usize>(data: &[f64], m: usize) -> [&[f64]; K] {
    std::array::from_fn(|k| &data[k * m..(k + 1) * m])
}

/// [`split`], mutable.
fn split_mut<const K: usize>(data: &mut [f64], m: usize) -> [&mut [f64]; K] {
    let mut rest = data;
    std::array::from_fn(|_| {
        let (a, b) = std::mem::take(&mut rest).split_at_mut(m);
        rest = b;
        a
    })
}

impl PairArrays {
    /// The arrays of `pairs`.
    pub(crate) fn new(pairs: &[(DVec3, DVec3)]) -> PairArrays {
        let m = pairs.len();
        let mut data = vec![0.0; 9 * m];
        for (i, &(l, v)) in pairs.iter().enumerate() {
            for (k, x) in [l.x, l.y, l.z, v.x, v.y, v.z].into_iter().enumerate() {
                data[k * m + i] = x;
            }
        }
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                unsafe { halves_avx512(&mut data, m) };
                return PairArrays { data, m };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                unsafe { halves_avx2(&mut data, m) };
                return PairArrays { data, m };
            }
        }
        halves_lanes(&mut data, m);
        PairArrays { data, m }
    }

    /// Number of pairs.
    pub(crate) fn len(&self) -> usize {
        self.m
    }

    /// The nine arrays `lx, ly, lz, vx, vy, vz, hx, hy, hz`, each cut to its first `m`
    /// pairs (`m ≤ len`).
    fn components(&self, m: usize) -> [&[f64]; 9] {
        split::<9>(&self.data, self.m).map(|a| &a[..m])
    }

    /// `acc[i] += s(n, α; l_i, v_i)`, the shaded lobe about the unit normal `n` of width
    /// `alpha` at every pair (0 below the horizons), for the first `acc.len()` pairs.
    pub(crate) fn accumulate_shaded(&self, n: DVec3, alpha: f64, acc: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                unsafe { acc_avx512(self, n, alpha, acc) };
                return;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                unsafe { acc_avx2(self, n, alpha, acc) };
                return;
            }
        }
        acc_lanes(self, n, alpha, acc);
    }
}

/// The half vectors of [`PairArrays::new`] from its `l` and `v` arrays: glam's
/// `(l + v).normalize_or_zero()` (`s · (1/√(s·s))`, zero where that factor is not finite and
/// positive), pair by pair in lanes.
#[inline(always)]
fn halves_lanes(data: &mut [f64], m: usize) {
    let (lv, h) = data.split_at_mut(6 * m);
    let [lx, ly, lz, vx, vy, vz] = split::<6>(lv, m);
    let [hx, hy, hz] = split_mut::<3>(h, m);
    for i in 0..m {
        let (x, y, z) = (lx[i] + vx[i], ly[i] + vy[i], lz[i] + vz[i]);
        let rcp = 1.0 / (x * x + y * y + z * z).sqrt();
        let ok = rcp.is_finite() && rcp > 0.0;
        hx[i] = if ok { x * rcp } else { 0.0 };
        hy[i] = if ok { y * rcp } else { 0.0 };
        hz[i] = if ok { z * rcp } else { 0.0 };
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn halves_avx512(data: &mut [f64], m: usize) {
    halves_lanes(data, m);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn halves_avx2(data: &mut [f64], m: usize) {
    halves_lanes(data, m);
}

/// The loop of [`PairArrays::accumulate_shaded`], compiled for each instruction set.
#[inline(always)]
fn acc_lanes(p: &PairArrays, n: DVec3, alpha: f64, acc: &mut [f64]) {
    let m = acc.len();
    let [lx, ly, lz, vx, vy, vz, hx, hy, hz] = p.components(m);
    let a2 = alpha * alpha;
    for i in 0..m {
        // glam's `dot`: (n.x·w.x + n.y·w.y) + n.z·w.z.
        let nl = n.x * lx[i] + n.y * ly[i] + n.z * lz[i];
        let nv = n.x * vx[i] + n.y * vy[i] + n.z * vz[i];
        let c = n.x * hx[i] + n.y * hy[i] + n.z * hz[i];
        let s = shaded_parts(nl, nv, cos_sin2(nl), cos_sin2(nv), c * c, a2);
        acc[i] += if nl > 0.0 && nv > 0.0 && c > 0.0 {
            s
        } else {
            0.0
        };
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn acc_avx512(p: &PairArrays, n: DVec3, alpha: f64, acc: &mut [f64]) {
    acc_lanes(p, n, alpha, acc);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn acc_avx2(p: &PairArrays, n: DVec3, alpha: f64, acc: &mut [f64]) {
    acc_lanes(p, n, alpha, acc);
}

/// What an anisotropic lobe about the unit normal `n` ([`AnisoGgx`]) reads of each pair that
/// does not depend on its widths or direction: the pairs as flat arrays, `n·l`, `n·v`, `n·h`,
/// their squares, `4 n·v`, and whether the lobe can be non-zero there (1.0; 0.0 as in
/// [`LobeGeometry`]).
#[derive(Clone, Debug)]
pub(crate) struct AnisoPairs {
    arrays: PairArrays,
    nl2: Vec<f64>,
    nv2: Vec<f64>,
    nh2: Vec<f64>,
    four_nv: Vec<f64>,
    live: Vec<f64>,
}

impl AnisoPairs {
    /// The pairs `pairs` for lobes about the unit normal `n`.
    pub(crate) fn new(n: DVec3, pairs: &[(DVec3, DVec3)]) -> AnisoPairs {
        let arrays = PairArrays::new(pairs);
        let m = pairs.len();
        let mut a = AnisoPairs {
            nl2: Vec::with_capacity(m),
            nv2: Vec::with_capacity(m),
            nh2: Vec::with_capacity(m),
            four_nv: Vec::with_capacity(m),
            live: Vec::with_capacity(m),
            arrays,
        };
        for &(l, v) in pairs {
            // The half vector as the arrays hold it (the same bits).
            let h = (l + v).normalize_or_zero();
            let (nl, nv, nh) = (n.dot(l), n.dot(v), n.dot(h));
            // A zero half vector gives n·h = 0: dead like one below the horizon.
            let ok = nl > 0.0 && nv > 0.0 && nh > 0.0;
            a.nl2.push(nl * nl);
            a.nv2.push(nv * nv);
            a.nh2.push(nh * nh);
            a.four_nv.push(if ok { 4.0 * nv } else { 1.0 });
            a.live.push(if ok { 1.0 } else { 0.0 });
        }
        a
    }

    /// Number of pairs.
    pub(crate) fn len(&self) -> usize {
        self.live.len()
    }

    /// `out[i] = s_i − target[i]` with `s_i` [`AnisoGgx::shaded`] of `lobe` (whose normal must
    /// be this set's `n`) at pair `i`, for the first `out.len()` pairs: its operations in its
    /// order, so the same bits.
    pub(crate) fn residuals(&self, lobe: &AnisoGgx, target: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                unsafe { aniso_avx512(self, lobe, target, out) };
                return;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                unsafe { aniso_avx2(self, lobe, target, out) };
                return;
            }
        }
        aniso_lanes(self, lobe, target, out);
    }
}

/// The loop of [`AnisoPairs::residuals`], compiled for each instruction set.
#[inline(always)]
fn aniso_lanes(p: &AnisoPairs, lobe: &AnisoGgx, target: &[f64], out: &mut [f64]) {
    let m = out.len();
    let a = &p.arrays;
    let [lx, ly, lz, vx, vy, vz, hx, hy, hz] = a.components(m);
    let (nl2, nv2, nh2) = (&p.nl2[..m], &p.nv2[..m], &p.nh2[..m]);
    let (fv, live, target) = (&p.four_nv[..m], &p.live[..m], &target[..m]);
    let (t, b) = (lobe.tangent, lobe.bitangent);
    let (at, ab) = (lobe.alpha_t, lobe.alpha_b);
    // `PI · α_t · α_b · q · q` is evaluated left to right: its first two products once.
    let k = PI * at * ab;
    for i in 0..m {
        // glam's `dot`: (u.x·w.x + u.y·w.y) + u.z·w.z.
        let tl = t.x * lx[i] + t.y * ly[i] + t.z * lz[i];
        let bl = b.x * lx[i] + b.y * ly[i] + b.z * lz[i];
        let tv = t.x * vx[i] + t.y * vy[i] + t.z * vz[i];
        let bv = b.x * vx[i] + b.y * vy[i] + b.z * vz[i];
        let th = t.x * hx[i] + t.y * hy[i] + t.z * hz[i];
        let bh = b.x * hx[i] + b.y * hy[i] + b.z * hz[i];
        // Λ(l), Λ(v) as `AnisoGgx::lambda`.
        let (x, y) = (at * tl, ab * bl);
        let lam_l = 0.5 * ((1.0 + (x * x + y * y) / nl2[i]).sqrt() - 1.0);
        let (x, y) = (at * tv, ab * bv);
        let lam_v = 0.5 * ((1.0 + (x * x + y * y) / nv2[i]).sqrt() - 1.0);
        let g2 = 1.0 / (1.0 + lam_l + lam_v);
        // D(h) as `AnisoGgx::d`.
        let (x, y) = (th / at, bh / ab);
        let q = x * x + y * y + nh2[i];
        let d = 1.0 / (k * q * q);
        let s = d * g2 / fv[i];
        let s = if live[i] != 0.0 { s } else { 0.0 };
        out[i] = s - target[i];
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn aniso_avx512(p: &AnisoPairs, lobe: &AnisoGgx, target: &[f64], out: &mut [f64]) {
    aniso_lanes(p, lobe, target, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn aniso_avx2(p: &AnisoPairs, lobe: &AnisoGgx, target: &[f64], out: &mut [f64]) {
    aniso_lanes(p, lobe, target, out);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ggx::{direction_pairs, shaded};
    use rand::RngExt;

    /// A normal, a width and a direction set.
    type Case = (DVec3, f64, Vec<(DVec3, DVec3)>);

    /// Random unit vectors, some below the horizon, and direction sets of several widths.
    fn cases() -> Vec<Case> {
        let mut rng = meso_testkit::rng(987_654_321);
        let mut rnd = move || rng.random::<f64>();
        let mut out = Vec::new();
        for k in 0..300 {
            let n = DVec3::new(rnd() - 0.5, rnd() - 0.5, 0.2 + rnd()).normalize();
            let width = 0.001 + 1.5 * rnd() * rnd();
            let alpha = 0.001 + rnd() * rnd();
            let mut pairs = direction_pairs(n, width);
            // Pairs the direction set never has: below the horizon, and l = −v (no half vector).
            if k % 3 == 0 {
                let l = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.7).normalize();
                let v = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.3).normalize();
                pairs.push((l, v));
                pairs.push((v, -v));
                pairs.push((n, n));
            }
            out.push((n, alpha, pairs));
        }
        out
    }

    /// The lanes give [`shaded`]'s values and squared differences bit for bit.
    #[test]
    fn lobe_geometry_matches_the_scalar_lobe_bit_for_bit() {
        for (n, alpha, pairs) in cases() {
            let g = LobeGeometry::new(n, &PairArrays::new(&pairs));
            let target: Vec<f64> = pairs
                .iter()
                .enumerate()
                .map(|(i, _)| 0.1 * i as f64)
                .collect();
            let mut out = vec![0.0; pairs.len()];
            g.squared_differences(&target, alpha, &mut out);
            for (i, &(l, v)) in pairs.iter().enumerate() {
                let d = target[i] - shaded(n, alpha, l, v);
                assert_eq!(out[i].to_bits(), (d * d).to_bits(), "pair {i}");
            }
            let mut scratch = Vec::new();
            let want = {
                let s: f64 = out.iter().sum();
                (s / out.len() as f64).sqrt()
            };
            assert_eq!(
                g.rms(&target, alpha, &mut scratch).to_bits(),
                want.to_bits()
            );
            // Eight widths at once: each the one-width RMS.
            let alphas: [f64; WIDTH_LANES] =
                std::array::from_fn(|j| alpha * (0.5 + 0.25 * j as f64));
            let many = g.rms_of_widths(&target, &alphas);
            let mut plain = [-0.0; WIDTH_LANES];
            widths_lanes(&g, &target, &alphas, &mut plain);
            for j in 0..WIDTH_LANES {
                let one = g.rms(&target, alphas[j], &mut scratch);
                assert_eq!(many[j].to_bits(), one.to_bits(), "width {}", alphas[j]);
                let sse2 = (plain[j] / pairs.len() as f64).sqrt();
                assert_eq!(sse2.to_bits(), one.to_bits(), "width {}", alphas[j]);
            }
        }
    }

    /// The anisotropic residuals are [`AnisoGgx::shaded`] minus the target bit for bit, for
    /// random widths (ratios up to 100) and directions, on the 45° direction sets and pairs
    /// below the horizon or without a half vector.
    #[test]
    fn aniso_residuals_match_the_scalar_lobe_bit_for_bit() {
        for (k, (n, alpha, mut pairs)) in cases().into_iter().enumerate() {
            pairs.extend(crate::ggx::direction_pairs_with(
                n,
                alpha,
                &crate::ggx::ANISO_HALF_PHIS_DEG,
            ));
            let lanes = AnisoPairs::new(n, &pairs);
            let target: Vec<f64> = (0..pairs.len()).map(|i| 0.01 * i as f64).collect();
            for j in 0..4 {
                let ratio = [1.0, 0.3, 0.05, 0.01][j];
                let psi = 0.7 * k as f64 + 1.3 * j as f64;
                let lobe = AnisoGgx::new(n, psi, alpha, (alpha * ratio).max(1e-3));
                let mut out = vec![0.0; pairs.len()];
                lanes.residuals(&lobe, &target, &mut out);
                let mut plain = vec![0.0; pairs.len()];
                aniso_lanes(&lanes, &lobe, &target, &mut plain);
                for (i, &(l, v)) in pairs.iter().enumerate() {
                    let want = lobe.shaded(l, v) - target[i];
                    assert_eq!(out[i].to_bits(), want.to_bits(), "case {k}, pair {i}");
                    assert_eq!(plain[i].to_bits(), want.to_bits(), "case {k}, pair {i}");
                }
            }
        }
    }

    /// Accumulating over normals gives the scalar sums bit for bit, and the SSE2 lanes agree
    /// with whatever instruction set the dispatch chose.
    #[test]
    fn accumulated_lobes_match_the_scalar_sums_bit_for_bit() {
        let cases = cases();
        for (k, (_, alpha, pairs)) in cases.iter().enumerate() {
            let p = PairArrays::new(pairs);
            assert_eq!(p.len(), pairs.len());
            let normals: Vec<DVec3> = cases[k..(k + 5).min(cases.len())]
                .iter()
                .map(|c| c.0)
                .collect();
            let mut acc = vec![0.0; pairs.len()];
            let mut plain = vec![0.0; pairs.len()];
            let mut want = vec![0.0; pairs.len()];
            for &n in &normals {
                p.accumulate_shaded(n, *alpha, &mut acc);
                acc_lanes(&p, n, *alpha, &mut plain);
                for (w, &(l, v)) in want.iter_mut().zip(pairs) {
                    *w += shaded(n, *alpha, l, v);
                }
            }
            for i in 0..pairs.len() {
                assert_eq!(acc[i].to_bits(), want[i].to_bits(), "case {k}, pair {i}");
                assert_eq!(plain[i].to_bits(), want[i].to_bits(), "case {k}, pair {i}");
            }
        }
    }
}
