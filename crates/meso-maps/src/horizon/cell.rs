//! [`CellHorizon`]: the horizons of one cell of a height map (a pyramid's level-0 texel) kept
//! point by point, so that what of the cell sees the light and what sees the viewer are found
//! together, not as two fractions multiplied.
//!
//! A [`HorizonCdf`] keeps of a footprint, per azimuth, only the fraction of it under each
//! elevation; which points those are is lost, and two directions far apart in azimuth can only
//! be combined as if independent (or through a [`super::HorizonJoint`], whose grid of four
//! elevations is too coarse for one cell: there its copula is the product). On one cell the
//! points are at hand: the four corner samples' angles interpolated bilinearly, the very model
//! [`HorizonCdfSum::of_bilinear_cell`] counts on 4 × 4 sub-cells. So a cell keeps its corners
//! and reads each sub-cell's visibility of both directions.
//!
//! Measured (2026-12-07, facade height map 256², height 20, view 45° from −y, light 69° from
//! the normal, blocks of 4 × 6 cells as a pixel of 4 cells seen at 45°; the mean over blocks of
//! the Lambert radiance weighted by the seen area, against rays on the displaced surface): the
//! cells' distributions multiplied 0.80 / 0.55 / 0.77 of the truth at light azimuths 0° / 45° /
//! 135°, the sub-cells together 0.98 / 0.81 / 0.93 (docs/heightmaps.md, "One cell, light and
//! viewer together").

use super::{
    bilinear_points, HorizonCdf, HorizonCdfSum, HorizonDirection, HorizonPair, HORIZON_DIRECTIONS,
};

/// Sub-cells a side (the points of [`HorizonCdfSum::of_bilinear_cell`]).
const SUB: usize = 4;

/// Points a cell is read at: its `SUB × SUB` sub-cells.
const POINTS: usize = SUB * SUB;

/// The horizons of one cell of a height map: per stored azimuth (the order of
/// [`super::HORIZON_AZIMUTHS_DEG`]) the horizon angles (radians) of its four corner samples, at
/// `(x, y)` = (0, 0), (1, 0), (0, 1), (1, 1) of the cell, read bilinearly in between (128
/// bytes, as a [`HorizonCdf`]). Each of its 4 × 4 sub-cells sees an elevation over the part of
/// it whose angle lies below (the angle taken linear across the sub-cell, within the corners'
/// range), so the fractions move continuously with the direction; a direction between two
/// stored azimuths weights their fractions as [`HorizonCdf::visibility_along`] does.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CellHorizon {
    /// Per stored azimuth, the corners' angles (radians).
    pub corners: [[f32; 4]; HORIZON_DIRECTIONS],
}

/// What a cell's sub-cells see of one direction: all alike, or each its own fraction.
#[derive(Clone, Copy, Debug)]
enum Seen {
    Uniform(f64),
    Points([f64; POINTS]),
}

impl Seen {
    fn mean(&self) -> f64 {
        match self {
            Seen::Uniform(v) => *v,
            Seen::Points(p) => p.iter().sum::<f64>() / POINTS as f64,
        }
    }

    fn at(&self, k: usize) -> f64 {
        match self {
            Seen::Uniform(v) => *v,
            Seen::Points(p) => p[k],
        }
    }

    /// The fraction seeing both of two directions seen as `a` and `b`: per sub-cell the
    /// smaller of the two fractions, averaged.
    fn both(a: &Seen, b: &Seen) -> f64 {
        match (a, b) {
            (Seen::Uniform(x), Seen::Uniform(y)) => x.min(*y),
            _ => (0..POINTS).map(|k| a.at(k).min(b.at(k))).sum::<f64>() / POINTS as f64,
        }
    }

    /// `a · self + b · other`, point by point.
    fn mix(self, a: f64, other: Seen, b: f64) -> Seen {
        match (self, other) {
            (Seen::Uniform(x), Seen::Uniform(y)) => Seen::Uniform(a * x + b * y),
            (x, y) => Seen::Points(std::array::from_fn(|k| a * x.at(k) + b * y.at(k))),
        }
    }
}

impl CellHorizon {
    /// A cell of corner angles `corners[d]` (radians, per stored azimuth `d`, at `(x, y)` =
    /// (0, 0), (1, 0), (0, 1), (1, 1)).
    #[must_use]
    pub fn new(corners: &[[f64; 4]; HORIZON_DIRECTIONS]) -> CellHorizon {
        CellHorizon {
            corners: corners.map(|a| a.map(|x| x as f32)),
        }
    }

    /// The cell's horizon distribution ([`HorizonCdfSum::of_bilinear_cell`] of its corners,
    /// weight 1): what a coarser texel pools of it.
    #[must_use]
    pub fn cdf(&self) -> HorizonCdf {
        HorizonCdfSum::of_bilinear_cell(&self.corners.map(|a| a.map(f64::from)), 1.0).finish()
    }

    /// Per sub-cell, the fraction of it whose horizon along stored azimuth `slot` lies at or
    /// below elevation `e` (radians).
    fn seen_along(&self, slot: usize, e: f64) -> Seen {
        let a = self.corners[slot].map(f64::from);
        let lo = a.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        // Every point's angle lies within the corners' range.
        if e >= hi {
            return Seen::Uniform(1.0);
        }
        if e < lo {
            return Seen::Uniform(0.0);
        }
        let step = 1.0 / SUB as f64;
        // The sub-cells' centres' angles, as the cell's distribution counts them.
        let mids = bilinear_points(&a);
        Seen::Points(std::array::from_fn(|k| {
            let (x, y) = (
                (k % SUB) as f64 * step + 0.5 * step,
                (k / SUB) as f64 * step + 0.5 * step,
            );
            let mid = mids[k];
            // The angle's gradient at the centre; across the sub-cell it spans ± half of
            // (|∂x| + |∂y|) times the side.
            let gx = (a[1] - a[0]) * (1.0 - y) + (a[3] - a[2]) * y;
            let gy = (a[2] - a[0]) * (1.0 - x) + (a[3] - a[1]) * x;
            let half = 0.5 * step * (gx.abs() + gy.abs());
            let (l, h) = ((mid - half).max(lo), (mid + half).min(hi));
            if h - l > 1e-9 {
                ((e - l) / (h - l)).clamp(0.0, 1.0)
            } else {
                f64::from(u8::from(mid <= e))
            }
        }))
    }

    /// Per sub-cell, the fraction of it that sees the direction prepared as `d`.
    fn seen(&self, d: &HorizonDirection) -> Seen {
        if let Some(v) = d.fixed {
            return Seen::Uniform(v);
        }
        let x = self.seen_along(d.ix, d.elev);
        if d.s2 <= 0.0 {
            return x;
        }
        x.mix(d.c2, self.seen_along(d.iy, d.elev), d.s2)
    }

    /// The fraction of the cell that sees the direction prepared as `d`.
    #[must_use]
    pub fn visibility_along(&self, d: &HorizonDirection) -> f64 {
        self.seen(d).mean()
    }

    /// The fraction of the cell that sees both directions prepared as `a` and `b`: per
    /// sub-cell the smaller of its two fractions (exact where each is all or nothing, as
    /// on the stored azimuths away from the horizon's edge), averaged. Hence
    /// `joint(a, a) = visibility(a)` and `joint ≤ min(V(a), V(b))`.
    #[must_use]
    pub fn joint_visibility_along(&self, a: &HorizonDirection, b: &HorizonDirection) -> f64 {
        Seen::both(&self.seen(a), &self.seen(b))
    }

    /// The fraction of what of the cell sees the view of `pair` that also sees its light (the
    /// light's visibility alone where nothing sees the view): with the view weight, which
    /// holds the cell's visibility of the viewer, the two together.
    #[must_use]
    pub fn visibility_given(&self, pair: &HorizonPair) -> f64 {
        let (light, view) = (self.seen(&pair.light), self.seen(&pair.view));
        let seen = view.mean();
        if seen <= 0.0 {
            return light.mean();
        }
        (Seen::both(&light, &view) / seen).min(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A direction at elevation `elev` and azimuth `az` (degrees).
    fn dir(elev: f64, az: f64) -> HorizonDirection {
        let (e, p) = (elev.to_radians(), az.to_radians());
        HorizonDirection::new(DVec3::new(e.cos() * p.cos(), e.cos() * p.sin(), e.sin()))
    }

    /// A cell whose corners' angles along every azimuth rise from `lo` to `hi` degrees
    /// along x, plus one degree per slot.
    fn ramp_cell(lo: f64, hi: f64) -> CellHorizon {
        CellHorizon::new(&std::array::from_fn(|s| {
            let (a, b) = ((lo + s as f64).to_radians(), (hi + s as f64).to_radians());
            [a, b, a, b]
        }))
    }

    #[test]
    fn a_cell_sees_what_its_bilinear_points_see() {
        // Angles 10°–30° linear in x along +x (slot 0): at elevation e, the part with angle
        // below e is the fraction (e − 10)/20 of the cell, exactly, the sub-cells being linear.
        let c = ramp_cell(10.0, 30.0);
        for e in [5.0, 10.0, 12.5, 20.0, 27.0, 30.0, 45.0] {
            let want = ((e - 10.0) / 20.0f64).clamp(0.0, 1.0);
            let got = c.visibility_along(&dir(e, 0.0));
            assert!((got - want).abs() < 1e-6, "elevation {e}: {got} vs {want}");
        }
        // A twisted cell (not linear): within 0.02 of the area fraction counted on a fine grid
        // of the bilinear angles.
        let t = CellHorizon::new(
            &[[
                5f64.to_radians(),
                35f64.to_radians(),
                30f64.to_radians(),
                8f64.to_radians(),
            ]; HORIZON_DIRECTIONS],
        );
        let a = t.corners[0].map(f64::from);
        let n = 400;
        for e in [6.0f64, 10.0, 15.0, 19.5, 24.0, 30.0, 34.0] {
            let mut below = 0;
            for i in 0..n {
                for j in 0..n {
                    let (x, y) = ((j as f64 + 0.5) / n as f64, (i as f64 + 0.5) / n as f64);
                    let v = a[0] * (1.0 - x) * (1.0 - y)
                        + a[1] * x * (1.0 - y)
                        + a[2] * (1.0 - x) * y
                        + a[3] * x * y;
                    below += usize::from(v <= e.to_radians());
                }
            }
            let want = below as f64 / (n * n) as f64;
            let got = t.visibility_along(&dir(e, 0.0));
            assert!(
                (got - want).abs() < 0.02,
                "twisted, elevation {e}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn the_joint_lies_in_the_frechet_bounds_and_is_exact_on_one_azimuth() {
        let c = CellHorizon::new(&std::array::from_fn(|s| {
            let k = s as f64;
            [
                (5.0 + 7.0 * k).to_radians(),
                (40.0 - 3.0 * k).to_radians(),
                (22.0 + k).to_radians(),
                (12.0 + 4.0 * k).to_radians(),
            ]
        }));
        for (ea, aa) in [(15.0, 0.0), (25.0, 30.0), (35.0, 200.0), (60.0, 100.0)] {
            let a = dir(ea, aa);
            let va = c.visibility_along(&a);
            assert!((c.joint_visibility_along(&a, &a) - va).abs() < 1e-12);
            for (eb, ab) in [(20.0, 90.0), (30.0, 180.0), (45.0, 270.0), (10.0, 315.0)] {
                let b = dir(eb, ab);
                let (vb, j) = (c.visibility_along(&b), c.joint_visibility_along(&a, &b));
                assert!(j <= va.min(vb) + 1e-12 && j >= (va + vb - 1.0).max(0.0) - 1e-12);
                let g = c.visibility_given(&HorizonPair::new(&a, &b));
                if vb > 0.0 {
                    assert!((g - (j / vb).min(1.0)).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn the_joint_knows_which_part_of_the_cell_sees() {
        // Along +x (slot 0) the cell's left half sees elevation 20°, along −y (slot 3) its
        // left half too: both halves are one, so the joint is a half, where the product of
        // the fractions says a quarter. Along +y (slot 1) the right half sees: none sees both.
        let (low, high) = (5f64.to_radians(), 40f64.to_radians());
        let mut corners = [[high; 4]; HORIZON_DIRECTIONS];
        corners[0] = [low, high, low, high];
        corners[3] = [low, high, low, high];
        corners[1] = [high, low, high, low];
        let c = CellHorizon::new(&corners);
        let (x, y, my) = (dir(22.5, 0.0), dir(22.5, 90.0), dir(22.5, 270.0));
        for d in [&x, &y, &my] {
            assert!((c.visibility_along(d) - 0.5).abs() < 1e-6);
        }
        assert!((c.joint_visibility_along(&x, &my) - 0.5).abs() < 1e-6);
        assert!(c.joint_visibility_along(&x, &y).abs() < 1e-6);
    }
}
