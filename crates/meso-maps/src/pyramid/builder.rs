//! Assembling a level from its fitted rows, batch by batch: the lobes and horizon statistics
//! stored in `f64` or, on big levels, `f32` ([`crate::compact`]), allocations reserved up front
//! under the memory budget, the level's residual summed at the end, and what the next level
//! reads of it (for an `f32` level, its horizon statistics in `f64`).

use super::level_fit::RowOut;
use super::{Level, Residual};
use crate::compact::{Horizons, Lobes};
use crate::horizon::HorizonStats;

/// What a level hands to the next beside itself: its horizon statistics in `f64` when the
/// level keeps them in `f32`.
#[derive(Default)]
pub(super) struct Carry {
    pub(super) horizon: Option<Vec<HorizonStats>>,
}

/// A level being assembled from its rows, batch by batch.
pub(super) struct LevelBuilder {
    carry: Carry,
    lobes: Lobes,
    lstart: Vec<u32>,
    horizon: Option<Horizons>,
    residual: Vec<(f64, f64)>,
}

impl LevelBuilder {
    /// Room for `texels` texels of at most `max_per_texel` lobes each (reserved, not touched),
    /// stored in `f32` when `compact`, with an `f64` copy of the horizon statistics when
    /// `carry_horizon`; or the failed allocation.
    pub(super) fn new(
        texels: usize,
        max_per_texel: usize,
        has_horizon: bool,
        compact: bool,
        carry_horizon: bool,
    ) -> std::result::Result<LevelBuilder, meso_core::budget::AllocError> {
        use meso_core::budget::try_with_capacity;
        let mut lstart = try_with_capacity(texels + 1)?;
        lstart.push(0u32);
        let n = texels.saturating_mul(max_per_texel.max(1));
        Ok(LevelBuilder {
            carry: Carry {
                horizon: if carry_horizon {
                    Some(try_with_capacity(texels)?)
                } else {
                    None
                },
            },
            lobes: if compact {
                Lobes::F32(try_with_capacity(n)?)
            } else {
                Lobes::F64(try_with_capacity(n)?)
            },
            lstart,
            horizon: match (has_horizon, compact) {
                (false, _) => None,
                (true, true) => Some(Horizons::F32(try_with_capacity(texels)?)),
                (true, false) => Some(Horizons::F64(try_with_capacity(texels)?)),
            },
            residual: Vec::new(),
        })
    }

    /// Append a batch of rows (in order), freeing their buffers.
    pub(super) fn extend(&mut self, rows: Vec<RowOut>) {
        for ro in rows {
            for lc in &ro.lcount {
                self.lstart.push(self.lstart.last().unwrap() + lc);
            }
            self.lobes.extend_from_slice(&ro.lobes);
            if let Some(h) = &mut self.horizon {
                h.extend_from_slice(&ro.horizon);
            }
            if let Some(h) = &mut self.carry.horizon {
                h.extend_from_slice(&ro.horizon);
            }
            self.residual.extend_from_slice(&ro.residual);
        }
    }

    /// Level `k` (`cols × rows` texels) with its residual, and what the next level reads.
    pub(super) fn finish(mut self, k: usize, cols: usize, rows: usize) -> (Level, Carry) {
        self.lobes.shrink_to_fit();
        let level = Level {
            cols,
            rows,
            span: 1usize << k,
            lobe_start: self.lstart,
            lobes: self.lobes,
            horizon: self.horizon,
            residual: residual(&self.residual),
        };
        (level, self.carry)
    }
}

/// A level's residual from the NDF residuals and shading errors of its sampled texels.
pub(super) fn residual(errs: &[(f64, f64)]) -> Residual {
    Residual {
        mean: errs.iter().map(|e| e.0).sum::<f64>() / errs.len().max(1) as f64,
        max: errs.iter().map(|e| e.0).fold(0.0, f64::max),
        texels: errs.len() as u32,
        shading_mean: Some(errs.iter().map(|e| e.1).sum::<f64>() / errs.len().max(1) as f64),
        shading_max: Some(errs.iter().map(|e| e.1).fold(0.0, f64::max)),
    }
}

/// A level being written band by band (the streamed extraction, `extract_to_file`): only its
/// lobe count, its sampled residuals and, for the next level, its horizon statistics in `f64`.
#[derive(Default)]
pub(super) struct BandLevel {
    pub(super) lobes: usize,
    pub(super) residual: Vec<(f64, f64)>,
    pub(super) carry: Carry,
}

impl BandLevel {
    /// A level whose horizon statistics the next level reads when `carry_horizon`.
    pub(super) fn new(carry_horizon: bool) -> BandLevel {
        BandLevel {
            carry: Carry {
                horizon: carry_horizon.then(Vec::new),
            },
            ..BandLevel::default()
        }
    }

    /// A batch of rows (in order) of level `k` (`cols` texels a row) as a band of its own, in
    /// the level's precision (`compact`: `f32`, as [`LevelBuilder`] stores it); its residuals
    /// and horizon statistics kept for the level.
    pub(super) fn band(
        &mut self,
        rows: Vec<RowOut>,
        (k, cols): (usize, usize),
        has_h: bool,
        compact: bool,
    ) -> Level {
        let n = rows.len();
        let mut lobe_start = Vec::with_capacity(n * cols + 1);
        lobe_start.push(0u32);
        let mut lobes = Vec::new();
        let mut horizon = Vec::new();
        for ro in rows {
            for lc in &ro.lcount {
                lobe_start.push(lobe_start.last().unwrap() + lc);
            }
            lobes.extend_from_slice(&ro.lobes);
            horizon.extend_from_slice(&ro.horizon);
            if let Some(h) = &mut self.carry.horizon {
                h.extend_from_slice(&ro.horizon);
            }
            self.residual.extend_from_slice(&ro.residual);
        }
        self.lobes += lobes.len();
        Level {
            cols,
            rows: n,
            span: 1usize << k,
            lobe_start,
            lobes: Lobes::new(lobes, compact),
            horizon: has_h.then(|| Horizons::new(horizon, compact)),
            residual: Residual::default(),
        }
    }
}
