//! A brute-force quadrature over one Phong peak `cos^η(α/2)` in the peak's own frame, for the
//! tests of `lobes` (the closed-form response and `meso_maps::peak_projected_area`, the
//! projected area): written once, independent of the Gaussian forms both check.

use glam::DVec3;
use meso_core::frame::Frame;

/// Calls `visit(d, m)` at the midpoints of an `na × np` grid in the frame of `axis` (its tangent
/// towards `tangent`): polar angle `α ∈ [0, amax)`, azimuth `φ ∈ [0, 2π)`, with `m` the world
/// direction and `d = cos^η(α/2) sin α` the peak times the polar Jacobian (the constant cell
/// size left out: callers take ratios).
pub(super) fn for_each_peak_node(
    axis: DVec3,
    tangent: DVec3,
    eta: f64,
    amax: f64,
    (na, np): (usize, usize),
    mut visit: impl FnMut(f64, DVec3),
) {
    let f = Frame::from_normal_tangent(axis, tangent);
    for ia in 0..na {
        let a = (ia as f64 + 0.5) / na as f64 * amax;
        let d = (0.5 * (1.0 + a.cos())).powf(0.5 * eta) * a.sin();
        for ip in 0..np {
            let p = (ip as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
            let m = f.to_world(DVec3::new(a.sin() * p.cos(), a.sin() * p.sin(), a.cos()));
            visit(d, m);
        }
    }
}
