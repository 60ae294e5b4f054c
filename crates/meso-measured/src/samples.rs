//! Data to fit: direction pairs with RGB BRDF values and quadrature weights, built from a MERL
//! table (with a documented subsample) or from CSV samples.

use crate::csv::CsvSample;
use crate::merl::{CellPosition, MerlTable};
use glam::DVec3;

/// One datum: a direction pair, the measured BRDF (1/sr) and a weight (the solid-angle measure it
/// stands for, any common unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Towards the light, unit, local frame.
    pub wi: DVec3,
    /// Towards the viewer, unit, local frame.
    pub wo: DVec3,
    /// BRDF in 1/sr per channel.
    pub rgb: [f64; 3],
    /// Weight of the sample in the error metrics (≥ 0).
    pub weight: f64,
}

/// How [`SampleSet::from_merl`] selects cells.
#[derive(Clone, Copy, Debug)]
pub struct MerlSampling {
    /// Keep cells with θi and θo below this angle, degrees (Ngan et al. use 80°).
    pub max_theta_deg: f64,
    /// Target number of cells; 0 keeps all valid cells. The subsample is a jittered stride through
    /// the valid cells in file order (stratified over θh, θd, φd).
    pub target: usize,
    /// The direction pair representing each cell.
    pub position: CellPosition,
    /// Rotate each cell's direction pair about the normal by a stratified azimuth φh (golden-ratio
    /// sequence) instead of φh = 0. A MERL table describes an *isotropic* BRDF, so every φh is
    /// equally valid; spreading them lets models with anisotropic freedom (tilted lobe axes) see
    /// the isotropy instead of one azimuthal slice.
    pub spread_phi_h: bool,
    /// At most this many valid cells *not* among the fitted ones are kept as a held-out set
    /// ([`SampleSet::held_out`], a jittered stride through the remaining cells); 0 = none,
    /// `usize::MAX` (default) = all of them (about a million cells for a full table, 80 bytes
    /// each: a lobe narrower than the fitted cells' spacing is hit by few cells, so a small
    /// held-out set can miss it too). Empty when `target` keeps every valid cell.
    pub held_out: usize,
}

impl Default for MerlSampling {
    fn default() -> Self {
        MerlSampling {
            max_theta_deg: 80.0,
            target: 30_000,
            position: CellPosition::Edge,
            spread_phi_h: true,
            held_out: usize::MAX,
        }
    }
}

/// Counts of what [`SampleSet::from_merl`] kept and skipped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MerlSamplingStats {
    /// Cells in the table.
    pub total: usize,
    /// Cells with at least one channel not measured (skipped).
    pub missing: usize,
    /// Measured cells beyond the θ limit (skipped).
    pub beyond_theta: usize,
    /// Valid cells (measured and within the limit).
    pub valid: usize,
    /// Cells kept.
    pub kept: usize,
}

/// Angular size of a MERL cell used as the data's resolution, radians: 1°, the θd and φd bins
/// (the θh bins are 0.85–1.8° wide for θh between 16° and 71°, finer only near the normal).
pub const MERL_CELL_SIZE: f64 = std::f64::consts::PI / 180.0;

/// Peak memory (bytes) of [`SampleSet::from_merl`] besides the table: up to every cell as a
/// [`Sample`] in the list of valid cells and again split into the kept and held-out cells, two
/// samples per cell (233 MB; `meso fit` of a MERL table with every cell valid measured 185 MB
/// peak RSS in all, table included).
#[must_use]
pub fn merl_sampling_bytes() -> u64 {
    2 * crate::merl::N_CELLS as u64 * std::mem::size_of::<Sample>() as u64
}

/// A set of samples to fit or to score a model on.
#[derive(Clone, Debug, Default)]
pub struct SampleSet {
    /// The samples.
    pub samples: Vec<Sample>,
    /// Angular size of one sample's cell in the source data, radians ([`MERL_CELL_SIZE`] for MERL
    /// tables); 0 when unknown (scattered samples such as CSV files). Enters
    /// [`SampleSet::angular_resolution`].
    pub cell_size: f64,
    /// Samples of the same data kept out of `samples` for validation: never fitted, scored in
    /// [`crate::fit::FitResult::held_out`] (a narrow lobe hiding between the fitted samples shows
    /// there). May be empty.
    pub held_out: Vec<Sample>,
}

/// Indices `⌊(j + jitter_j)·n/m⌋`, j < m: a deterministic jittered stride through `0..n`.
fn jittered_stride(n: usize, m: usize) -> impl Iterator<Item = usize> {
    let step = n as f64 / m as f64;
    (0..m).map(move |j| {
        let jitter = (j as f64 * 0.618_033_988_749_895).fract();
        (((j as f64 + jitter) * step) as usize).min(n - 1)
    })
}

impl SampleSet {
    /// Cells of a MERL table as samples, weighted by their solid-angle measure
    /// ([`crate::merl::MerlCell::measure`]); missing cells are skipped and counted.
    #[must_use]
    pub fn from_merl(table: &MerlTable, opts: &MerlSampling) -> (SampleSet, MerlSamplingStats) {
        let cos_max = opts.max_theta_deg.to_radians().cos();
        let mut stats = MerlSamplingStats::default();
        let mut valid = Vec::new();
        for c in table.cells(opts.position) {
            stats.total += 1;
            if c.rgb.iter().any(|&v| v < 0.0) {
                stats.missing += 1;
                continue;
            }
            if c.wi.z <= cos_max || c.wo.z <= cos_max {
                stats.beyond_theta += 1;
                continue;
            }
            let (wi, wo) = if opts.spread_phi_h {
                let a =
                    2.0 * std::f64::consts::PI * (c.index as f64 * 0.618_033_988_749_895).fract();
                let (sa, ca) = a.sin_cos();
                let rot = |w: DVec3| DVec3::new(ca * w.x - sa * w.y, sa * w.x + ca * w.y, w.z);
                (rot(c.wi), rot(c.wo))
            } else {
                (c.wi, c.wo)
            };
            valid.push(Sample {
                wi,
                wo,
                rgb: c.rgb,
                weight: c.measure,
            });
        }
        stats.valid = valid.len();
        let n = valid.len();
        let mut set = if opts.target == 0 || opts.target >= n {
            SampleSet {
                samples: valid,
                cell_size: MERL_CELL_SIZE,
                held_out: Vec::new(),
            }
        } else {
            let mut chosen = vec![false; n];
            for k in jittered_stride(n, opts.target) {
                chosen[k] = true;
            }
            let (mut kept, mut rest) = (Vec::new(), Vec::new());
            for (k, s) in valid.into_iter().enumerate() {
                if chosen[k] {
                    kept.push(s);
                } else {
                    rest.push(s);
                }
            }
            let strip = |samples: Vec<Sample>| SampleSet {
                samples,
                cell_size: MERL_CELL_SIZE,
                held_out: Vec::new(),
            };
            // Weights scaled so that each set's total is that of all valid cells.
            let (kept, rest) = (strip(kept), strip(rest));
            let scale = n as f64 / kept.len().max(1) as f64;
            let mut set = SampleSet {
                samples: kept
                    .samples
                    .into_iter()
                    .map(|mut s| {
                        s.weight *= scale;
                        s
                    })
                    .collect(),
                ..kept
            };
            if opts.held_out > 0 && !rest.is_empty() {
                let scale = n as f64 / rest.len() as f64;
                let rest = if opts.held_out >= rest.len() {
                    rest.samples
                } else {
                    rest.stratified(opts.held_out).samples
                };
                set.held_out = rest
                    .into_iter()
                    .map(|mut s| {
                        s.weight *= scale;
                        s
                    })
                    .collect();
            }
            set
        };
        set.cell_size = MERL_CELL_SIZE;
        stats.kept = set.len();
        (set, stats)
    }

    /// [`SampleSet::from_merl`] of the table [`crate::merl::MerlTable::from_fn`] would make of
    /// `f` — the same samples, weights and values, bit for bit — evaluating `f` only at the
    /// cells the sampling keeps (fitted and held out: with the defaults 50 000 of the table's
    /// 1.46 M cells), in parallel. What a material's engine parameters are fitted to
    /// ([`crate::engine::of_material`]).
    ///
    /// `done` is called once per cell evaluated (from the worker threads), for a progress bar:
    /// there are `samples.len() + held_out.len()` of them.
    ///
    /// # Errors
    /// [`MerlError::BadValue`](crate::merl::MerlError::BadValue) when `f` is negative, NaN or infinite at a kept cell.
    pub fn from_merl_fn<F>(
        pos: CellPosition,
        opts: &MerlSampling,
        f: F,
        done: &(dyn Fn() + Sync),
    ) -> Result<(SampleSet, MerlSamplingStats), crate::merl::MerlError>
    where
        F: Fn(DVec3, DVec3) -> [f64; 3] + Sync,
    {
        use crate::merl::{cell_angles, MerlError, MerlTable, N_PHI_D, N_THETA_D};
        use rayon::prelude::*;
        // Sample a table of cell indices: the selection depends on which cells are measured
        // (all above the horizon, as `from_fn` makes them) and on their order, not on values.
        let index = MerlTable::cell_index_table(pos);
        let (mut set, stats) = SampleSet::from_merl(
            &index,
            &MerlSampling {
                position: pos,
                ..*opts
            },
        );
        let fill = |s: &mut Sample| -> Result<(), MerlError> {
            let k = s.rgb[0] as usize;
            let (ih, id, ip) = (
                k / (N_THETA_D * N_PHI_D),
                (k / N_PHI_D) % N_THETA_D,
                k % N_PHI_D,
            );
            // The cell's own pair (φh = 0), as `from_fn` evaluates it; the sample keeps its
            // turned copy (`spread_phi_h`), as `from_merl` gives it.
            let (wi, wo) = crate::rusinkiewicz::dirs_from_half_diff(cell_angles(ih, id, ip, pos));
            let v = f(wi, wo);
            if let Some(&value) = v.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                return Err(MerlError::BadValue { ih, id, ip, value });
            }
            s.rgb = v;
            done();
            Ok(())
        };
        set.samples.par_iter_mut().try_for_each(fill)?;
        set.held_out.par_iter_mut().try_for_each(fill)?;
        Ok((set, stats))
    }

    /// CSV samples, each with weight 1 (the file says nothing about its sampling density).
    #[must_use]
    pub fn from_csv(samples: &[CsvSample]) -> SampleSet {
        SampleSet {
            samples: samples
                .iter()
                .map(|s| Sample {
                    wi: s.wi(),
                    wo: s.wo(),
                    rgb: s.rgb,
                    weight: 1.0,
                })
                .collect(),
            cell_size: 0.0,
            held_out: Vec::new(),
        }
    }

    /// Move every `every`-th sample (indices `every − 1`, `2·every − 1`, …) to
    /// [`SampleSet::held_out`] (appended); `every < 2` changes nothing. For scattered data
    /// (CSV), where no unfitted cells exist.
    #[must_use]
    pub fn hold_out_every(self, every: usize) -> SampleSet {
        if every < 2 {
            return self;
        }
        let mut held_out = self.held_out;
        let mut samples = Vec::with_capacity(self.samples.len());
        for (k, s) in self.samples.into_iter().enumerate() {
            if k % every == every - 1 {
                held_out.push(s);
            } else {
                samples.push(s);
            }
        }
        SampleSet {
            samples,
            cell_size: self.cell_size,
            held_out,
        }
    }

    /// The data's angular resolution δ (radians): the larger of [`SampleSet::cell_size`] and the
    /// mean spacing `sqrt(2π/N)` of `N` samples' half vectors spread over the hemisphere (2π sr).
    /// A lobe narrower than δ can sit between the samples unseen; [`crate::fit::fit`] caps the
    /// lobe sharpness by it (`κ ≤ 1/δ²`). Examples: 30 000 MERL cells, δ = 1° (the cell size;
    /// `sqrt(2π/N)` = 0.83°); 6 000 CSV samples, δ = 1.86°; 1 000 CSV samples, δ = 4.5°.
    #[must_use]
    pub fn angular_resolution(&self) -> f64 {
        let n = self.samples.len().max(1) as f64;
        self.cell_size.max((2.0 * std::f64::consts::PI / n).sqrt())
    }

    /// The data's angular resolution at the surface normal (radians): the spacing of the
    /// samples' half vectors around the normal, `r_n·sqrt(π/n)` for the `n = clamp(N/100, 10,
    /// 300)` half vectors nearest to the normal, `r_n` the angle of the n-th (n points in a cap of
    /// area `πr²`). What caps lobes held on the normal ([`crate::fit::LobeAxes::Normal`]); MERL
    /// tables sample θh finely there (the first bins are 0.01° wide), so it is far below
    /// [`SampleSet::angular_resolution`] for them. 0 for an empty set.
    #[must_use]
    pub fn angular_resolution_at_normal(&self) -> f64 {
        let mut angles: Vec<f64> = self
            .samples
            .iter()
            .filter_map(|s| {
                let h = (s.wi + s.wo).try_normalize()?;
                Some(h.z.clamp(-1.0, 1.0).acos())
            })
            .collect();
        if angles.is_empty() {
            return 0.0;
        }
        let n = (angles.len() / 100).clamp(10, 300).min(angles.len());
        let (_, r, _) = angles.select_nth_unstable_by(n - 1, f64::total_cmp);
        *r * (std::f64::consts::PI / n as f64).sqrt()
    }

    /// A subsample of about `m` samples by a jittered stride (weights scaled by the stride so
    /// totals are preserved), with the same `cell_size` and no held-out samples. Returns a copy
    /// (without held-out samples) if `m ≥ len`.
    #[must_use]
    pub fn stratified(&self, m: usize) -> SampleSet {
        let n = self.samples.len();
        if m == 0 || m >= n {
            return SampleSet {
                samples: self.samples.clone(),
                cell_size: self.cell_size,
                held_out: Vec::new(),
            };
        }
        let scale = n as f64 / m as f64;
        SampleSet {
            samples: jittered_stride(n, m)
                .map(|k| {
                    let mut s = self.samples[k];
                    s.weight *= scale;
                    s
                })
                .collect(),
            cell_size: self.cell_size,
            held_out: Vec::new(),
        }
    }

    /// The held-out samples as a set of their own (same `cell_size`), for scoring.
    #[must_use]
    pub fn held_out_set(&self) -> SampleSet {
        SampleSet {
            samples: self.held_out.clone(),
            cell_size: self.cell_size,
            held_out: Vec::new(),
        }
    }

    /// Number of samples.
    #[must_use]
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether the set is empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}
