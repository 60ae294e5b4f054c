//! Queries on an extracted pyramid: a level by index, the top level, a texel's lobes and
//! horizon statistics (with the texel index checked), a level's bytes, and keeping levels'
//! lobes and horizon statistics in `f32` ([`crate::compact`]).

use super::{Level, Pyramid};
use crate::compact::{Horizons, Lobes};
use crate::error::{MapError, Result};
use crate::horizon::HorizonStats;
use meso_core::ndf::PhongLobe;

impl Level {
    /// The lobes of texel `(row, col)` in `f64` (on an `f32` level, the weights renormalised to
    /// sum to 1 in `f64`).
    pub fn texel_lobes(&self, row: usize, col: usize) -> Result<Vec<PhongLobe>> {
        let t = self.index(row, col)?;
        Ok(self.lobes_of(t))
    }
    /// The lobes of texel `t = row·cols + col` (as [`Level::texel_lobes`]).
    ///
    /// # Panics
    /// `t ≥ texels()`.
    #[must_use]
    pub fn lobes_of(&self, t: usize) -> Vec<PhongLobe> {
        let (a, b) = (self.lobe_start[t] as usize, self.lobe_start[t + 1] as usize);
        let mut out: Vec<PhongLobe> = self.lobes.range(a, b).collect();
        if self.lobes.is_compact() {
            let s: f64 = out.iter().map(|l| l.weight).sum();
            if s > 0.0 {
                for l in &mut out {
                    l.weight /= s;
                }
            }
        }
        out
    }
    /// The horizon statistics of texel `(row, col)` (`None` for normal maps).
    pub fn texel_horizon(&self, row: usize, col: usize) -> Result<Option<HorizonStats>> {
        let t = self.index(row, col)?;
        Ok(self.horizon.as_ref().map(|h| h.get(t)))
    }
    /// Keep the lobes and horizon statistics in `f32` ([`crate::compact`]); a no-op on a
    /// level already compact.
    pub fn compact(&mut self) {
        if let Lobes::F64(v) = &mut self.lobes {
            let v = std::mem::take(v);
            self.lobes = Lobes::new(v, true);
        }
        if let Some(Horizons::F64(v)) = &mut self.horizon {
            let v = std::mem::take(v);
            self.horizon = Some(Horizons::new(v, true));
        }
    }
    /// Bytes the level's lobes, lobe starts and horizon statistics occupy.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.lobes.bytes()
            + self.lobe_start.len() * 4
            + self.horizon.as_ref().map_or(0, Horizons::bytes)
    }
    fn index(&self, row: usize, col: usize) -> Result<usize> {
        if row >= self.rows {
            return Err(MapError::OutOfRange {
                what: "row",
                index: row,
                count: self.rows,
            });
        }
        if col >= self.cols {
            return Err(MapError::OutOfRange {
                what: "column",
                index: col,
                count: self.cols,
            });
        }
        Ok(row * self.cols + col)
    }
    /// Number of texels.
    #[must_use]
    pub fn texels(&self) -> usize {
        self.cols * self.rows
    }
}

impl Pyramid {
    /// The top level (one texel covering the whole map).
    #[must_use]
    pub fn top(&self) -> &Level {
        self.levels
            .last()
            .expect("a pyramid has at least one level")
    }
    /// Level `k`, or an error naming the range.
    pub fn level(&self, k: usize) -> Result<&Level> {
        self.levels.get(k).ok_or(MapError::OutOfRange {
            what: "level",
            index: k,
            count: self.levels.len(),
        })
    }
    /// Keep the levels of at least `min_texels` texels in `f32` ([`Level::compact`]).
    pub fn compact(&mut self, min_texels: usize) {
        for l in &mut self.levels {
            if l.texels() >= min_texels {
                l.compact();
            }
        }
    }
}
