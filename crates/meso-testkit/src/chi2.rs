//! Chi-square goodness-of-fit test of a direction sampler against the density it claims.
//!
//! The method of Mitsuba 3's `ChiSquareTest` and pbrt-v4's BSDF tests:
//!
//! 1. Draw `samples` directions and histogram them over `n_theta × n_phi` cells uniform in
//!    θ ∈ [0, π] (from +z) and φ ∈ [0, 2π) (from +x towards +y) — the whole sphere.
//! 2. Integrate the claimed pdf over every cell (composite Gauss–Legendre in `cos θ` and φ: each
//!    cell is split into `cell_subdivisions²` sub-cells with 3 × 3 nodes each), giving the expected
//!    count `samples · ∫_cell pdf dω`.
//! 3. Any sample in a cell whose integrated pdf is zero fails the test at once (the sampler puts
//!    mass where the pdf says there is none, or a peak is narrower than the sub-cells).
//! 4. Cells with expected count below `min_expected` are pooled into one; Pearson's statistic
//!    `Σ (O − E)² / E` over the remaining cells and the pool, with `cells − 1` degrees of freedom.
//!    This step alone is [`pearson`], for tests that bin on a grid of their own with exact cell
//!    probabilities (a tabulated NDF's sampler on its equal-area grid).
//! 5. The p-value `Q(dof/2, χ²/2)` is compared with the Šidák-corrected level
//!    `1 − (1 − significance)^{1/tests_run}`; below it, the sampler is rejected.
//!
//! A sampler may decline to produce a sample (`None`, e.g. a direction below the horizon that is
//! absorbed); its pdf must then integrate to the probability of `Some`. The `None` outcome is one
//! more category of the test, with expected count `samples · (1 − ∫ pdf)`; set
//! [`ChiSquareTest::normalization_tolerance`] to `None` for such defective densities.
//!
//! Keep `n_theta` even when the pdf is discontinuous at the horizon, so that `z = 0` is a cell
//! edge and the cell integrals stay accurate.

use crate::Rng;
use glam::DVec3;
use std::f64::consts::PI;
use std::fmt;

/// Configuration of a chi-square test; see the [module docs](self). All fields are public so that
/// a test can override a few with `..Default::default()`.
#[derive(Clone, Debug)]
pub struct ChiSquareTest {
    /// Number of θ bins over `[0, π]` (default 80).
    pub n_theta: usize,
    /// Number of φ bins over `[0, 2π)` (default 160).
    pub n_phi: usize,
    /// Number of calls to the sampler (default 1 000 000).
    pub samples: usize,
    /// Significance level of one test before correction (default 0.01).
    pub significance: f64,
    /// Number of tests in the family, for the Šidák correction (default 1).
    pub tests_run: usize,
    /// Cells with a smaller expected count are pooled (default 5).
    pub min_expected: f64,
    /// Seed of the random-number generator handed to the sampler.
    pub seed: u64,
    /// Each cell is split into `cell_subdivisions²` sub-cells (in `cos θ` and φ), each integrated
    /// with a 3 × 3 Gauss–Legendre rule (default 4). Raise it for peaks narrower than a cell.
    pub cell_subdivisions: usize,
    /// Reject when `|∫ pdf dω − 1|` exceeds this (default `Some(1e-3)`); `None` skips the check,
    /// for samplers that return `None` with positive probability.
    pub normalization_tolerance: Option<f64>,
}

impl Default for ChiSquareTest {
    fn default() -> Self {
        ChiSquareTest {
            n_theta: 80,
            n_phi: 160,
            samples: 1_000_000,
            significance: 0.01,
            tests_run: 1,
            min_expected: 5.0,
            seed: 0x6d65_736f_5eed,
            cell_subdivisions: 4,
            normalization_tolerance: Some(1e-3),
        }
    }
}

/// The cell that contributes most to the statistic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellResidual {
    /// θ range of the cell, radians.
    pub theta: (f64, f64),
    /// φ range of the cell, radians.
    pub phi: (f64, f64),
    /// Observed count.
    pub observed: f64,
    /// Expected count.
    pub expected: f64,
}

/// The outcome of [`ChiSquareTest::run_report`].
#[derive(Clone, Debug)]
pub struct ChiSquareReport {
    /// Pearson's statistic `Σ (O − E)² / E`.
    pub statistic: f64,
    /// Degrees of freedom (cells used − 1).
    pub dof: usize,
    /// `Pr[χ²_dof ≥ statistic]`.
    pub p_value: f64,
    /// The Šidák-corrected significance level the p-value is compared with.
    pub threshold: f64,
    /// `∫_{S²} pdf dω`, the sum of the cell integrals (≈ 1 for a normalised density).
    pub pdf_integral: f64,
    /// Number of sampler calls.
    pub samples: usize,
    /// Number of calls that returned `None`.
    pub none_samples: usize,
    /// Number of categories (cells, and the `None` outcome) merged into the pool of small ones.
    pub pooled_cells: usize,
    /// The cell with the largest contribution `(O − E)²/E` (unpooled cells only).
    pub worst_cell: Option<CellResidual>,
    /// Observed counts, `n_theta × n_phi`, θ-major.
    pub observed: Vec<f64>,
    /// Expected counts, `n_theta × n_phi`, θ-major.
    pub expected: Vec<f64>,
    /// Why the test failed, or `None` when it passed.
    pub failure: Option<String>,
}

impl ChiSquareReport {
    /// Did the sampler pass?
    #[must_use]
    pub fn passed(&self) -> bool {
        self.failure.is_none()
    }
}

impl fmt::Display for ChiSquareReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.failure {
            None => write!(f, "chi-square test passed")?,
            Some(why) => write!(f, "chi-square test FAILED: {why}")?,
        }
        write!(
            f,
            "\n  χ² = {:.2}, dof = {}, p = {:.4e} (threshold {:.4e}); ∫pdf = {:.6}; \
             {} samples ({} None), {} cells pooled",
            self.statistic,
            self.dof,
            self.p_value,
            self.threshold,
            self.pdf_integral,
            self.samples,
            self.none_samples,
            self.pooled_cells
        )?;
        if let Some(w) = &self.worst_cell {
            write!(
                f,
                "\n  worst cell θ ∈ [{:.2}°, {:.2}°], φ ∈ [{:.2}°, {:.2}°]: observed {}, expected {:.1}",
                w.theta.0.to_degrees(),
                w.theta.1.to_degrees(),
                w.phi.0.to_degrees(),
                w.phi.1.to_degrees(),
                w.observed,
                w.expected
            )?;
        }
        Ok(())
    }
}

impl ChiSquareTest {
    /// Run the test: `Ok(report)` when the sampler passes, `Err(message)` (the report's text)
    /// when it is rejected or the test cannot be carried out.
    ///
    /// # Errors
    /// See [`ChiSquareReport::failure`].
    pub fn run(
        &self,
        sample: impl FnMut(&mut Rng) -> Option<DVec3>,
        pdf: impl Fn(DVec3) -> f64 + Sync,
    ) -> Result<ChiSquareReport, String> {
        let report = self.run_report(sample, pdf);
        if report.passed() {
            Ok(report)
        } else {
            Err(report.to_string())
        }
    }

    /// The Šidák-corrected significance level `1 − (1 − significance)^{1/tests_run}`.
    #[must_use]
    pub fn threshold(&self) -> f64 {
        1.0 - (1.0 - self.significance).powf(1.0 / self.tests_run.max(1) as f64)
    }

    /// `∫ pdf dω` over each cell of this test's grid (`n_theta × n_phi`, θ-major).
    #[must_use]
    pub fn cell_integrals(&self, pdf: impl Fn(DVec3) -> f64 + Sync) -> Vec<f64> {
        cell_integrals(&pdf, self.n_theta, self.n_phi, self.cell_subdivisions)
    }

    /// Run the test and return the full report, whether it passed or not.
    #[must_use]
    pub fn run_report(
        &self,
        sample: impl FnMut(&mut Rng) -> Option<DVec3>,
        pdf: impl Fn(DVec3) -> f64 + Sync,
    ) -> ChiSquareReport {
        let mut report = ChiSquareReport {
            statistic: 0.0,
            dof: 0,
            p_value: 0.0,
            threshold: self.threshold(),
            pdf_integral: f64::NAN,
            samples: self.samples,
            none_samples: 0,
            pooled_cells: 0,
            worst_cell: None,
            observed: vec![0.0; self.n_theta * self.n_phi],
            expected: Vec::new(),
            failure: None,
        };
        if let Err(why) = self.evaluate(&mut report, sample, pdf) {
            report.failure = Some(why);
        }
        report
    }

    /// The steps of [`run_report`](Self::run_report), filling `report`; `Err` is the
    /// failure (the report keeps what the steps before it found).
    fn evaluate(
        &self,
        report: &mut ChiSquareReport,
        sample: impl FnMut(&mut Rng) -> Option<DVec3>,
        pdf: impl Fn(DVec3) -> f64 + Sync,
    ) -> Result<(), String> {
        let (nt, np) = (self.n_theta, self.n_phi);
        if nt == 0 || np == 0 || self.samples == 0 || self.cell_subdivisions == 0 {
            return Err("empty grid, no samples or no sub-cells".into());
        }
        // 1. Histogram the samples.
        self.histogram(report, sample)?;
        // 2. Expected counts.
        self.expected_counts(report, &pdf)?;
        // 3. Samples where the pdf is zero.
        check_zero_pdf_cells(report, nt, np)?;
        // The `None` outcome is one more category, expected `samples · (1 − ∫ pdf)`. When the
        // pdf integrates to ~1 its expected count is ~0 and it is pooled like any tiny cell.
        let n = self.samples as f64;
        let none_expected = (n * (1.0 - report.pdf_integral)).max(0.0);
        let none_observed = report.none_samples as f64;
        // 4. Pool small cells (ascending expected count, as Mitsuba), accumulate the statistic.
        let bins = self.pool(report, none_observed, none_expected);
        score(report, &bins, nt, np)?;
        // 5. Decide.
        self.decide(report, none_observed, none_expected)
    }

    /// Step 1: draw the samples into `report.observed` (counting `None`s); a sample that is
    /// not a unit vector fails the test.
    fn histogram(
        &self,
        report: &mut ChiSquareReport,
        mut sample: impl FnMut(&mut Rng) -> Option<DVec3>,
    ) -> Result<(), String> {
        let (nt, np) = (self.n_theta, self.n_phi);
        let mut rng = crate::rng(self.seed);
        for k in 0..self.samples {
            let Some(d) = sample(&mut rng) else {
                report.none_samples += 1;
                continue;
            };
            let len = d.length();
            if !(d.is_finite() && (len - 1.0).abs() <= 1e-3) {
                return Err(format!(
                    "sample {k} is not a unit vector: {d} (length {len})"
                ));
            }
            let (i, j) = cell_of(d / len, nt, np);
            report.observed[i * np + j] += 1.0;
        }
        Ok(())
    }

    /// Step 2: the pdf's integral over every cell, the expected counts and the total; a
    /// negative or non-finite cell integral fails the test.
    fn expected_counts(
        &self,
        report: &mut ChiSquareReport,
        pdf: &(impl Fn(DVec3) -> f64 + Sync),
    ) -> Result<(), String> {
        let (nt, np) = (self.n_theta, self.n_phi);
        let integrals = cell_integrals(pdf, nt, np, self.cell_subdivisions);
        if let Some(c) = integrals.iter().position(|v| !v.is_finite() || *v < 0.0) {
            let (lo, hi) = cell_bounds(c, nt, np);
            return Err(format!(
                "the pdf integrates to {} (negative or not finite) over the cell θ ∈ [{:.2}°, {:.2}°], \
                 φ ∈ [{:.2}°, {:.2}°]",
                integrals[c],
                lo.0.to_degrees(),
                hi.0.to_degrees(),
                lo.1.to_degrees(),
                hi.1.to_degrees()
            ));
        }
        report.pdf_integral = integrals.iter().sum();
        let n = self.samples as f64;
        report.expected = integrals.iter().map(|v| v * n).collect();
        Ok(())
    }

    /// Step 4: the categories left after pooling the cells (and the `None` outcome) whose
    /// expected count is below `min_expected`, as (observed, expected, cell), ascending in
    /// expected count; counts the pooled cells in the report.
    fn pool(
        &self,
        report: &mut ChiSquareReport,
        none_observed: f64,
        none_expected: f64,
    ) -> Vec<(f64, f64, Option<usize>)> {
        let mut order: Vec<usize> = (0..self.n_theta * self.n_phi).collect();
        order.sort_by(|&a, &b| report.expected[a].total_cmp(&report.expected[b]));
        let categories = order
            .iter()
            .map(|&c| (report.observed[c], report.expected[c], Some(c)))
            .chain(std::iter::once((none_observed, none_expected, None)));
        let (bins, pooled) = pool_categories(categories, self.min_expected);
        report.pooled_cells += pooled;
        bins
    }

    /// Step 5: the normalization check (when asked for) and the p-value against the
    /// threshold.
    fn decide(
        &self,
        report: &ChiSquareReport,
        none_observed: f64,
        none_expected: f64,
    ) -> Result<(), String> {
        if let Some(tol) = self.normalization_tolerance {
            if (report.pdf_integral - 1.0).abs() > tol {
                return Err(format!(
                    "the pdf integrates to {:.6} over the sphere, not 1 (tolerance {tol})",
                    report.pdf_integral
                ));
            }
        }
        if report.p_value.is_nan() || report.p_value < report.threshold {
            let mut why = format!(
                "the samples do not follow the pdf: p-value {:.3e} < {:.3e}",
                report.p_value, report.threshold
            );
            if (none_observed - none_expected).abs() > 5.0 * none_expected.sqrt() + 5.0 {
                why += &format!(
                    "; the sampler returned None {none_observed} times where the pdf's missing \
                     mass {:.3e} predicts {none_expected:.1}",
                    1.0 - report.pdf_integral
                );
            }
            return Err(why);
        }
        Ok(())
    }
}

/// Step 3: fail when samples fell in a cell where the pdf integrates to zero.
fn check_zero_pdf_cells(report: &ChiSquareReport, nt: usize, np: usize) -> Result<(), String> {
    for (c, (&o, &e)) in report.observed.iter().zip(&report.expected).enumerate() {
        if e == 0.0 && o > 0.0 {
            let (lo, hi) = cell_bounds(c, nt, np);
            return Err(format!(
                "{o} samples fell in the cell θ ∈ [{:.2}°, {:.2}°], φ ∈ [{:.2}°, {:.2}°] where \
                 the pdf integrates to 0 (if the pdf is positive there, raise cell_subdivisions)",
                lo.0.to_degrees(),
                hi.0.to_degrees(),
                lo.1.to_degrees(),
                hi.1.to_degrees()
            ));
        }
    }
    Ok(())
}

/// Pearson's statistic over `bins`, the worst regular cell, the degrees of freedom and the
/// p-value, into `report`; fewer than two categories fail the test.
fn score(
    report: &mut ChiSquareReport,
    bins: &[(f64, f64, Option<usize>)],
    nt: usize,
    np: usize,
) -> Result<(), String> {
    let mut worst: Option<(f64, usize)> = None;
    for &(o, e, cell) in bins {
        let contrib = (o - e) * (o - e) / e;
        if let Some(c) = cell {
            if worst.is_none_or(|(w, _)| contrib > w) {
                worst = Some((contrib, c));
            }
        }
    }
    report.worst_cell = worst.map(|(_, c)| {
        let (lo, hi) = cell_bounds(c, nt, np);
        CellResidual {
            theta: (lo.0, hi.0),
            phi: (lo.1, hi.1),
            observed: report.observed[c],
            expected: report.expected[c],
        }
    });
    report.statistic = statistic(bins);
    let p = pearson_of(bins, 0)?;
    report.dof = p.dof;
    report.p_value = p.p_value;
    Ok(())
}

/// Pearson's χ² test of counts over categories: what the harness does after binning (steps 4
/// and 5 of the [module docs](self) without the significance decision), for tests that bin on a
/// grid of their own with exact cell probabilities (e.g. a tabulated NDF's sampler on its own
/// equal-area grid).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pearson {
    /// `Σ (O − E)² / E` over the categories left after pooling.
    pub statistic: f64,
    /// Degrees of freedom: categories left after pooling − 1.
    pub dof: usize,
    /// `Pr[χ²_dof ≥ statistic]`.
    pub p_value: f64,
    /// Number of categories merged into the pool of small ones.
    pub pooled: usize,
}

/// Pearson's χ² test of `observed` counts against `expected` counts (same length, one entry a
/// category; expected counts are `samples · probability`): categories whose expected count is
/// below `min_expected` are pooled exactly as [`ChiSquareTest`] pools its cells (ascending
/// expected count; an under-filled pool merged into the smallest category), then Pearson's
/// statistic and its p-value. `Err` when the lengths differ, an expected count is negative or
/// not finite, a category with no expected count has observations (the sampler puts mass where
/// the probabilities say there is none), or fewer than two categories are left.
pub fn pearson(observed: &[f64], expected: &[f64], min_expected: f64) -> Result<Pearson, String> {
    if observed.len() != expected.len() {
        return Err(format!(
            "{} observed counts against {} expected ones",
            observed.len(),
            expected.len()
        ));
    }
    if let Some(c) = expected.iter().position(|e| !e.is_finite() || *e < 0.0) {
        return Err(format!("expected count {} of category {c}", expected[c]));
    }
    if let Some(c) = (0..observed.len()).find(|&c| expected[c] == 0.0 && observed[c] > 0.0) {
        return Err(format!(
            "{} samples in category {c}, whose probability is 0",
            observed[c]
        ));
    }
    let mut order: Vec<usize> = (0..observed.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (bins, pooled) = pool_categories(
        order.iter().map(|&c| (observed[c], expected[c], Some(c))),
        min_expected,
    );
    pearson_of(&bins, pooled)
}

/// Pool `categories` (observed, expected, cell), taken in the order given: a category whose
/// expected count is below `min_expected`, or any while the pool is started but under-filled,
/// goes into the pool. Returns the categories left (ascending in expected count; the pool one of
/// them, as cell `None`, or merged into the smallest when it stays under-filled) and how many
/// were pooled.
fn pool_categories(
    categories: impl Iterator<Item = (f64, f64, Option<usize>)>,
    min_expected: f64,
) -> (Vec<(f64, f64, Option<usize>)>, usize) {
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    let mut bins: Vec<(f64, f64, Option<usize>)> = Vec::new();
    let mut pooled = 0;
    for (o, e, cell) in categories {
        if e == 0.0 && o == 0.0 {
            continue;
        }
        if e < min_expected || (pool_o > 0.0 && pool_e < min_expected) {
            pool_o += o;
            pool_e += e;
            pooled += 1;
        } else {
            bins.push((o, e, cell));
        }
    }
    bins.sort_by(|a, b| a.1.total_cmp(&b.1));
    if pool_e > 0.0 || pool_o > 0.0 {
        if pool_e >= min_expected || bins.is_empty() {
            bins.push((pool_o, pool_e, None));
        } else {
            // An under-filled pool is merged into the smallest regular category rather than
            // counted as a category of its own (which would add a degree of freedom that
            // carries no information).
            bins[0].0 += pool_o;
            bins[0].1 += pool_e;
            bins[0].2 = None;
            pooled += 1;
        }
    }
    (bins, pooled)
}

/// Pearson's statistic `Σ (O − E)² / E` over `bins` (observed, expected, cell).
fn statistic(bins: &[(f64, f64, Option<usize>)]) -> f64 {
    bins.iter().map(|&(o, e, _)| (o - e) * (o - e) / e).sum()
}

/// The statistic, degrees of freedom and p-value of pooled `bins`; fewer than two fail.
fn pearson_of(bins: &[(f64, f64, Option<usize>)], pooled: usize) -> Result<Pearson, String> {
    let cells = bins.len();
    if cells < 2 {
        return Err(format!(
            "only {cells} cell(s) left after pooling: too few samples for this grid"
        ));
    }
    let statistic = statistic(bins);
    let dof = cells - 1;
    Ok(Pearson {
        statistic,
        dof,
        p_value: crate::gamma::chi_square_sf(statistic, dof),
        pooled,
    })
}

/// The cell `(θ index, φ index)` of a unit direction.
fn cell_of(d: DVec3, nt: usize, np: usize) -> (usize, usize) {
    let theta = d.z.clamp(-1.0, 1.0).acos();
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let i = ((theta / PI * nt as f64) as usize).min(nt - 1);
    let j = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
    (i, j)
}

/// `((θ0, φ0), (θ1, φ1))` of cell `c` (θ-major index).
fn cell_bounds(c: usize, nt: usize, np: usize) -> ((f64, f64), (f64, f64)) {
    let (i, j) = (c / np, c % np);
    let dt = PI / nt as f64;
    let dp = 2.0 * PI / np as f64;
    (
        (i as f64 * dt, j as f64 * dp),
        ((i + 1) as f64 * dt, (j + 1) as f64 * dp),
    )
}

/// 3-point Gauss–Legendre on `[0, 1]`: nodes and weights.
const GL3_X: [f64; 3] = [
    0.5 - 0.387_298_334_620_741_7, // (1 − √(3/5))/2
    0.5,
    0.5 + 0.387_298_334_620_741_7,
];
const GL3_W: [f64; 3] = [5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0];

/// `∫_cell pdf dω` over the `nt × np` (θ, φ) grid, θ-major. Each cell is split into `sub × sub`
/// sub-cells uniform in `z = cos θ` and φ, each integrated by 3 × 3 Gauss–Legendre (`dω = dz dφ`).
/// Rows are shared out over the available threads.
pub(crate) fn cell_integrals(
    pdf: &(impl Fn(DVec3) -> f64 + Sync),
    nt: usize,
    np: usize,
    sub: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; nt * np];
    if nt == 0 || np == 0 || sub == 0 {
        return out;
    }
    // Azimuthal nodes of one row: for each φ cell, sub × 3 (cos φ, sin φ, weight).
    let dphi = 2.0 * PI / np as f64;
    let phi_nodes: Vec<(f64, f64, f64)> = (0..np)
        .flat_map(|j| {
            (0..sub).flat_map(move |s| {
                GL3_X.iter().zip(GL3_W).map(move |(&x, w)| {
                    let phi = dphi * (j as f64 + (s as f64 + x) / sub as f64);
                    let (sp, cp) = phi.sin_cos();
                    (cp, sp, w * dphi / sub as f64)
                })
            })
        })
        .collect();
    let per_cell = sub * 3;
    let row = |i: usize, out_row: &mut [f64]| {
        let z_hi = (PI * i as f64 / nt as f64).cos();
        let z_lo = if i + 1 == nt {
            -1.0
        } else {
            (PI * (i + 1) as f64 / nt as f64).cos()
        };
        let z_hi = if i == 0 { 1.0 } else { z_hi };
        let dz = z_hi - z_lo;
        for s in 0..sub {
            for (&x, &wz) in GL3_X.iter().zip(&GL3_W) {
                let z = z_lo + dz * (s as f64 + x) / sub as f64;
                let wz = wz * dz / sub as f64;
                let r = (1.0 - z * z).max(0.0).sqrt();
                for (j, cell) in out_row.iter_mut().enumerate() {
                    let mut acc = 0.0;
                    for &(cp, sp, wp) in &phi_nodes[j * per_cell..(j + 1) * per_cell] {
                        acc += wp * pdf(DVec3::new(r * cp, r * sp, z));
                    }
                    *cell += wz * acc;
                }
            }
        }
    };
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(nt);
    if threads <= 1 {
        for (i, out_row) in out.chunks_mut(np).enumerate() {
            row(i, out_row);
        }
    } else {
        let rows_per = nt.div_ceil(threads);
        std::thread::scope(|scope| {
            for (t, chunk) in out.chunks_mut(rows_per * np).enumerate() {
                let row = &row;
                scope.spawn(move || {
                    for (k, out_row) in chunk.chunks_mut(np).enumerate() {
                        row(t * rows_per + k, out_row);
                    }
                });
            }
        });
    }
    out
}

/// `∫_{S²} pdf dω` by the cell-wise rule of the chi-square test (`n_theta × n_phi` cells, each
/// split into `subdivisions²` sub-cells with 3 × 3 Gauss–Legendre nodes). Handles a jump at the
/// horizon exactly when `n_theta` is even, and sharp peaks once the sub-cells resolve them.
#[must_use]
pub fn check_normalization(
    pdf: impl Fn(DVec3) -> f64 + Sync,
    n_theta: usize,
    n_phi: usize,
    subdivisions: usize,
) -> f64 {
    cell_integrals(&pdf, n_theta, n_phi, subdivisions)
        .iter()
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_cover_the_sphere() {
        let (nt, np) = (8, 16);
        for (d, expect) in [
            (DVec3::Z, (0, 0)),
            (DVec3::new(0.0, 0.0, -1.0), (7, 0)),
            (DVec3::X, (4, 0)),
            (DVec3::Y, (4, 4)),
            (-DVec3::X, (4, 8)),
            (DVec3::new(1.0, -1e-12, 0.0).normalize(), (4, 15)),
        ] {
            assert_eq!(cell_of(d, nt, np), expect, "{d}");
        }
        // Cell areas: ∫ 1 dω over each cell = Δφ (cos θ0 − cos θ1), exactly.
        let areas = cell_integrals(&|_| 1.0, nt, np, 1);
        for (c, a) in areas.iter().enumerate() {
            let (lo, hi) = cell_bounds(c, nt, np);
            let exact = (hi.1 - lo.1) * (lo.0.cos() - hi.0.cos());
            assert!((a - exact).abs() < 1e-15, "cell {c}");
        }
        let total: f64 = areas.iter().sum();
        assert!((total - 4.0 * PI).abs() < 1e-13);
    }

    #[test]
    fn normalization_of_known_densities() {
        let uniform = check_normalization(|_| 0.25 / PI, 80, 160, 1);
        assert!((uniform - 1.0).abs() < 1e-12);
        let cosine = check_normalization(|d| d.z.max(0.0) / PI, 80, 160, 1);
        assert!((cosine - 1.0).abs() < 1e-12, "{cosine}");
        // A very sharp Phong peak (η = 10⁴, about 1.1° wide) off the grid's axes.
        let lobe = meso_core::ndf::PhongLobe::new(DVec3::new(0.2, 0.1, 0.9), 1.0, 1e4);
        let sharp = check_normalization(|d| lobe.unit_density(d), 80, 160, 4);
        assert!((sharp - 1.0).abs() < 1e-6, "{sharp}");
    }

    /// Counts drawn from known probabilities pass; the same counts against other
    /// probabilities fail; small categories are pooled; bad input is refused.
    #[test]
    fn pearson_accepts_the_truth_and_rejects_a_lie() {
        use rand::RngExt as _;
        let probs: Vec<f64> = (0..40).map(|k| (1 + k % 7) as f64).collect();
        let total: f64 = probs.iter().sum();
        let probs: Vec<f64> = probs.iter().map(|p| p / total).collect();
        let mut rng = crate::rng(5);
        let n = 100_000;
        let mut counts = vec![0.0; probs.len()];
        for _ in 0..n {
            let mut u: f64 = rng.random();
            let c = probs
                .iter()
                .position(|p| {
                    u -= p;
                    u < 0.0
                })
                .unwrap_or(probs.len() - 1);
            counts[c] += 1.0;
        }
        let expected: Vec<f64> = probs.iter().map(|p| p * n as f64).collect();
        let r = pearson(&counts, &expected, 5.0).unwrap();
        assert_eq!((r.dof, r.pooled), (39, 0));
        assert!(r.p_value > 1e-3, "{r:?}");
        // Swap the probabilities of two unequal categories: rejected.
        let mut wrong = expected.clone();
        wrong.swap(0, 6);
        let r = pearson(&counts, &wrong, 5.0).unwrap();
        assert!(r.p_value < 1e-9, "{r:?}");
        // Categories expecting under 5 are pooled.
        let mut tiny = expected.clone();
        let mut obs = counts.clone();
        tiny.extend([1.0, 2.0, 3.0]);
        obs.extend([1.0, 3.0, 2.0]);
        let r = pearson(&obs, &tiny, 5.0).unwrap();
        assert_eq!((r.dof, r.pooled), (40, 3));
        assert!(pearson(&[1.0], &[1.0, 2.0], 5.0).is_err());
        assert!(pearson(&[1.0, 2.0], &[0.0, 3.0], 5.0).is_err());
        assert!(pearson(&[1.0, 2.0], &[f64::NAN, 3.0], 5.0).is_err());
    }
}
