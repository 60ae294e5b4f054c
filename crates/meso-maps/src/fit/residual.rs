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
    for l in lobes {
        let width = 2.0 / (l.exponent + 1.0).sqrt();
        if width < 0.25 * bin_angle {
            out[grid.bin(l.axis)] += l.weight;
            continue;
        }
        // Bins whose nearest point (centre minus a bin diagonal) is where the lobe has fallen
        // below e⁻³⁰ of its peak get nothing.
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
            let v = s / 9.0 * da * l.weight;
            *o += v;
        }
    }
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
