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
}

impl Default for MerlSampling {
    fn default() -> Self {
        MerlSampling {
            max_theta_deg: 80.0,
            target: 30_000,
            position: CellPosition::Edge,
            spread_phi_h: true,
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

/// A set of samples to fit or to score a model on.
#[derive(Clone, Debug, Default)]
pub struct SampleSet {
    /// The samples.
    pub samples: Vec<Sample>,
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
        let set = SampleSet { samples: valid };
        let set = if opts.target == 0 || opts.target >= set.len() {
            set
        } else {
            set.stratified(opts.target)
        };
        stats.kept = set.len();
        (set, stats)
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
        }
    }

    /// A subsample of about `m` samples by a jittered stride (weights scaled by the stride so
    /// totals are preserved). Returns a clone if `m ≥ len`.
    #[must_use]
    pub fn stratified(&self, m: usize) -> SampleSet {
        let n = self.samples.len();
        if m == 0 || m >= n {
            return self.clone();
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
