//! Visibility conditioned on the normal within a lobe: per stored azimuth, the horizons of the
//! facets a lobe stands for that are turned towards it, apart from the rest
//! ([`HorizonToward`]).
//!
//! A lobe's distribution ([`HorizonCdf`]) says how much of what the lobe stands for sees a
//! direction, the same for all its normals. But a facet turned towards a direction is more
//! often open to it: on the steep facade map a lobe's visibility, read alike by all its
//! normals, puts the seen-weighted Lambert radiance of levels 2–5 at 0.70–2.26 of the exact
//! (every cell's own normal and fraction that sees); the two groups, each lobe node reading the
//! group its own tilt falls in, at 0.75–1.63 (docs/heightmaps.md, "Where the rest of the
//! coarse levels' deficit comes from").

use super::{HorizonCdf, HorizonCdfSum, HorizonDirection, CDF_NODES, HORIZON_DIRECTIONS};
use glam::DVec3;

/// A unit normal counts as turned towards a stored azimuth when its horizontal component along
/// it exceeds this (the sine of about 6°): flat facets, and the nodes of a lobe about the
/// vertical, are of the rest.
pub const TOWARD_TILT: f64 = 0.1;

/// The unit vectors of [`super::HORIZON_AZIMUTHS_DEG`] in the plane (0°, 90°, 180°, 270°, then the
/// diagonals 45°, 135°, 225°, 315°).
const AZIMUTH_UNITS: [[f64; 2]; HORIZON_DIRECTIONS] = {
    const S: f64 = std::f64::consts::FRAC_1_SQRT_2;
    [
        [1.0, 0.0],
        [0.0, 1.0],
        [-1.0, 0.0],
        [0.0, -1.0],
        [S, S],
        [-S, S],
        [-S, -S],
        [S, -S],
    ]
};

/// Whether unit normal `m` is turned towards the stored azimuth of unit vector `u`.
#[inline]
fn turned_towards(m: DVec3, u: [f64; 2]) -> bool {
    m.x * u[0] + m.y * u[1] > TOWARD_TILT
}

/// Per stored azimuth of [`super::HORIZON_AZIMUTHS_DEG`], the share of a lobe's weight from facets
/// turned towards it ([`TOWARD_TILT`]) and the distribution of their horizons along it (as
/// [`HorizonCdf::frac`]), to 1/255 (136 bytes). The rest's distribution follows from the
/// lobe's own ([`HorizonToward::reading`]). Pooled exactly ([`HorizonTowardSum`]).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct HorizonToward {
    /// Per direction, the share of the lobe's weight turned towards it, in units of 1/255.
    pub share: [u8; HORIZON_DIRECTIONS],
    /// Per direction, per node of [`super::CDF_ELEVATIONS_DEG`], the fraction of the facets
    /// turned towards it whose horizon lies at or below the node, in units of 1/255.
    pub frac: [[u8; CDF_NODES]; HORIZON_DIRECTIONS],
}

/// Weighted sums of facets' horizon distributions split by whether each is turned towards each
/// stored azimuth: [`HorizonTowardSum::finish`] gives the [`HorizonToward`] of everything
/// added.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct HorizonTowardSum {
    weight: f64,
    toward: [f64; HORIZON_DIRECTIONS],
    sum: [[f32; CDF_NODES]; HORIZON_DIRECTIONS],
}

impl HorizonTowardSum {
    /// Add the horizon distribution `cell` (its sums) of facets of unit normal `m`, scaled by
    /// `scale`: along each stored azimuth `m` is turned towards, to that azimuth's group.
    pub fn add(&mut self, cell: &HorizonCdfSum, m: DVec3, scale: f64) {
        if cell.weight <= 0.0 || scale <= 0.0 {
            return;
        }
        let w = cell.weight * scale;
        self.weight += w;
        let k = scale as f32;
        for (d, &u) in AZIMUTH_UNITS.iter().enumerate() {
            if turned_towards(m, u) {
                self.toward[d] += w;
                for (x, y) in self.sum[d].iter_mut().zip(&cell.sum[d]) {
                    *x += k * y;
                }
            }
        }
    }

    /// The pooled groups, rounded to 1/255 (all zero when nothing was added).
    #[must_use]
    pub fn finish(&self) -> HorizonToward {
        let mut out = HorizonToward::default();
        if self.weight <= 0.0 {
            return out;
        }
        for d in 0..HORIZON_DIRECTIONS {
            let t = self.toward[d];
            out.share[d] = super::to_255(t as f32, 1.0 / self.weight);
            if t > 0.0 {
                let inv = 1.0 / t;
                out.frac[d] = self.sum[d].map(|v| super::to_255(v, inv));
            }
        }
        out
    }
}

/// What the nodes of one lobe read of one direction ([`HorizonToward::reading`]): for each of
/// the direction's two stored azimuths, its unit vector, its weight, and the fraction that sees
/// of the facets turned towards it and of the rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TowardReading {
    slots: [([f64; 2], f64, f64, f64); 2],
    fixed: Option<f64>,
}

impl TowardReading {
    /// A reading the same for every normal: `v`.
    fn uniform(v: f64) -> TowardReading {
        TowardReading {
            slots: [([0.0; 2], 0.0, v, v); 2],
            fixed: Some(v),
        }
    }

    /// Whether every normal reads alike: a fixed direction, or the groups of both stored
    /// azimuths reading the same (to 10⁻⁶).
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        self.fixed.is_some()
            || self
                .slots
                .iter()
                .all(|s| (s.2 - s.3).abs() <= 1e-6 || s.1 <= 0.0)
    }

    /// The fraction that sees the direction of the lobe's facets of unit normal `m`: along
    /// each of its two stored azimuths the group `m` falls in, interpolated as
    /// [`HorizonCdf::visibility_along`] interpolates them.
    #[inline]
    #[must_use]
    pub fn at(&self, m: DVec3) -> f64 {
        if let Some(v) = self.fixed {
            return v;
        }
        let mut v = 0.0;
        for &(u, w, toward, rest) in &self.slots {
            if w > 0.0 {
                v += w * if turned_towards(m, u) { toward } else { rest };
            }
        }
        v
    }
}

impl HorizonToward {
    /// What a lobe whose own distribution is `cdf` reads of direction `d` per normal: the
    /// fraction that sees of its facets turned towards each stored azimuth (this one's
    /// distribution) and of the rest (`(F − s·T)/(1 − s)` of the lobe's own `F`, the share `s`
    /// and the group's `T`, within [0, 1]; the lobe's own where the rest weighs nothing).
    /// The weighted mean over the two groups is the lobe's own fraction (up to rounding).
    #[must_use]
    pub fn reading(&self, cdf: &HorizonCdf, d: &HorizonDirection) -> TowardReading {
        if cdf.weight <= 0.0 {
            return TowardReading::uniform(1.0);
        }
        if let Some(v) = d.fixed {
            return TowardReading::uniform(v);
        }
        let slot = |k: usize, w: f64| {
            let f = cdf.at(k, d);
            let s = super::unit_255(self.share[k]);
            let t = if s > 0.0 { self.at(k, d) } else { f };
            let rest = if 1.0 - s > 1e-6 {
                ((f - s * t) / (1.0 - s)).clamp(0.0, 1.0)
            } else {
                f
            };
            (AZIMUTH_UNITS[k], w, t, rest)
        };
        TowardReading {
            slots: [slot(d.ix, d.c2), slot(d.iy, d.s2)],
            fixed: None,
        }
    }

    /// The fraction of the facets turned towards stored azimuth `slot` whose horizon along it
    /// lies below the elevation of `d` (linear between the nodes).
    fn at(&self, slot: usize, d: &HorizonDirection) -> f64 {
        super::fraction_at(&self.frac[slot], d)
    }
}

#[cfg(test)]
mod tests {
    use super::super::HORIZON_AZIMUTHS_DEG;
    use super::*;

    fn dir(elev: f64, az: f64) -> HorizonDirection {
        let (e, p) = (elev.to_radians(), az.to_radians());
        HorizonDirection::new(DVec3::new(e.cos() * p.cos(), e.cos() * p.sin(), e.sin()))
    }

    #[test]
    fn the_azimuth_units_are_the_stored_azimuths() {
        for (u, a) in AZIMUTH_UNITS.iter().zip(HORIZON_AZIMUTHS_DEG) {
            let r = a.to_radians();
            assert!(
                (u[0] - r.cos()).abs() < 1e-12 && (u[1] - r.sin()).abs() < 1e-12,
                "{a}°"
            );
        }
    }

    #[test]
    fn each_normal_reads_its_group_and_the_groups_average_to_the_lobe() {
        // Walls facing +x whose horizon along +x is low (5°), walls facing −x whose horizon
        // along +x is high (40°), and flat tops between (20°), weights 1 : 2 : 1.
        let deg = |x: f64| x.to_radians();
        let set = |a: f64| HorizonCdfSum::of_points(&[[deg(a); 16]; HORIZON_DIRECTIONS], 1.0);
        let east = DVec3::new(0.9, 0.0, 0.436).normalize();
        let west = DVec3::new(-0.9, 0.0, 0.436).normalize();
        let parts = [
            (set(5.0), east, 1.0),
            (set(40.0), west, 2.0),
            (set(20.0), DVec3::Z, 1.0),
        ];
        let (mut cdf, mut tw) = (HorizonCdfSum::default(), HorizonTowardSum::default());
        for (c, m, w) in &parts {
            cdf.add(c, *w);
            tw.add(c, *m, *w);
        }
        let (cdf, tw) = (cdf.finish(), tw.finish());
        assert_eq!(tw.share[0], 64, "a quarter turned towards +x");
        for e in [3.0, 10.0, 30.0, 50.0] {
            let d = dir(e, 0.0);
            let r = tw.reading(&cdf, &d);
            let want_east = f64::from(u8::from(e > 5.0));
            let want_rest =
                (2.0 * f64::from(u8::from(e > 40.0)) + f64::from(u8::from(e > 20.0))) / 3.0;
            assert!(
                (r.at(east) - want_east).abs() < 0.02,
                "{e}°: {}",
                r.at(east)
            );
            assert!(
                (r.at(west) - want_rest).abs() < 0.02,
                "{e}°: {}",
                r.at(west)
            );
            assert!((r.at(DVec3::Z) - want_rest).abs() < 0.02);
            let mean = 0.25 * r.at(east) + 0.75 * r.at(west);
            assert!((mean - cdf.visibility_along(&d)).abs() < 0.01);
        }
        // Below the horizon and a lobe of no weight: fixed.
        let below = HorizonDirection::new(DVec3::new(1.0, 0.0, -0.2));
        assert_eq!(tw.reading(&cdf, &below).at(east), 0.0);
        assert_eq!(
            tw.reading(&HorizonCdf::default(), &dir(10.0, 0.0)).at(west),
            1.0
        );
    }
}
