//! The quality measure of a fit: bin probabilities of lobes or of any core NDF on an
//! equal-area grid, and the relative L2 distance to the histogram of the footprint's normals.

use super::{Entry, ENTRY_GRID_RES};
use crate::sphgrid::SphereGrid;
use glam::DVec3;
use meso_core::ndf::PhongLobe;

/// Resolution of the equal-area grid of the NDF residual (1024 bins of ≈ 6.3°).
pub const RESIDUAL_GRID_RES: usize = 32;

/// Probability of each bin of `grid` under a lobe set (weights summing to 1): lobes narrower
/// than a quarter of a bin put all their mass in the bin of their axis; others are integrated
/// with 3×3 points per bin. `out` has `grid.bins()` entries.
pub fn lobe_bin_mass(lobes: &[PhongLobe], grid: SphereGrid, out: &mut [f64]) {
    out.fill(0.0);
    let da = grid.bin_solid_angle();
    let bin_angle = da.sqrt();
    GRID_POINTS.with(|cache| {
        let mut cache = cache.borrow_mut();
        let pts = cache.points(grid);
        for l in lobes {
            let width = 2.0 / (l.exponent + 1.0).sqrt();
            if width < 0.25 * bin_angle {
                out[grid.bin(l.axis)] += l.weight;
                continue;
            }
            // Bins whose nearest point (centre minus a bin diagonal) is where the lobe has fallen
            // below e⁻³⁰ of its peak get nothing. `far`: a cosine to the centre below which the
            // test below certainly fails (its angle `α_cut + margin` plus 10⁻⁷ rad, `α_cut` where
            // `(η/2)·ln((1 + cos α)/2) = −30`), so those bins skip its `acos`, `cos` and `ln`
            // with the same outcome.
            let margin = 1.5 * bin_angle;
            let reach = (2.0 * (-60.0 / l.exponent).exp() - 1.0)
                .clamp(-1.0, 1.0)
                .acos()
                + margin
                + 1e-7;
            let far = if reach < std::f64::consts::PI {
                reach.cos()
            } else {
                f64::NEG_INFINITY
            };
            for (o, p) in out.iter_mut().zip(pts.chunks_exact(POINTS_PER_BIN)) {
                let d = l.axis.dot(p[0]);
                if d < far {
                    continue;
                }
                let alpha = (d.clamp(-1.0, 1.0).acos() - margin).max(0.0);
                if 0.5 * l.exponent * (0.5 * (1.0 + alpha.cos())).ln() < -30.0 {
                    continue;
                }
                let mut s = 0.0;
                for &m in &p[1..] {
                    s += l.unit_density(m);
                }
                let v = s / 9.0 * da * l.weight;
                *o += v;
            }
        }
    });
}

/// Points per bin of [`GridPoints`]: the centre, then the 3×3 quadrature points row by row.
const POINTS_PER_BIN: usize = 10;

/// The points [`lobe_bin_mass`] reads of each bin of one grid, computed once per thread and
/// resolution (`SphereGrid::point`'s own values: the centre `(½, ½)`, then `((a + ½)/3,
/// (b + ½)/3)` for `a`, `b` = 0, 1, 2; 240 KB at [`RESIDUAL_GRID_RES`]).
#[derive(Default)]
struct GridPoints {
    res: usize,
    pts: Vec<DVec3>,
}

impl GridPoints {
    /// The points of `grid`, [`POINTS_PER_BIN`] a bin in bin order.
    fn points(&mut self, grid: SphereGrid) -> &[DVec3] {
        if self.res != grid.res || self.pts.is_empty() {
            self.pts.clear();
            for k in 0..grid.bins() {
                self.pts.push(grid.point(k, 0.5, 0.5));
                for a in 0..3 {
                    for b in 0..3 {
                        self.pts.push(grid.point(
                            k,
                            (a as f64 + 0.5) / 3.0,
                            (b as f64 + 0.5) / 3.0,
                        ));
                    }
                }
            }
            self.res = grid.res;
        }
        &self.pts
    }
}

thread_local! {
    /// [`lobe_bin_mass`]'s grid points, per thread.
    static GRID_POINTS: std::cell::RefCell<GridPoints> = std::cell::RefCell::new(GridPoints::default());
}

/// Probability of each bin of `grid` under any core NDF (`∫ n = 1`): Phong peaks by
/// [`lobe_bin_mass`], delta sums by their histogram, a vMF lobe narrower than a quarter of a bin
/// in the bin of its axis, other densities (vMF, tabulated) with 3×3 points per bin,
/// renormalised (a density the points all miss goes to the bin of its mean normal). `out` has
/// `grid.bins()` entries.
pub fn ndf_bin_mass(ndf: &meso_core::ndf::Ndf, grid: SphereGrid, out: &mut [f64]) {
    use meso_core::ndf::Ndf;
    out.fill(0.0);
    let da = grid.bin_solid_angle();
    match ndf {
        Ndf::PhongPeaks(p) => return lobe_bin_mass(p.lobes(), grid, out),
        Ndf::Deltas(d) => {
            for n in d.normals() {
                out[grid.bin(n.normal)] += n.weight;
            }
            return;
        }
        Ndf::VonMisesFisher(v) if 1.0 / (v.kappa + 1.0).sqrt() < 0.25 * da.sqrt() => {
            out[grid.bin(v.mu)] = 1.0;
            return;
        }
        _ => {}
    }
    let mut tot = 0.0;
    for (k, o) in out.iter_mut().enumerate() {
        let mut s = 0.0;
        for a in 0..3 {
            for b in 0..3 {
                s += ndf.eval(grid.point(k, (a as f64 + 0.5) / 3.0, (b as f64 + 0.5) / 3.0));
            }
        }
        *o = s / 9.0 * da;
        tot += *o;
    }
    if tot > 0.0 {
        out.iter_mut().for_each(|o| *o /= tot);
    } else {
        out[grid.bin(ndf.stats().mean_normal.normalize_or(DVec3::Z))] = 1.0;
    }
}

/// Relative L2 error `‖P_fit − P_hist‖ / ‖P_hist‖` between the lobes' bin probabilities and the
/// histogram of `(normal, weight)` pairs on a [`RESIDUAL_GRID_RES`]² equal-area grid. Because
/// the bins have equal solid angle this equals the relative L2 error of the bin-averaged NDFs.
#[must_use]
pub fn ndf_l2_error(
    normals: impl Iterator<Item = (DVec3, f64)>,
    fit_mass: impl FnOnce(SphereGrid, &mut [f64]),
) -> f64 {
    let grid = SphereGrid {
        res: RESIDUAL_GRID_RES,
    };
    l2_of_histogram(normals.map(|(n, w)| (grid.bin(n), w)), fit_mass)
}

/// [`ndf_l2_error`] of merged entries: each entry's weight in the residual bin that holds its
/// entry-grid bin. The entry grid's bins nest in the residual grid's
/// ([`ENTRY_GRID_RES`] = 8 × [`RESIDUAL_GRID_RES`], the same square map; `⌊8x⌋ div 8 = ⌊x⌋`
/// and the scaling by 8 is exact), so this is the histogram of the entries' normals, the same
/// as [`ndf_l2_error`] of those normals up to the order of the sums, with no pass over them.
#[must_use]
pub fn entries_l2_error(entries: &[Entry], fit_mass: impl FnOnce(SphereGrid, &mut [f64])) -> f64 {
    const F: usize = ENTRY_GRID_RES / RESIDUAL_GRID_RES;
    const _: () = assert!(F * RESIDUAL_GRID_RES == ENTRY_GRID_RES);
    l2_of_histogram(
        entries.iter().map(|e| {
            let b = e.bin as usize;
            let (iu, iv) = (b % ENTRY_GRID_RES, b / ENTRY_GRID_RES);
            ((iv / F) * RESIDUAL_GRID_RES + iu / F, e.w)
        }),
        fit_mass,
    )
}

/// The relative L2 error of the fit's bin masses against the histogram of `(bin, weight)`
/// pairs on the [`RESIDUAL_GRID_RES`]² grid.
fn l2_of_histogram(
    bins: impl Iterator<Item = (usize, f64)>,
    fit_mass: impl FnOnce(SphereGrid, &mut [f64]),
) -> f64 {
    let grid = SphereGrid {
        res: RESIDUAL_GRID_RES,
    };
    let mut hist = vec![0.0; grid.bins()];
    let mut tot = 0.0;
    for (b, w) in bins {
        hist[b] += w;
        tot += w;
    }
    if tot <= 0.0 {
        return 0.0;
    }
    hist.iter_mut().for_each(|h| *h /= tot);
    let mut fit = vec![0.0; grid.bins()];
    fit_mass(grid, &mut fit);
    let num: f64 = hist.iter().zip(&fit).map(|(h, f)| (h - f) * (h - f)).sum();
    let den: f64 = hist.iter().map(|h| h * h).sum();
    (num / den).sqrt()
}

#[cfg(test)]
mod tests {
    use super::super::test_dirs::random_dir;
    use super::*;

    /// [`lobe_bin_mass`] as it was written before its grid points were cached and its far bins
    /// skipped by a cosine: every bin's centre and 3×3 points from `SphereGrid::point`, the
    /// `acos`/`cos`/`ln` test on every bin.
    fn lobe_bin_mass_reference(lobes: &[PhongLobe], grid: SphereGrid, out: &mut [f64]) {
        out.fill(0.0);
        let da = grid.bin_solid_angle();
        let bin_angle = da.sqrt();
        for l in lobes {
            let width = 2.0 / (l.exponent + 1.0).sqrt();
            if width < 0.25 * bin_angle {
                out[grid.bin(l.axis)] += l.weight;
                continue;
            }
            let margin = 1.5 * bin_angle;
            for (k, o) in out.iter_mut().enumerate() {
                let c = grid.point(k, 0.5, 0.5);
                let alpha = (l.axis.dot(c).clamp(-1.0, 1.0).acos() - margin).max(0.0);
                if 0.5 * l.exponent * (0.5 * (1.0 + alpha.cos())).ln() < -30.0 {
                    continue;
                }
                let mut s = 0.0;
                for a in 0..3 {
                    for b in 0..3 {
                        let m = grid.point(k, (a as f64 + 0.5) / 3.0, (b as f64 + 0.5) / 3.0);
                        s += l.unit_density(m);
                    }
                }
                *o += s / 9.0 * da * l.weight;
            }
        }
    }

    /// The cached points and the cosine skip give every bin the same mass to the last bit, for
    /// lobes from the uniform sphere (η = 0) to nearly a delta, tilted up to the horizon, and on
    /// two grid resolutions (the cache rebuilt between them).
    #[test]
    fn lobe_bin_mass_is_the_direct_sum_bit_for_bit() {
        let mut rng = meso_testkit::rng(11);
        for res in [RESIDUAL_GRID_RES, 16, RESIDUAL_GRID_RES] {
            let grid = SphereGrid { res };
            for exponent in [0.0, 1.0, 4.0, 11.9, 12.5, 40.0, 300.0, 5e3, 1e5, 1e6] {
                let lobes: Vec<PhongLobe> = (0..3)
                    .map(|i| {
                        let [u, _] = meso_testkit::uniform2(&mut rng);
                        PhongLobe {
                            axis: random_dir(&mut rng, 0.5 + 10.0 * f64::from(i)),
                            weight: 0.1 + u,
                            exponent,
                        }
                    })
                    .collect();
                let (mut got, mut want) = (vec![0.0; grid.bins()], vec![0.0; grid.bins()]);
                lobe_bin_mass(&lobes, grid, &mut got);
                lobe_bin_mass_reference(&lobes, grid, &mut want);
                assert!(want.iter().any(|&v| v > 0.0), "η = {exponent}: no mass");
                for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                    assert_eq!(
                        g.to_bits(),
                        w.to_bits(),
                        "res {res}, η = {exponent}, bin {k}"
                    );
                }
            }
        }
    }
}
