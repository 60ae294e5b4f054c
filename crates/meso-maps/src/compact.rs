//! How a pyramid level keeps its lobes and horizon statistics in memory: as `f64`
//! ([`PhongLobe`], [`HorizonStats`]: 40 and 136 bytes) on small levels, as `f32` ([`Lobe32`],
//! [`Horizon32`]: 20 and 68 bytes) on the big fine levels, which hold almost all of a pyramid's
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

use crate::format::LazyLevel;
use crate::horizon::{HorizonStats, HORIZON_DIRECTIONS};
use glam::DVec3;
use meso_core::ndf::PhongLobe;
use std::sync::Arc;

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

/// A lobe as a map file codes it (11 bytes): its axis as the file's two 20-bit octahedral
/// coordinates, its exponent as the file's 16-bit code, and its weight (the file's 16-bit code
/// over its texel's sum) in `f32`. It reads back as the [`Lobe32`] of the decoded lobe, bit for
/// bit ([`LobeCode::to_phong`]): a map file's compact level kept at about half its `f32` size
/// (what `meso render` holds, [`crate::Pyramid::read_coded`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct LobeCode([u8; 11]);

impl LobeCode {
    /// The lobe of axis code `(u, v)` (20 bits each), exponent code `eta` and weight `weight`.
    #[must_use]
    pub fn new(u: u32, v: u32, eta: u16, weight: f32) -> LobeCode {
        let a = (u64::from(u) & 0xF_FFFF) | ((u64::from(v) & 0xF_FFFF) << 20);
        let mut b = [0u8; 11];
        b[..5].copy_from_slice(&a.to_le_bytes()[..5]);
        b[5..7].copy_from_slice(&eta.to_le_bytes());
        b[7..].copy_from_slice(&weight.to_le_bytes());
        LobeCode(b)
    }
    /// The lobe coded: axis and exponent to the map file's nearest codes, weight to `f32`.
    #[must_use]
    pub fn from_phong(l: &PhongLobe) -> LobeCode {
        let (u, v) = crate::format::oct_encode(l.axis);
        LobeCode::new(u, v, crate::format::eta_encode(l.exponent), l.weight as f32)
    }
    /// The axis code `(u, v)`.
    #[must_use]
    pub fn axis_code(&self) -> (u32, u32) {
        let mut a = [0u8; 8];
        a[..5].copy_from_slice(&self.0[..5]);
        let a = u64::from_le_bytes(a);
        ((a & 0xF_FFFF) as u32, ((a >> 20) & 0xF_FFFF) as u32)
    }
    /// The exponent code.
    #[must_use]
    pub fn eta_code(&self) -> u16 {
        u16::from_le_bytes([self.0[5], self.0[6]])
    }
    /// The lobe as the map file's reader decodes it, rounded to `f32` as a compact level keeps
    /// it ([`Lobe32`]), in `f64` with its axis renormalised: [`Lobe32::to_phong`] of that.
    #[inline]
    #[must_use]
    pub fn to_phong(&self) -> PhongLobe {
        let (u, v) = self.axis_code();
        let a = crate::format::oct_decode(u, v);
        let w = f32::from_le_bytes([self.0[7], self.0[8], self.0[9], self.0[10]]);
        Lobe32 {
            axis: [a.x as f32, a.y as f32, a.z as f32],
            weight: w,
            exponent: crate::format::eta_decode(self.eta_code()) as f32,
        }
        .to_phong()
    }
}

/// The lobes of a level, in `f64`, in `f32`, or as a map file's codes, held or read from the
/// mapped file by band (module docs). Read them as [`PhongLobe`]s.
#[derive(Clone, Debug, PartialEq)]
pub enum Lobes {
    /// Full precision.
    F64(Vec<PhongLobe>),
    /// Rounded to `f32`.
    F32(Vec<Lobe32>),
    /// A map file's codes (reading back as `F32` would: [`LobeCode`]).
    Coded(Vec<LobeCode>),
    /// A map file's codes decoded band by band from the mapped file when read (the very
    /// values of `Coded`, [`LazyLevel`]); read-only: writing to one first copies the codes
    /// into `Coded`.
    Lazy(Arc<LazyLevel>),
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
            Lobes::Coded(v) => v.len(),
            Lobes::Lazy(l) => l.lobes(),
        }
    }
    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether the lobes are stored in `f32` (or coded, which reads back as `f32`).
    #[must_use]
    pub fn is_compact(&self) -> bool {
        matches!(self, Lobes::F32(_) | Lobes::Coded(_) | Lobes::Lazy(_))
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
            Lobes::Coded(v) => v[i].to_phong(),
            Lobes::Lazy(l) => l.lobe(i),
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
            Lobes::Coded(v) => LobeIter::Coded(v[a..b].iter()),
            Lobes::Lazy(l) => LobeIter::Lazy(l.range(a, b)),
        }
    }
    /// All lobes.
    #[must_use]
    pub fn iter(&self) -> LobeIter<'_> {
        self.range(0, self.len())
    }
    /// Bytes the lobes occupy (their number × 40, 20 or 11; held by band, the most the
    /// level's decoded bands take, lobes and horizon statistics: [`LazyLevel::held_bytes_bound`]).
    #[must_use]
    pub fn bytes(&self) -> usize {
        match self {
            Lobes::F64(v) => v.len() * std::mem::size_of::<PhongLobe>(),
            Lobes::F32(v) => v.len() * std::mem::size_of::<Lobe32>(),
            Lobes::Coded(v) => v.len() * std::mem::size_of::<LobeCode>(),
            Lobes::Lazy(l) => usize::try_from(l.held_bytes_bound()).unwrap_or(usize::MAX),
        }
    }
    /// Copy lobes held by band into `Coded` (before writing to them).
    fn own(&mut self) {
        if let Lobes::Lazy(l) = self {
            *self = Lobes::Coded(l.lobe_codes(0, l.lobes()));
        }
    }
    /// Replace lobe `i` (rounded when compact, coded when coded).
    ///
    /// # Panics
    /// `i ≥ len()`.
    pub fn set(&mut self, i: usize, l: PhongLobe) {
        self.own();
        match self {
            Lobes::F64(v) => v[i] = l,
            Lobes::F32(v) => v[i] = Lobe32::from_phong(&l),
            Lobes::Coded(v) => v[i] = LobeCode::from_phong(&l),
            Lobes::Lazy(_) => unreachable!("owned above"),
        }
    }
    /// Append one lobe (rounded when compact).
    pub fn push(&mut self, l: PhongLobe) {
        self.own();
        match self {
            Lobes::F64(v) => v.push(l),
            Lobes::F32(v) => v.push(Lobe32::from_phong(&l)),
            Lobes::Coded(v) => v.push(LobeCode::from_phong(&l)),
            Lobes::Lazy(_) => unreachable!("owned above"),
        }
    }
    /// Append lobes (rounded when compact).
    pub fn extend_from_slice(&mut self, ls: &[PhongLobe]) {
        self.own();
        match self {
            Lobes::F64(v) => v.extend_from_slice(ls),
            Lobes::F32(v) => v.extend(ls.iter().map(Lobe32::from_phong)),
            Lobes::Coded(v) => v.extend(ls.iter().map(LobeCode::from_phong)),
            Lobes::Lazy(_) => unreachable!("owned above"),
        }
    }
    /// Release unused capacity.
    pub fn shrink_to_fit(&mut self) {
        match self {
            Lobes::F64(v) => v.shrink_to_fit(),
            Lobes::F32(v) => v.shrink_to_fit(),
            Lobes::Coded(v) => v.shrink_to_fit(),
            Lobes::Lazy(_) => {}
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
    /// Over coded lobes.
    Coded(std::slice::Iter<'a, LobeCode>),
    /// Over lobes held by band.
    Lazy(crate::format::LazyLobes<'a>),
}

impl Iterator for LobeIter<'_> {
    type Item = PhongLobe;
    #[inline(always)]
    fn next(&mut self) -> Option<PhongLobe> {
        match self {
            LobeIter::F64(i) => i.next().copied(),
            LobeIter::F32(i) => i.next().map(Lobe32::to_phong),
            LobeIter::Coded(i) => i.next().map(LobeCode::to_phong),
            LobeIter::Lazy(i) => i.next(),
        }
    }
    fn size_hint(&self) -> (usize, Option<usize>) {
        match self {
            LobeIter::F64(i) => i.size_hint(),
            LobeIter::F32(i) => i.size_hint(),
            LobeIter::Coded(i) => i.size_hint(),
            LobeIter::Lazy(i) => i.size_hint(),
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

/// Horizon statistics in `f32` (68 bytes: the weight, then a mean and a variance per
/// direction of [`crate::HORIZON_AZIMUTHS_DEG`]).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Horizon32 {
    /// Samples summarised.
    pub weight: f32,
    /// Mean horizon angle per direction (radians).
    pub mean: [f32; HORIZON_DIRECTIONS],
    /// Variance per direction (radians²).
    pub var: [f32; HORIZON_DIRECTIONS],
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

/// Bytes of a [`HorizonCode`]: the weight (4) and 16 codes of 12 bits (24).
pub const HORIZON_CODE_BYTES: usize = 28;

/// Horizon statistics as a map file codes them (28 bytes): the weight in `f32` and per
/// direction the 12-bit codes of the mean horizon angle and of its standard deviation. It
/// reads back as the [`Horizon32`] of the decoded statistics, bit for bit
/// ([`HorizonCode::to_stats`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HorizonCode([u8; HORIZON_CODE_BYTES]);

impl Default for HorizonCode {
    fn default() -> HorizonCode {
        HorizonCode([0; HORIZON_CODE_BYTES])
    }
}

impl HorizonCode {
    /// The statistics of weight `weight` and codes `mean` and `sd` (12 bits each, per direction
    /// of [`crate::HORIZON_AZIMUTHS_DEG`]; larger codes are kept as 4 095, which the map file's
    /// decoder reads them as).
    #[must_use]
    pub fn new(
        weight: f32,
        mean: [u16; HORIZON_DIRECTIONS],
        sd: [u16; HORIZON_DIRECTIONS],
    ) -> HorizonCode {
        let mut b = [0u8; HORIZON_CODE_BYTES];
        b[..4].copy_from_slice(&weight.to_le_bytes());
        // Two codes in three bytes.
        for (i, pair) in mean.chunks(2).chain(sd.chunks(2)).enumerate() {
            // A code reads as at most 4 095 (the decoder's clamp): kept so.
            let v = u32::from(pair[0].min(0xFFF)) | (u32::from(pair[1].min(0xFFF)) << 12);
            b[4 + 3 * i..7 + 3 * i].copy_from_slice(&v.to_le_bytes()[..3]);
        }
        HorizonCode(b)
    }
    /// The statistics coded: the angles to the map file's nearest codes, weight to `f32`.
    #[must_use]
    pub fn from_stats(h: &HorizonStats) -> HorizonCode {
        use crate::format::{angle_encode, MEAN_SPAN, SD_SPAN};
        HorizonCode::new(
            h.weight as f32,
            h.mean.map(|m| angle_encode(m, MEAN_SPAN)),
            h.var.map(|v| angle_encode(v.max(0.0).sqrt(), SD_SPAN)),
        )
    }
    /// The statistics as the map file's reader decodes them, rounded to `f32` as a compact
    /// level keeps them ([`Horizon32`]), in `f64`.
    #[inline]
    #[must_use]
    pub fn to_stats(&self) -> HorizonStats {
        use crate::format::{angle_decode, MEAN_SPAN, SD_SPAN};
        let q = |i: usize| {
            let b = &self.0[4 + 3 * (i / 2)..7 + 3 * (i / 2)];
            let v = u32::from_le_bytes([b[0], b[1], b[2], 0]);
            ((v >> (12 * (i % 2))) & 0xFFF) as u16
        };
        let mut h = Horizon32 {
            weight: f32::from_le_bytes([self.0[0], self.0[1], self.0[2], self.0[3]]),
            ..Horizon32::default()
        };
        for d in 0..HORIZON_DIRECTIONS {
            h.mean[d] = angle_decode(q(d), MEAN_SPAN) as f32;
            let sd = angle_decode(q(HORIZON_DIRECTIONS + d), SD_SPAN);
            h.var[d] = (sd * sd) as f32;
        }
        h.to_stats()
    }
}

/// The horizon statistics of a level's texels, in `f64`, in `f32`, or as a map file's codes,
/// held or read from the mapped file by band (module docs).
#[derive(Clone, Debug, PartialEq)]
pub enum Horizons {
    /// Full precision.
    F64(Vec<HorizonStats>),
    /// Rounded to `f32`.
    F32(Vec<Horizon32>),
    /// A map file's codes (reading back as `F32` would: [`HorizonCode`]).
    Coded(Vec<HorizonCode>),
    /// A map file's codes decoded band by band from the mapped file when read (the very
    /// values of `Coded`, [`LazyLevel`]); read-only: writing to one first copies the codes
    /// into `Coded`.
    Lazy(Arc<LazyLevel>),
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
            Horizons::Coded(v) => v.len(),
            Horizons::Lazy(l) => l.texels(),
        }
    }
    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether the statistics are stored in `f32` (or coded, which reads back as `f32`).
    #[must_use]
    pub fn is_compact(&self) -> bool {
        matches!(
            self,
            Horizons::F32(_) | Horizons::Coded(_) | Horizons::Lazy(_)
        )
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
            Horizons::Coded(v) => v[t].to_stats(),
            Horizons::Lazy(l) => l.horizon(t),
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
    /// Bytes they occupy (texels × 136, 68 or 28; held by band, 0: counted by the level's
    /// [`Lobes::bytes`]).
    #[must_use]
    pub fn bytes(&self) -> usize {
        match self {
            Horizons::F64(v) => v.len() * std::mem::size_of::<HorizonStats>(),
            Horizons::F32(v) => v.len() * std::mem::size_of::<Horizon32>(),
            Horizons::Coded(v) => v.len() * std::mem::size_of::<HorizonCode>(),
            Horizons::Lazy(_) => 0,
        }
    }
    /// Copy statistics held by band into `Coded` (before writing to them).
    fn own(&mut self) {
        if let Horizons::Lazy(l) = self {
            *self = Horizons::Coded(l.horizon_codes(0, l.texels()));
        }
    }
    /// Append statistics (rounded when compact, coded when coded; held by band, the codes
    /// copied into `Coded` first).
    pub fn extend_from_slice(&mut self, hs: &[HorizonStats]) {
        self.own();
        match self {
            Horizons::F64(v) => v.extend_from_slice(hs),
            Horizons::F32(v) => v.extend(hs.iter().map(Horizon32::from_stats)),
            Horizons::Coded(v) => v.extend(hs.iter().map(HorizonCode::from_stats)),
            Horizons::Lazy(_) => unreachable!("owned above"),
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

    /// [`crate::Pyramid::read_coded`] keeps the compact levels of a format-4 file as codes
    /// (11 bytes a lobe, 16 a texel's horizons) that read back bit for bit as
    /// [`crate::Pyramid::read`]'s `f32` levels; the small levels are the same `f64` ones. A
    /// coded level pushed to and read back gives the codes' values; a texel written from a
    /// coded pyramid gives the same file.
    #[test]
    fn coded_levels_read_back_as_f32_levels() {
        use crate::{extract, fixtures, ExtractParams, Pyramid, Source};
        let map = fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap();
        let pyr = extract(
            Source::Heights(&map),
            &ExtractParams::default(),
            &mut |_| {},
        )
        .unwrap();
        let dir = std::env::temp_dir().join(format!("meso-coded-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("g256.map");
        pyr.write(&path).unwrap();
        let full = Pyramid::read(&path).unwrap();
        let coded = Pyramid::read_coded(&path).unwrap();
        assert_eq!(full.levels.len(), coded.levels.len());
        let mut n_coded = 0;
        for (a, b) in full.levels.iter().zip(&coded.levels) {
            assert_eq!(a.lobe_start, b.lobe_start);
            assert_eq!(a.lobes.len(), b.lobes.len());
            let big = a.texels() >= COMPACT_TEXELS;
            assert_eq!(matches!(b.lobes, Lobes::Coded(_)), big);
            assert_eq!(matches!(b.horizon, Some(Horizons::Coded(_))), big);
            assert_eq!(a.lobes.is_compact(), b.lobes.is_compact());
            for i in 0..a.lobes.len() {
                assert_eq!(a.lobes.get(i), b.lobes.get(i), "lobe {i}");
            }
            let (ha, hb) = (a.horizon.as_ref().unwrap(), b.horizon.as_ref().unwrap());
            for t in 0..a.texels() {
                assert_eq!(ha.get(t), hb.get(t), "texel {t}");
            }
            if big {
                n_coded += 1;
                assert_eq!(b.lobes.bytes(), 11 * b.lobes.len());
                assert_eq!(hb.bytes(), HORIZON_CODE_BYTES * b.texels());
            }
        }
        assert_eq!(n_coded, 1, "level 0 (256²) is coded");
        assert_eq!(coded.to_bytes(), full.to_bytes());
        // Pushing to a coded level codes the lobe: it reads back as its codes decode.
        let mut l = Lobes::Coded(Vec::new());
        let p = full.levels[0].lobes.get(5);
        l.push(p);
        let q = l.get(0);
        assert!(q.axis.angle_between(p.axis) < 3e-6);
        assert_eq!(q.weight, f64::from(p.weight as f32));
        assert!((q.exponent - p.exponent).abs() <= 1e-3 * p.exponent);
        let mut h = Horizons::Coded(Vec::new());
        let s = full.levels[0].horizon.as_ref().unwrap().get(7);
        h.extend_from_slice(&[s]);
        assert_eq!(h.get(0), s, "a decoded horizon codes to itself");
        std::fs::remove_dir_all(&dir).ok();
    }

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
            mean: [0.1, 0.2, 0.3, 1.5, 0.05, 0.7, 1.1, 0.0],
            var: [0.01, 0.0, 0.002, 0.3, 0.2, 0.04, 0.0, 0.5],
        };
        let hb = Horizons::new(vec![h], true).get(0);
        assert_eq!(hb.weight, 16.0);
        for d in 0..HORIZON_DIRECTIONS {
            assert!((hb.mean[d] - h.mean[d]).abs() <= 6e-8 * h.mean[d]);
            assert!((hb.var[d] - h.var[d]).abs() <= 6e-8 * h.var[d]);
        }
        assert_eq!(Horizons::new(vec![h], false).get(0), h);
    }

    #[test]
    fn horizon_codes_keep_every_direction_in_its_slot() {
        use crate::format::{angle_decode, MEAN_SPAN, SD_SPAN};
        // Distinct codes in every slot, the largest too (4 095), and one above it (kept as
        // 4 095, as the decoder clamps).
        let mean: [u16; HORIZON_DIRECTIONS] = std::array::from_fn(|d| 17 + 511 * d as u16);
        let mut sd: [u16; HORIZON_DIRECTIONS] = std::array::from_fn(|d| 4_095 - 300 * d as u16);
        sd[3] = 5_000;
        let h = HorizonCode::new(3.5, mean, sd).to_stats();
        assert_eq!(h.weight, 3.5);
        for d in 0..HORIZON_DIRECTIONS {
            let m = angle_decode(mean[d], MEAN_SPAN) as f32;
            let s = angle_decode(sd[d].min(4_095), SD_SPAN);
            assert_eq!(h.mean[d], f64::from(m), "mean {d}");
            assert_eq!(h.var[d], f64::from((s * s) as f32), "sd {d}");
        }
    }
}
