//! Tabulated NDFs: a piecewise-constant density on the [`EqualAreaGrid`].
//!
//! Each cell holds a density in 1/sr; since cells have equal solid angle, normalisation is
//! `Σ v_c · 4π/N = 1`. Sampling picks a cell from the discrete CDF and a uniform point in it
//! (uniform in `(z, φ)` is uniform in solid angle), so the sampler's pdf is exactly the table.

use crate::grid::EqualAreaGrid;
use glam::DVec3;
use std::sync::OnceLock;

/// A piecewise-constant NDF on an equal-area grid.
#[derive(Clone, Debug)]
pub struct Tabulated {
    grid: EqualAreaGrid,
    values: Vec<f64>,
    cdf: Vec<f64>,
    /// The bands and prefix sums of [`Tabulated::projected_areas`], built on first use (Smith
    /// masking builds a [`ProjectedAreas`] per direction pair on the exact path).
    areas: OnceLock<AreaTables>,
}

/// Equal grids and values (the cache of projected areas is not compared).
impl PartialEq for Tabulated {
    fn eq(&self, other: &Self) -> bool {
        self.grid == other.grid && self.values == other.values && self.cdf == other.cdf
    }
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
        Ok(Tabulated {
            grid,
            values,
            cdf,
            areas: OnceLock::new(),
        })
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

    /// Density in 1/sr: the value of the cell that holds `m`. At the poles themselves (`m` on
    /// ±z), where the first and last bands' wedge cells all meet and no cell holds `m` more than
    /// another, the mean of that band's cells, so that turning the table about z by whole
    /// sectors turns its values everywhere (a MERL table's first θh row sits on the pole).
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        if m.x == 0.0 && m.y == 0.0 {
            let band = self.grid.cell_of(m) / self.grid.n_phi * self.grid.n_phi;
            let cells = &self.values[band..band + self.grid.n_phi];
            return cells.iter().sum::<f64>() / cells.len() as f64;
        }
        self.values[self.grid.cell_of(m)]
    }

    /// Exact sampling of the table.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let (c, u0) = super::pick(&self.cdf, u[0]);
        self.grid.point_in_cell(c, u0, u[1])
    }
}

/// Exact projected areas of a [`Tabulated`] NDF over the upper hemisphere,
/// `a(ω) = ∫_{z>0} n(m)(ω·m)⁺ dω_m` (dimensionless: per unit of the NDF's mass), and its first
/// moment `∫_{z>0} n(m) m dω_m`, for Smith masking of a table
/// ([`crate::convolution::SmithMasking`]). Everything is in closed form.
///
/// The density is constant on each cell, a box in `(z, φ)`. A cell on the lit side of the
/// terminator (`ω·m = 0`) adds its value times `ω·M_c`, `M_c = ∫_cell m dω`; per band these are
/// prefix sums over φ, so a band costs O(1) plus the cells the terminator crosses. With
/// `x = φ − φ_ω`, `s = sin θ_ω`, the integrand is `A + B cos x`, `A = ω_z z`,
/// `B = s √(1 − z²)`, lit for `|x| < ψ(z) = acos(−A/B)` (ψ monotone in z); a crossed cell is
/// `Φ(x₁) − Φ(x₀)` with `Φ(c) = ∫_band ∫_0^{min(c, ψ(z))} (A + B cos x) dx dz`, which is
/// elementary: `B sin ψ = √(s² − z²)` and
/// `∫ (A ψ + √(s² − z²)) dz = ½[ω_z z² ψ + asin(z/s) − |ω_z| atan(|ω_z| z / √(s² − z²)) + z √(s² − z²)]`,
/// split at the height where the terminator crosses the meridian `x = c`.
/// Tested against brute force and the quadrature of a general NDF.
#[derive(Clone, Copy, Debug)]
pub struct ProjectedAreas<'a> {
    table: &'a Tabulated,
    /// Per band above the horizon: its index, its `z` range clipped to `z ≥ 0`, and
    /// `∫_0^z √(1 − z'²) dz'` at both ends.
    bands: &'a [AreaBand],
    /// Per band, `n_phi + 1` prefix sums over φ of `v_c M_c`.
    prefix: &'a [DVec3],
}

/// What [`ProjectedAreas`] reads beside the table, built once per table.
#[derive(Clone, Debug)]
struct AreaTables {
    bands: Vec<AreaBand>,
    prefix: Vec<DVec3>,
}

/// One band of [`ProjectedAreas`].
#[derive(Clone, Copy, Debug)]
struct AreaBand {
    iz: usize,
    z: [f64; 2],
    disc: [f64; 2],
}

/// `∫_0^z √(1 − z'²) dz'`.
fn half_disc(z: f64) -> f64 {
    0.5 * (z * (1.0 - z * z).max(0.0).sqrt() + z.clamp(-1.0, 1.0).asin())
}

impl Tabulated {
    /// The exact projected areas of the table over the upper hemisphere ([`ProjectedAreas`]).
    /// Its per-band prefix sums are computed on the first call and kept with the table.
    #[must_use]
    pub fn projected_areas(&self) -> ProjectedAreas<'_> {
        let t = self.areas.get_or_init(|| self.area_tables());
        ProjectedAreas {
            table: self,
            bands: &t.bands,
            prefix: &t.prefix,
        }
    }

    /// The bands and prefix sums of [`Tabulated::projected_areas`].
    fn area_tables(&self) -> AreaTables {
        let g = self.grid;
        let n = g.n_phi;
        let dphi = 2.0 * std::f64::consts::PI / n as f64;
        // `(sin φ, cos φ)` of the meridians, shared by every band.
        let edges: Vec<(f64, f64)> = (0..=n).map(|j| (j as f64 * dphi).sin_cos()).collect();
        let mut bands = Vec::new();
        let mut prefix = Vec::new();
        for iz in 0..g.n_z {
            let z1 = -1.0 + 2.0 * (iz + 1) as f64 / g.n_z as f64;
            if z1 <= 0.0 {
                continue;
            }
            let z0 = (-1.0 + 2.0 * iz as f64 / g.n_z as f64).max(0.0);
            let z1 = z1.min(1.0);
            let disc = [half_disc(z0), half_disc(z1)];
            bands.push(AreaBand {
                iz,
                z: [z0, z1],
                disc,
            });
            let rz = disc[1] - disc[0];
            let mz = 0.5 * dphi * (z1 * z1 - z0 * z0);
            let mut acc = DVec3::ZERO;
            prefix.push(acc);
            for j in 0..n {
                let ((s0, c0), (s1, c1)) = (edges[j], edges[j + 1]);
                let m = DVec3::new(rz * (s1 - s0), rz * (c0 - c1), mz);
                acc += self.values[iz * n + j] * m;
                prefix.push(acc);
            }
        }
        AreaTables { bands, prefix }
    }
}

/// `ω` seen from the terminator's side: what [`ProjectedAreas`] needs of it.
#[derive(Clone, Copy)]
struct Terminator {
    wz: f64,
    /// `sin θ_ω`.
    s: f64,
}

/// A meridian `|x| = c` (`x = φ − φ_ω`) under a [`Terminator`].
#[derive(Clone, Copy)]
struct Meridian {
    c: f64,
    sin_c: f64,
    /// Where the terminator crosses it (`ψ(z) = c`), and the antiderivative there (`NaN` when
    /// not in `[0, s]`).
    zc: f64,
    t_zc: f64,
    disc_zc: f64,
}

impl Terminator {
    /// Half-width `ψ(z)` of the lit arc at height `z`.
    fn psi(self, z: f64) -> f64 {
        let (a, b) = (self.wz * z, self.s * (1.0 - z * z).max(0.0).sqrt());
        if a >= b {
            std::f64::consts::PI
        } else if a <= -b {
            0.0
        } else {
            (-a / b).acos()
        }
    }

    /// `∫ (A ψ(z) + √(s² − z²)) dz` at `z ∈ [0, s]`, given `ψ(z)` (module docs).
    fn antiderivative(self, z: f64, psi: f64) -> f64 {
        let q = (self.s * self.s - z * z).max(0.0).sqrt();
        let wa = self.wz.abs();
        0.5 * (self.wz * z * z * psi + (z / self.s).clamp(-1.0, 1.0).asin()
            - wa * (wa * z).atan2(q)
            + z * q)
    }

    fn meridian(self, c: f64) -> Meridian {
        let (sin_c, cos_c) = c.sin_cos();
        let k = self.s * cos_c;
        // |zc| ≤ s exactly; clamped against rounding.
        let zc = if self.wz == 0.0 {
            f64::NAN
        } else {
            (-k * self.wz.signum() / self.wz.hypot(k)).clamp(-self.s, self.s)
        };
        let inside = zc >= 0.0;
        Meridian {
            c,
            sin_c,
            zc,
            t_zc: if inside {
                self.antiderivative(zc, c)
            } else {
                f64::NAN
            },
            disc_zc: half_disc(zc),
        }
    }
}

/// A band of [`ProjectedAreas`] under a [`Terminator`]: `ψ` and the antiderivative at its ends.
struct BandTerms {
    z: [f64; 2],
    disc: [f64; 2],
    /// The antiderivative at `z₀`, `min(z₁, s)` (0 where unused).
    t: [f64; 2],
    t_top: f64,
}

impl BandTerms {
    fn new(band: &AreaBand, tm: Terminator, psi: [f64; 2]) -> BandTerms {
        let at = |z: f64, psi: f64| {
            if z <= tm.s {
                tm.antiderivative(z, psi)
            } else {
                0.0
            }
        };
        let top = band.z[1].min(tm.s);
        BandTerms {
            z: band.z,
            disc: band.disc,
            t: [at(band.z[0], psi[0]), at(band.z[1], psi[1])],
            t_top: if top == band.z[1] {
                at(band.z[1], psi[1])
            } else {
                tm.antiderivative(top, tm.psi(top))
            },
        }
    }

    /// `∫_{z₁}^{z₂} (A c + B sin c) dz`.
    fn boxed(&self, tm: Terminator, m: &Meridian, z1: f64, d1: f64, z2: f64, d2: f64) -> f64 {
        0.5 * tm.wz * m.c * (z2 * z2 - z1 * z1) + tm.s * m.sin_c * (d2 - d1)
    }

    /// `Φ(c)`: the band's lit integral over `0 ≤ x ≤ c` (module docs).
    fn phi(&self, tm: Terminator, m: &Meridian) -> f64 {
        let [z0, z1] = self.z;
        let [d0, d1] = self.disc;
        if tm.wz == 0.0 {
            // ψ = π/2 at every height below the pole.
            let h = Meridian {
                c: m.c.min(std::f64::consts::FRAC_PI_2),
                sin_c: if m.c < std::f64::consts::FRAC_PI_2 {
                    m.sin_c
                } else {
                    1.0
                },
                ..*m
            };
            return self.boxed(tm, &h, z0, d0, z1, d1);
        }
        let zc = m.zc;
        if tm.wz > 0.0 {
            // ψ grows with z: unlit beyond c below zc, the whole [0, c] above it.
            if zc <= z0 {
                self.boxed(tm, m, z0, d0, z1, d1)
            } else if zc >= z1 {
                // ψ < c over the whole band (so z₁ ≤ s).
                self.t[1] - self.t[0]
            } else {
                (m.t_zc - self.t[0]) + self.boxed(tm, m, zc, m.disc_zc, z1, d1)
            }
        } else {
            // ψ falls with z (to 0 at z = s): [0, c] lit below zc, ψ < c above it.
            let lit_to = zc.clamp(z0, z1);
            let lit = if lit_to > z0 {
                let dl = if lit_to == z1 { d1 } else { m.disc_zc };
                self.boxed(tm, m, z0, d0, lit_to, dl)
            } else {
                0.0
            };
            let top = z1.min(tm.s);
            let partial = if lit_to < top {
                let from = if lit_to == z0 { self.t[0] } else { m.t_zc };
                self.t_top - from
            } else {
                0.0
            };
            lit + partial
        }
    }
}

impl ProjectedAreas<'_> {
    /// `∫_{z>0} n(m) m dω_m` (its `z` is the projected area towards the normal).
    #[must_use]
    pub fn moment(&self) -> DVec3 {
        let n1 = self.table.grid.n_phi + 1;
        (0..self.bands.len())
            .map(|b| self.prefix[b * n1 + n1 - 1])
            .sum()
    }

    /// `∫_{z>0} n(m)(ω·m)⁺ dω_m` for a unit `ω` (either side of the horizon).
    #[must_use]
    pub fn area(&self, w: DVec3) -> f64 {
        use std::f64::consts::PI;
        let n = self.table.grid.n_phi;
        let n1 = n + 1;
        let dphi = 2.0 * PI / n as f64;
        let tm = Terminator {
            wz: w.z,
            s: w.x.hypot(w.y),
        };
        if tm.s <= 0.0 {
            return if w.z > 0.0 { w.dot(self.moment()) } else { 0.0 };
        }
        let phi_w = w.y.atan2(w.x);
        // The meridians, `x` in (−π, π], filled when a band needs them.
        let reduce = |j: usize| {
            let x = j as f64 * dphi - phi_w;
            x - 2.0 * PI * ((x - PI) / (2.0 * PI)).ceil()
        };
        let mut meridians: Vec<Option<(f64, Meridian)>> = vec![None; n];
        let mut half_turn: Option<Meridian> = None;
        let mut total = 0.0;
        let mut psi_below = tm.psi(self.bands.first().map_or(0.0, |b| b.z[0]));
        for (k, band) in self.bands.iter().enumerate() {
            let pre = &self.prefix[k * n1..(k + 1) * n1];
            let psi_above = tm.psi(band.z[1]);
            let psi = [psi_below, psi_above];
            psi_below = psi_above;
            // ψ is monotone in z: [0, lo) is lit at every height of the band, [0, hi) at some.
            let (lo, hi) = (psi[0].min(psi[1]), psi[0].max(psi[1]));
            if lo >= PI {
                total += w.dot(pre[n]);
                continue;
            }
            if hi <= 0.0 {
                continue;
            }
            // Cells (unwrapped indices) wholly inside the lit arc, and those the terminator
            // crosses on either side of it.
            let p0 = ((phi_w - lo) / dphi).ceil() as i64;
            let p1 = ((phi_w + lo) / dphi).floor() as i64 - 1;
            let l0 = ((phi_w - hi) / dphi).floor() as i64;
            let mut r1 = ((phi_w + hi) / dphi).ceil() as i64 - 1;
            if r1 - l0 + 1 > n as i64 {
                r1 = l0 + n as i64 - 1;
            }
            let crossed: [(i64, i64); 2] = if p1 >= p0 {
                let (start, count) = (p0.rem_euclid(n as i64) as usize, (p1 - p0 + 1) as usize);
                let lit = if start + count <= n {
                    pre[start + count] - pre[start]
                } else {
                    (pre[n] - pre[start]) + pre[start + count - n]
                };
                total += w.dot(lit);
                [(l0, p0 - 1), (p1 + 1, r1)]
            } else {
                [(l0, r1), (0, -1)]
            };
            let terms = BandTerms::new(band, tm, psi);
            let mut signed = |j: usize| {
                let (x, m) = *meridians[j].get_or_insert_with(|| {
                    let x = reduce(j);
                    (x, tm.meridian(x.abs()))
                });
                (x, x.signum() * terms.phi(tm, &m))
            };
            for (a, b) in crossed {
                for j in a..=b {
                    let jj = j.rem_euclid(n as i64) as usize;
                    let v = self.table.values[band.iz * n + jj];
                    if v <= 0.0 {
                        continue;
                    }
                    let (x0, f0) = signed(jj);
                    let (x1, f1) = signed((jj + 1) % n);
                    let mut lit = f1 - f0;
                    if x1 <= x0 {
                        // The cell spans x = π: add Φ(π) − Φ(−π).
                        let m = *half_turn.get_or_insert_with(|| tm.meridian(PI));
                        lit += 2.0 * terms.phi(tm, &m);
                    }
                    total += v * lit;
                }
            }
        }
        total
    }
}

#[cfg(test)]
mod pole_tests {
    use super::*;

    /// A table whose value depends on the sector, turned by whole sectors, has the turned
    /// values everywhere, the poles included (where every sector's wedge meets).
    #[test]
    fn the_poles_take_their_bands_mean() {
        let g = EqualAreaGrid::new(8, 8);
        let t = Tabulated::from_values(g, (0..g.len()).map(|c| 1.0 + (c % 8) as f64).collect())
            .unwrap();
        let top = &t.values()[7 * 8..];
        let mean = top.iter().sum::<f64>() / 8.0;
        assert!((t.eval(DVec3::Z) - mean).abs() < 1e-15);
        assert!((t.eval(-DVec3::Z) - mean).abs() < 1e-15);
        // Just off the pole, the wedge that holds the direction.
        let near = DVec3::new(1e-9, 1e-9, 1.0).normalize();
        assert_eq!(t.eval(near), t.values()[g.cell_of(near)]);
        // Turned by three sectors.
        let turned: Vec<f64> = (0..g.len())
            .map(|c| t.values()[c / 8 * 8 + (c % 8 + 3) % 8])
            .collect();
        let u = Tabulated::from_values(g, turned).unwrap();
        let q = glam::DQuat::from_rotation_z(-3.0 * std::f64::consts::TAU / 8.0);
        for m in [DVec3::Z, -DVec3::Z, DVec3::new(0.3, 0.2, 0.9).normalize()] {
            assert!(
                (u.eval(q * m) - t.eval(m)).abs() < 1e-12 * t.eval(m),
                "{m:?}"
            );
        }
    }
}
