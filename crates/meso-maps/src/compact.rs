//! How a pyramid level keeps its lobes and horizon statistics in memory: as `f64`
//! ([`PhongLobe`], [`HorizonStats`]: 40 and 72 bytes) on small levels, as `f32` ([`Lobe32`],
//! [`Horizon32`]: 20 and 36 bytes) on the big fine levels, which hold almost all of a pyramid's
//! texels (the levels of at least [`COMPACT_TEXELS`] texels by default; the coarse levels keep
//! full precision, the fine ones half the memory).
//!
//! Readers never see the difference in type: [`Lobes`] and [`Horizons`] yield the `f64` values
//! ([`Lobes::get`], [`Lobes::range`], [`Horizons::get`]), decoding an `f32` lobe to a unit axis
//! (renormalised in `f64`) and its weight, exponent as stored. An `f32` value is the `f64` one
//! rounded once: axes within 1.2·10⁻⁷ rad, weights, exponents and horizon statistics within
//! 6·10⁻⁸ relative (`f32`'s half ulp) — 20 to 1 000 times finer than a map file's codes
//! (docs/map-format.md), so a compact level written to a file gives the codes of the `f64` one
//! except for values within that distance of a rounding boundary (one code step then).

use crate::horizon::HorizonStats;
use glam::DVec3;
use meso_core::ndf::PhongLobe;

/// Levels with at least this many texels are stored in `f32` by default (`ExtractParams`'s
/// `compact_texels`, and [`crate::Pyramid::read`]): 256² texels, so that a 1024² map's
/// levels 0–2 (99.6 % of its texels) are compact and the coarse levels exact.
pub const COMPACT_TEXELS: usize = 1 << 16;

/// A Phong lobe in `f32` (20 bytes): axis (unit, local frame), weight, exponent.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Lobe32 {
    /// Unit axis (x, y, z).
    pub axis: [f32; 3],
    /// Weight (a texel's weights sum to 1).
    pub weight: f32,
    /// Exponent η.
    pub exponent: f32,
}

impl Lobe32 {
    /// The lobe rounded to `f32`.
    #[must_use]
    pub fn from_phong(l: &PhongLobe) -> Lobe32 {
        Lobe32 {
            axis: [l.axis.x as f32, l.axis.y as f32, l.axis.z as f32],
            weight: l.weight as f32,
            exponent: l.exponent as f32,
        }
    }
    /// The lobe in `f64`, its axis renormalised.
    #[inline]
    #[must_use]
    pub fn to_phong(&self) -> PhongLobe {
        let a = DVec3::new(
            f64::from(self.axis[0]),
            f64::from(self.axis[1]),
            f64::from(self.axis[2]),
        );
        PhongLobe {
            axis: a / a.length(),
            weight: f64::from(self.weight),
            exponent: f64::from(self.exponent),
        }
    }
}

/// The lobes of a level, in `f64` or in `f32` (module docs). Read them as [`PhongLobe`]s.
#[derive(Clone, Debug, PartialEq)]
pub enum Lobes {
    /// Full precision.
    F64(Vec<PhongLobe>),
    /// Rounded to `f32`.
    F32(Vec<Lobe32>),
}

impl Default for Lobes {
    fn default() -> Self {
        Lobes::F64(Vec::new())
    }
}

impl Lobes {
    /// `lobes` as they are, or rounded to `f32` when `compact`.
    #[must_use]
    pub fn new(lobes: Vec<PhongLobe>, compact: bool) -> Lobes {
        if compact {
            Lobes::F32(lobes.iter().map(Lobe32::from_phong).collect())
        } else {
            Lobes::F64(lobes)
        }
    }
    /// Number of lobes.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Lobes::F64(v) => v.len(),
            Lobes::F32(v) => v.len(),
        }
    }
    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether the lobes are stored in `f32`.
    #[must_use]
    pub fn is_compact(&self) -> bool {
        matches!(self, Lobes::F32(_))
    }
    /// Lobe `i`.
    ///
    /// # Panics
    /// `i ≥ len()`.
    #[inline]
    #[must_use]
    pub fn get(&self, i: usize) -> PhongLobe {
        match self {
            Lobes::F64(v) => v[i],
            Lobes::F32(v) => v[i].to_phong(),
        }
    }
    /// Lobes `a..b`.
    ///
    /// # Panics
    /// `a > b` or `b > len()`.
    #[must_use]
    pub fn range(&self, a: usize, b: usize) -> LobeIter<'_> {
        match self {
            Lobes::F64(v) => LobeIter::F64(v[a..b].iter()),
            Lobes::F32(v) => LobeIter::F32(v[a..b].iter()),
        }
    }
    /// All lobes.
    #[must_use]
    pub fn iter(&self) -> LobeIter<'_> {
        self.range(0, self.len())
    }
    /// Bytes the lobes occupy (their number × 40 or 20).
    #[must_use]
    pub fn bytes(&self) -> usize {
        match self {
            Lobes::F64(v) => v.len() * std::mem::size_of::<PhongLobe>(),
            Lobes::F32(v) => v.len() * std::mem::size_of::<Lobe32>(),
        }
    }
    /// Replace lobe `i` (rounded when compact).
    ///
    /// # Panics
    /// `i ≥ len()`.
    pub fn set(&mut self, i: usize, l: PhongLobe) {
        match self {
            Lobes::F64(v) => v[i] = l,
            Lobes::F32(v) => v[i] = Lobe32::from_phong(&l),
        }
    }
    /// Append one lobe (rounded when compact).
    pub fn push(&mut self, l: PhongLobe) {
        match self {
            Lobes::F64(v) => v.push(l),
            Lobes::F32(v) => v.push(Lobe32::from_phong(&l)),
        }
    }
    /// Append lobes (rounded when compact).
    pub fn extend_from_slice(&mut self, ls: &[PhongLobe]) {
        match self {
            Lobes::F64(v) => v.extend_from_slice(ls),
            Lobes::F32(v) => v.extend(ls.iter().map(Lobe32::from_phong)),
        }
    }
    /// Release unused capacity.
    pub fn shrink_to_fit(&mut self) {
        match self {
            Lobes::F64(v) => v.shrink_to_fit(),
            Lobes::F32(v) => v.shrink_to_fit(),
        }
    }
}

/// The lobes of [`Lobes::range`] as [`PhongLobe`]s.
#[derive(Clone, Debug)]
pub enum LobeIter<'a> {
    /// Over `f64` lobes.
    F64(std::slice::Iter<'a, PhongLobe>),
    /// Over `f32` lobes.
    F32(std::slice::Iter<'a, Lobe32>),
}

impl Iterator for LobeIter<'_> {
    type Item = PhongLobe;
    #[inline]
    fn next(&mut self) -> Option<PhongLobe> {
        match self {
            LobeIter::F64(i) => i.next().copied(),
            LobeIter::F32(i) => i.next().map(Lobe32::to_phong),
        }
    }
    fn size_hint(&self) -> (usize, Option<usize>) {
        match self {
            LobeIter::F64(i) => i.size_hint(),
            LobeIter::F32(i) => i.size_hint(),
        }
    }
}

impl ExactSizeIterator for LobeIter<'_> {}

impl<'a> IntoIterator for &'a Lobes {
    type Item = PhongLobe;
    type IntoIter = LobeIter<'a>;
    fn into_iter(self) -> LobeIter<'a> {
        self.iter()
    }
}

/// Horizon statistics in `f32` (36 bytes).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Horizon32 {
    /// Samples summarised.
    pub weight: f32,
    /// Mean horizon angle per direction (radians).
    pub mean: [f32; 4],
    /// Variance per direction (radians²).
    pub var: [f32; 4],
}

impl Horizon32 {
    /// The statistics rounded to `f32`.
    #[must_use]
    pub fn from_stats(h: &HorizonStats) -> Horizon32 {
        Horizon32 {
            weight: h.weight as f32,
            mean: h.mean.map(|x| x as f32),
            var: h.var.map(|x| x as f32),
        }
    }
    /// The statistics in `f64`.
    #[inline]
    #[must_use]
    pub fn to_stats(&self) -> HorizonStats {
        HorizonStats {
            weight: f64::from(self.weight),
            mean: self.mean.map(f64::from),
            var: self.var.map(f64::from),
        }
    }
}

/// The horizon statistics of a level's texels, in `f64` or in `f32` (module docs).
#[derive(Clone, Debug, PartialEq)]
pub enum Horizons {
    /// Full precision.
    F64(Vec<HorizonStats>),
    /// Rounded to `f32`.
    F32(Vec<Horizon32>),
}

impl Horizons {
    /// `stats` as they are, or rounded to `f32` when `compact`.
    #[must_use]
    pub fn new(stats: Vec<HorizonStats>, compact: bool) -> Horizons {
        if compact {
            Horizons::F32(stats.iter().map(Horizon32::from_stats).collect())
        } else {
            Horizons::F64(stats)
        }
    }
    /// Number of texels.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Horizons::F64(v) => v.len(),
            Horizons::F32(v) => v.len(),
        }
    }
    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether the statistics are stored in `f32`.
    #[must_use]
    pub fn is_compact(&self) -> bool {
        matches!(self, Horizons::F32(_))
    }
    /// The statistics of texel `t`.
    ///
    /// # Panics
    /// `t ≥ len()`.
    #[inline]
    #[must_use]
    pub fn get(&self, t: usize) -> HorizonStats {
        match self {
            Horizons::F64(v) => v[t],
            Horizons::F32(v) => v[t].to_stats(),
        }
    }
    /// All of them, in `f64`.
    #[must_use]
    pub fn iter(&self) -> HorizonIter<'_> {
        HorizonIter {
            h: self,
            next: 0,
            end: self.len(),
        }
    }
    /// All of them as a vector of `f64` statistics.
    #[must_use]
    pub fn to_vec(&self) -> Vec<HorizonStats> {
        self.iter().collect()
    }
    /// Bytes they occupy (texels × 72 or 36).
    #[must_use]
    pub fn bytes(&self) -> usize {
        match self {
            Horizons::F64(v) => v.len() * std::mem::size_of::<HorizonStats>(),
            Horizons::F32(v) => v.len() * std::mem::size_of::<Horizon32>(),
        }
    }
    /// Append statistics (rounded when compact).
    pub fn extend_from_slice(&mut self, hs: &[HorizonStats]) {
        match self {
            Horizons::F64(v) => v.extend_from_slice(hs),
            Horizons::F32(v) => v.extend(hs.iter().map(Horizon32::from_stats)),
        }
    }
}

/// The statistics of [`Horizons::iter`] in `f64`.
#[derive(Clone, Debug)]
pub struct HorizonIter<'a> {
    h: &'a Horizons,
    next: usize,
    end: usize,
}

impl Iterator for HorizonIter<'_> {
    type Item = HorizonStats;
    #[inline]
    fn next(&mut self) -> Option<HorizonStats> {
        (self.next < self.end).then(|| {
            self.next += 1;
            self.h.get(self.next - 1)
        })
    }
    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.end - self.next;
        (n, Some(n))
    }
}

impl ExactSizeIterator for HorizonIter<'_> {}

impl<'a> IntoIterator for &'a Horizons {
    type Item = HorizonStats;
    type IntoIter = HorizonIter<'a>;
    fn into_iter(self) -> HorizonIter<'a> {
        self.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_lobes_and_horizons_round_trip_within_f32_rounding() {
        let l = PhongLobe {
            axis: DVec3::new(0.3, -0.4, 0.7).normalize(),
            weight: 0.123_456_789,
            exponent: 4_321.123_456,
        };
        let back = Lobe32::from_phong(&l).to_phong();
        assert!((back.axis.length() - 1.0).abs() < 1e-15);
        assert!(back.axis.angle_between(l.axis) < 1.2e-7);
        assert!((back.weight - l.weight).abs() <= 6e-8 * l.weight);
        assert!((back.exponent - l.exponent).abs() <= 6e-8 * l.exponent);
        let f = Lobes::new(vec![l; 3], false);
        let c = Lobes::new(vec![l; 3], true);
        assert_eq!((f.len(), c.len()), (3, 3));
        assert_eq!((f.bytes(), c.bytes()), (120, 60));
        assert_eq!(f.get(1), l);
        assert_eq!(c.range(1, 3).count(), 2);
        assert!(c.iter().all(|x| x == back));
        let h = HorizonStats {
            weight: 16.0,
            mean: [0.1, 0.2, 0.3, 1.5],
            var: [0.01, 0.0, 0.002, 0.3],
        };
        let hb = Horizons::new(vec![h], true).get(0);
        assert_eq!(hb.weight, 16.0);
        for d in 0..4 {
            assert!((hb.mean[d] - h.mean[d]).abs() <= 6e-8 * h.mean[d]);
            assert!((hb.var[d] - h.var[d]).abs() <= 6e-8 * h.var[d]);
        }
        assert_eq!(Horizons::new(vec![h], false).get(0), h);
    }
}
