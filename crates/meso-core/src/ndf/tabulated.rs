//! Tabulated NDFs: a piecewise-constant density on the [`EqualAreaGrid`].
//!
//! Each cell holds a density in 1/sr; since cells have equal solid angle, normalisation is
//! `Σ v_c · 4π/N = 1`. Sampling picks a cell from the discrete CDF and a uniform point in it
//! (uniform in `(z, φ)` is uniform in solid angle), so the sampler's pdf is exactly the table.

use crate::grid::EqualAreaGrid;
use glam::DVec3;

/// A piecewise-constant NDF on an equal-area grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Tabulated {
    grid: EqualAreaGrid,
    values: Vec<f64>,
    cdf: Vec<f64>,
}

impl Tabulated {
    /// From per-cell non-negative values (any scale; normalised here to integrate to 1).
    ///
    /// # Errors
    /// Wrong length, negative or non-finite values, or all zero.
    pub fn from_values(
        grid: EqualAreaGrid,
        mut values: Vec<f64>,
    ) -> Result<Tabulated, crate::NdfError> {
        if values.len() != grid.len() {
            return Err(crate::NdfError::Invalid(format!(
                "tabulated NDF: {} values for a {}×{} grid ({} cells)",
                values.len(),
                grid.n_z,
                grid.n_phi,
                grid.len()
            )));
        }
        if let Some(k) = values.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(crate::NdfError::Invalid(format!(
                "tabulated NDF: value {} is {} (must be finite and >= 0)",
                k + 1,
                values[k]
            )));
        }
        let sum: f64 = values.iter().sum();
        if sum <= 0.0 {
            return Err(crate::NdfError::Invalid(
                "tabulated NDF: all values are zero".into(),
            ));
        }
        let scale = 1.0 / (sum * grid.cell_solid_angle());
        values.iter_mut().for_each(|v| *v *= scale);
        let cdf = super::cumulative(values.iter().copied());
        Ok(Tabulated { grid, values, cdf })
    }

    /// Tabulate any density by averaging it over `sub × sub` points per cell.
    ///
    /// # Errors
    /// As [`Tabulated::from_values`] (e.g. a density that is zero everywhere on the grid).
    pub fn from_fn(
        grid: EqualAreaGrid,
        sub: usize,
        f: impl Fn(DVec3) -> f64,
    ) -> Result<Tabulated, crate::NdfError> {
        let sub = sub.max(1);
        let values = (0..grid.len())
            .map(|c| {
                let mut s = 0.0;
                for a in 0..sub {
                    for b in 0..sub {
                        let fz = (a as f64 + 0.5) / sub as f64;
                        let fp = (b as f64 + 0.5) / sub as f64;
                        s += f(grid.point_in_cell(c, fz, fp)).max(0.0);
                    }
                }
                s / (sub * sub) as f64
            })
            .collect();
        Tabulated::from_values(grid, values)
    }

    /// A histogram of sample directions (unit vectors) with optional weights.
    ///
    /// # Errors
    /// No samples, or non-finite directions / weights.
    pub fn from_samples(
        grid: EqualAreaGrid,
        samples: impl IntoIterator<Item = (DVec3, f64)>,
    ) -> Result<Tabulated, crate::NdfError> {
        let mut values = vec![0.0; grid.len()];
        for (k, (w, weight)) in samples.into_iter().enumerate() {
            if !w.is_finite() || !weight.is_finite() || weight < 0.0 {
                return Err(crate::NdfError::Invalid(format!(
                    "tabulated NDF: sample {} is not a finite direction with a weight >= 0",
                    k + 1
                )));
            }
            values[grid.cell_of(w.normalize_or_zero())] += weight;
        }
        Tabulated::from_values(grid, values)
    }

    /// The grid.
    #[must_use]
    pub fn grid(&self) -> EqualAreaGrid {
        self.grid
    }

    /// Per-cell densities in 1/sr.
    #[must_use]
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Density in 1/sr.
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        self.values[self.grid.cell_of(m)]
    }

    /// Exact sampling of the table.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let (c, u0) = super::pick(&self.cdf, u[0]);
        self.grid.point_in_cell(c, u0, u[1])
    }
}
