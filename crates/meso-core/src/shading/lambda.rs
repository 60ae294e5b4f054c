//! Smith `Λ` of a compiled mirror-facet plan: in closed form for Beckmann and GGX and their
//! mixtures, per-lobe 1-D tables for tilted Phong peaks above the horizon, and a table of the
//! projected area otherwise (built once per material, Catmull–Rom between its nodes).

use super::*;

/// Smith Λ of a mirror-facet material's NDF: closed form for Beckmann and GGX and their
/// mixtures, else tabulated.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Lambda {
    Closed(crate::ndf::microfacet::Microfacet),
    ClosedMixture(crate::ndf::Mixture),
    Table(LambdaTable),
    Lobes(LobeLambda),
}

impl Lambda {
    pub(super) fn lookup(&self, w: DVec3) -> f64 {
        match self {
            Lambda::Closed(mf) => mf.lambda(w),
            Lambda::ClosedMixture(mx) => mx.lambda(w),
            Lambda::Table(t) => t.lookup(w),
            Lambda::Lobes(l) => l.lookup(w),
        }
    }
}

/// Mass of a Phong peak below the horizon above which [`LobeLambda`] does not apply.
const LOBE_HORIZON_MASS: f64 = 1e-4;

/// Nodes of each lobe's table in [`LobeLambda`] (in `t ∈ [−1, 1]`, `u = t|t|`).
const LOBE_NODES: usize = 257;

/// Smith Λ of Phong peaks with (almost) no mass below the horizon — tilted lobes, e.g. `meso
/// fit` with free axes: the projected area towards ω is the sum of the lobes' own, each a
/// function of `ω·axis` alone, `a(ω) = Σ w_k I_k(ω·a_k) / P`, `P = Σ w_k I_k(a_k·z)`, with
/// `I_k` the 1-D rule over the whole sphere about the lobe's axis
/// ([`crate::convolution::axial_projected_area`]) tabulated at `u = t|t|` (dense about 0, where a
/// sharp lobe's `I_k` bends) and read by Catmull–Rom. Exact but for the lobes' mass below the
/// horizon (≤ [`LOBE_HORIZON_MASS`] each, `cos^{η+2}(β/2)` for a lobe whose axis is `β` above
/// it), which the quadrature does not count. A lobe whose axis is the normal is symmetric about
/// it, so its table is the same rule over the upper hemisphere only: exact however much of it the
/// horizon cuts (a broad sheen lobe at the normal beside sharp tilted ones, the editor's satin).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct LobeLambda {
    /// Per lobe: axis, `w_k / P`, and `I_k` at the nodes.
    lobes: Vec<(DVec3, f64, Vec<f64>)>,
    /// `P`, the projected area towards the normal.
    pub(super) projected_area: f64,
}

impl LobeLambda {
    /// The tables of `lobes`, or `None` when a lobe not at the normal reaches below the horizon.
    pub(super) fn new(lobes: &[PhongLobe]) -> Option<LobeLambda> {
        let mut out = Vec::new();
        for l in lobes.iter().filter(|l| l.weight > 0.0) {
            // At the normal: the horizon is the lobe's own equator, cut exactly by the rule.
            let upright = l.axis.z >= 1.0 - 1e-12;
            let beta = std::f64::consts::FRAC_PI_2 - l.axis.z.clamp(-1.0, 1.0).acos();
            if !upright
                && (beta <= 0.0 || (0.5 * beta).cos().powf(l.exponent + 2.0) > LOBE_HORIZON_MASS)
            {
                return None;
            }
            let norm = PhongLobe::normalization(l.exponent);
            let density = |t: f64| norm * (0.5 * t).cos().max(0.0).powf(l.exponent);
            let table: Vec<f64> = (0..LOBE_NODES)
                .into_par_iter()
                .map(|j| {
                    let t = -1.0 + 2.0 * j as f64 / (LOBE_NODES - 1) as f64;
                    crate::convolution::axial_projected_area(density, t * t.abs(), !upright)
                })
                .collect();
            out.push((l.axis, l.weight, table));
        }
        let mut lambda = LobeLambda {
            lobes: out,
            projected_area: 1.0,
        };
        let p: f64 = lambda
            .lobes
            .iter()
            .map(|(a, w, t)| w * Self::read(t, a.z))
            .sum();
        if p <= 0.0 {
            return None;
        }
        lambda.lobes.iter_mut().for_each(|l| l.1 /= p);
        lambda.projected_area = p;
        Some(lambda)
    }

    /// `I_k(u)` from its table.
    fn read(table: &[f64], u: f64) -> f64 {
        let t = u.signum() * u.abs().sqrt();
        let last = LOBE_NODES - 1;
        let f = ((t + 1.0) * 0.5 * last as f64).clamp(0.0, last as f64);
        let j = (f as usize).min(last - 1);
        catmull_rom_at(|k| table[k], last, j, f - j as f64)
    }

    pub(super) fn lookup(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        let a: f64 = self
            .lobes
            .iter()
            .map(|(axis, w_p, t)| w_p * Self::read(t, w.dot(*axis)))
            .sum();
        (a / w.z - 1.0).max(0.0)
    }
}

/// Smith Λ of an NDF without a closed form, from a table of the relative projected area
/// `a(ω)` ([`SmithMasking::relative_projected_area`]) so that `Λ = a/cos θ − 1`: `a` is smooth
/// up to the horizon where `Λ` is not. What is tabulated is its excess over its linear part,
/// `r(ω) = a(ω) − ω·c` (`c` the [`SmithMasking::mean_normal`]), which is 0 wherever no facet
/// faces away from `ω` (so the table is exact there) and ≥ 0 near grazing. Nodes at
/// `cos θ = t²`, `t` uniform on `[0, 1]` (both ends included; dense near grazing, where a sharp
/// NDF's `r` bends over a small angle), and uniform in φ unless the NDF is isotropic
/// ([`Ndf::is_isotropic`]: one column, computed by the 1-D rule; a tabulated NDF's nodes are
/// exact, [`crate::ndf::tabulated::ProjectedAreas`]). Catmull–Rom in `t`, linear
/// in φ. Error against the quadrature: [`LAMBDA_TABLE_TOLERANCE`] (tested on sharp and tilted
/// lobes).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct LambdaTable {
    /// The linear part `c` of `a(ω)`.
    mean_normal: DVec3,
    /// Rows in `t = √cos θ`.
    n_t: usize,
    /// Columns in φ (1 for an isotropic NDF).
    n_phi: usize,
    /// `r(ω)` row-major, `n_t × n_phi`.
    values: Vec<f64>,
}

/// Rows of [`LambdaTable`] in `t = √cos θ`.
const LAMBDA_ROWS: usize = 97;
/// Columns of [`LambdaTable`] in φ for an anisotropic NDF.
const LAMBDA_COLUMNS: usize = 64;

/// The largest relative error of `G₂ = 1/(1 + Λ(i) + Λ(o))` from the plan's Λ table against the
/// quadrature that the tests allow for an isotropic NDF (`meso fit`'s lobes on the normal;
/// measured: docs/benchmarks.md "meso brdf").
pub const LAMBDA_TABLE_TOLERANCE: f64 = 2e-4;

/// [`LAMBDA_TABLE_TOLERANCE`] for tilted Phong peaks above the horizon, by per-lobe tables
/// (`LobeLambda`; measured 5.5e-4 on lobes tilted 10° and 25°, the part of the η = 60 lobe below
/// the horizon, 2.6e-5 of it, being what the quadrature does not count).
pub const LAMBDA_LOBES_TOLERANCE: f64 = 1e-3;

/// [`LAMBDA_TABLE_TOLERANCE`] for other anisotropic NDFs (lobes reaching below the horizon): the 97 × 64 table's
/// interpolation near grazing (measured 5e-3 at cos θ ≈ 0.02 on lobes tilted 10° and 25°).
pub const LAMBDA_TABLE_TOLERANCE_ANISOTROPIC: f64 = 1e-2;

impl LambdaTable {
    pub(super) fn new(m: &SmithMasking<'_>, isotropic: bool) -> LambdaTable {
        let (n_t, n_phi) = (LAMBDA_ROWS, if isotropic { 1 } else { LAMBDA_COLUMNS });
        let c = m.mean_normal();
        let node = |k: usize| {
            let (a, b) = (k / n_phi, k % n_phi);
            let t = a as f64 / (n_t - 1) as f64;
            let u = t * t;
            let phi = 2.0 * PI * b as f64 / n_phi as f64;
            let s = (1.0 - u * u).max(0.0).sqrt();
            let w = DVec3::new(s * phi.cos(), s * phi.sin(), u);
            m.relative_projected_area(w) - w.dot(c)
        };
        let values = (0..n_t * n_phi).into_par_iter().map(node).collect();
        LambdaTable {
            mean_normal: c,
            n_t,
            n_phi,
            values,
        }
    }

    pub(super) fn lookup(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        let last = self.n_t - 1;
        let ft = (w.z.min(1.0).sqrt() * last as f64).min(last as f64);
        let a0 = (ft as usize).min(last - 1);
        let ta = ft - a0 as f64;
        // Catmull–Rom in t through rows a0 − 1 … a0 + 2.
        let col = |b: usize| catmull_rom_at(|a| self.values[a * self.n_phi + b], last, a0, ta);
        let r = if self.n_phi == 1 {
            col(0)
        } else {
            let mut phi = w.y.atan2(w.x);
            if phi < 0.0 {
                phi += 2.0 * PI;
            }
            let p = phi / (2.0 * PI) * self.n_phi as f64;
            let b0 = (p as usize) % self.n_phi;
            let b1 = (b0 + 1) % self.n_phi;
            let tb = p - p.floor();
            col(b0) * (1.0 - tb) + col(b1) * tb
        };
        ((r + w.dot(self.mean_normal)) / w.z - 1.0).max(0.0)
    }
}

/// The Catmull–Rom cubic through nodes `j − 1 … j + 2` of `v` (nodes `0..=last`, extended
/// linearly past the ends) at `t ∈ [0, 1]` between nodes `j` and `j + 1`.
#[inline]
fn catmull_rom_at(v: impl Fn(usize) -> f64, last: usize, j: usize, t: f64) -> f64 {
    let (v1, v2) = (v(j), v(j + 1));
    let v0 = if j > 0 { v(j - 1) } else { 2.0 * v1 - v2 };
    let v3 = if j + 2 <= last {
        v(j + 2)
    } else {
        2.0 * v2 - v1
    };
    catmull_rom([v0, v1, v2, v3], t)
}

/// The Catmull–Rom cubic through `v[0..4]` at `t ∈ [0, 1]` between `v[1]` and `v[2]`.
#[inline]
fn catmull_rom(v: [f64; 4], t: f64) -> f64 {
    let (t2, t3) = (t * t, t * t * t);
    0.5 * ((2.0 * v[1])
        + (v[2] - v[0]) * t
        + (2.0 * v[0] - 5.0 * v[1] + 4.0 * v[2] - v[3]) * t2
        + (3.0 * v[1] - v[0] - 3.0 * v[2] + v[3]) * t3)
}
