//! Delta sums — the multiple surface of Eq. 3: `n(m) = Σ w_i δ(m − N_i)`, the limit η → ∞ of
//! Phong peaks. Weights are probabilities summing to 1. The density is singular, so integrals
//! against it are exact finite sums (Eq. 4 and Eq. 11); evaluation at a direction returns 0.

use glam::DVec3;

/// One normal of a multiple surface: a unit direction in the local frame and its weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WeightedNormal {
    /// Unit normal in the local frame.
    pub normal: DVec3,
    /// Probability weight (share of the surface area with this normal).
    pub weight: f64,
}

/// A multiple surface: a finite set of normals with probability weights.
#[derive(Clone, Debug, PartialEq)]
pub struct DeltaSum {
    normals: Vec<WeightedNormal>,
    cdf: Vec<f64>,
    /// `Σ w max(0, m_z)`: the projected area per unit microsurface area.
    projected_area: f64,
    /// Where the normals lie (built with them): lets sums over a cap of directions skip the
    /// rest ([`DeltaSum::for_each_in_cap`]).
    index: CapIndex,
}

/// Rows (in θ, over `[0, π]`) of the grid [`CapIndex`] sorts the normals into: 3° each.
const INDEX_ROWS: usize = 60;
/// Columns (in φ, over `[0, 2π)`) of the grid: 3° each.
const INDEX_COLS: usize = 120;
/// Sums with fewer normals than this keep no index (a scan is as fast).
const INDEX_MIN: usize = 256;

/// The normals' indices sorted by cell of a θ–φ grid (`INDEX_ROWS × INDEX_COLS`, row-major):
/// cell `c` holds `items[start[c]..start[c + 1]]`. Empty for small sums.
#[derive(Clone, Debug, Default, PartialEq)]
struct CapIndex {
    start: Vec<u32>,
    items: Vec<u32>,
}

/// The grid cell `(row, column)` of a unit direction.
fn index_cell(n: DVec3) -> (usize, usize) {
    let theta = n.z.clamp(-1.0, 1.0).acos();
    let phi = n.y.atan2(n.x).rem_euclid(std::f64::consts::TAU);
    let r = ((theta / std::f64::consts::PI * INDEX_ROWS as f64) as usize).min(INDEX_ROWS - 1);
    let c = ((phi / std::f64::consts::TAU * INDEX_COLS as f64) as usize).min(INDEX_COLS - 1);
    (r, c)
}

impl CapIndex {
    fn new(normals: &[WeightedNormal]) -> CapIndex {
        if normals.len() < INDEX_MIN {
            return CapIndex::default();
        }
        let cells: Vec<usize> = normals
            .iter()
            .map(|n| {
                let (r, c) = index_cell(n.normal);
                r * INDEX_COLS + c
            })
            .collect();
        let mut start = vec![0u32; INDEX_ROWS * INDEX_COLS + 1];
        for &c in &cells {
            start[c + 1] += 1;
        }
        for c in 0..INDEX_ROWS * INDEX_COLS {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; normals.len()];
        for (k, &c) in cells.iter().enumerate() {
            items[fill[c] as usize] = k as u32;
            fill[c] += 1;
        }
        CapIndex { start, items }
    }
}

impl DeltaSum {
    /// Build from weighted normals; weights are normalised to sum to 1, normals to unit length.
    ///
    /// # Errors
    /// Empty lists, negative / non-finite weights, zero total weight, invalid normals.
    pub fn new(normals: Vec<WeightedNormal>) -> Result<DeltaSum, crate::NdfError> {
        let normals = super::normalize_weights(normals, |n| n.weight, |n, w| n.weight = w)?;
        let mut out = Vec::with_capacity(normals.len());
        for (k, n) in normals.into_iter().enumerate() {
            let l = n.normal.length();
            if !(l.is_finite() && l > 1e-12) {
                return Err(crate::NdfError::Invalid(format!(
                    "normal {}: not a finite non-zero vector",
                    k + 1
                )));
            }
            out.push(WeightedNormal {
                normal: n.normal / l,
                weight: n.weight,
            });
        }
        let cdf = super::cumulative(out.iter().map(|n| n.weight));
        let index = CapIndex::new(&out);
        let projected_area = out.iter().map(|n| n.weight * n.normal.z.max(0.0)).sum();
        Ok(DeltaSum {
            normals: out,
            cdf,
            projected_area,
            index,
        })
    }

    /// The single normal of a plain surface, +z.
    #[must_use]
    pub fn surface_normal() -> DeltaSum {
        DeltaSum::new(vec![WeightedNormal {
            normal: DVec3::Z,
            weight: 1.0,
        }])
        .expect("one unit normal is valid")
    }

    /// The weighted normals (weights sum to 1).
    #[must_use]
    pub fn normals(&self) -> &[WeightedNormal] {
        &self.normals
    }

    /// `∫_{z>0} n(m) (m·z) dω = Σ w_k max(0, m_k·z)`: the projected area of the microsurface
    /// per unit of its area (computed once, with the sum).
    #[must_use]
    pub fn projected_area(&self) -> f64 {
        self.projected_area
    }

    /// Call `f(k)` for every normal `k` within the cap `normal · axis ≥ cos_radius` (`axis` a
    /// unit vector), in no particular order, each once. Normals outside the cap may be visited
    /// too (the cap is covered by grid cells); callers that need the exact cap test it.
    /// Large sums visit only the grid cells that meet the cap's bounding box in (θ, φ).
    pub fn for_each_in_cap(&self, axis: DVec3, cos_radius: f64, mut f: impl FnMut(usize)) {
        use std::f64::consts::{PI, TAU};
        if self.index.start.is_empty() || cos_radius <= -1.0 {
            (0..self.normals.len()).for_each(f);
            return;
        }
        let r = cos_radius.clamp(-1.0, 1.0).acos() + 1e-9;
        let theta_a = axis.z.clamp(-1.0, 1.0).acos();
        let (t0, t1) = (theta_a - r, theta_a + r);
        let row = |t: f64| {
            ((t / PI * INDEX_ROWS as f64).floor() as isize).clamp(0, INDEX_ROWS as isize - 1)
                as usize
        };
        let (r0, r1) = (row(t0.max(0.0)), row(t1.min(PI)));
        // A cap around a pole covers every azimuth; otherwise its azimuths lie within
        // asin(sin r / sin θ_a) of the axis's.
        let all_phi = t0 <= 0.0 || t1 >= PI || r >= 0.5 * PI;
        let (c0, span) = if all_phi {
            (0isize, INDEX_COLS as isize)
        } else {
            let dphi = (r.sin() / theta_a.sin()).clamp(-1.0, 1.0).asin();
            let phi_a = axis.y.atan2(axis.x);
            let scale = INDEX_COLS as f64 / TAU;
            let lo = ((phi_a - dphi) * scale).floor() as isize;
            let hi = ((phi_a + dphi) * scale).floor() as isize;
            (lo, (hi - lo + 1).min(INDEX_COLS as isize))
        };
        let cols = INDEX_COLS as isize;
        for rr in r0..=r1 {
            for c in c0..c0 + span {
                let cell = rr * INDEX_COLS + c.rem_euclid(cols) as usize;
                let (a, b) = (
                    self.index.start[cell] as usize,
                    self.index.start[cell + 1] as usize,
                );
                for &k in &self.index.items[a..b] {
                    f(k as usize);
                }
            }
        }
    }

    /// Choose one of the normals with probability equal to its weight.
    #[must_use]
    pub fn sample(&self, u: f64) -> DVec3 {
        self.normals[super::pick(&self.cdf, u).0].normal
    }
}
