//! Height maps generated in code, for tests, benchmarks and examples. All are tileable
//! ([`Border::Wrap`]) with texel size `s` (length units).

use crate::error::Result;
use crate::heightmap::{Border, HeightMap};
use rand::RngExt;
use rand::SeedableRng;

/// A flat map (all heights 0).
pub fn flat(n: usize, s: f64) -> Result<HeightMap> {
    HeightMap::from_fn(n, n, s, Border::Wrap, |_, _| 0.0)
}

/// V-grooves along y, period `period` texels: `h = depth·|2·frac(x/(period·s)) − 1|` (rims at
/// `x = 0` and `x = period·s`, valley in the middle). Walls have slope `±2·depth/(period·s)`.
pub fn v_grooves(n: usize, period: usize, depth: f64, s: f64) -> Result<HeightMap> {
    let p = period as f64 * s;
    HeightMap::from_fn(n, n, s, Border::Wrap, |x, _| {
        let f = (x / p).rem_euclid(1.0);
        depth * (2.0 * f - 1.0).abs()
    })
}

/// Parallel half-cylinders along y, touching, of radius `period·s/2`: bumps for `sign = +1`,
/// grooves for `sign = −1` (same NDF, §3.1 of the paper).
pub fn half_cylinders(n: usize, period: usize, s: f64, sign: f64) -> Result<HeightMap> {
    let p = period as f64 * s;
    let r = 0.5 * p;
    HeightMap::from_fn(n, n, s, Border::Wrap, |x, _| {
        let u = (x / p).rem_euclid(1.0) * p - r;
        sign * (r * r - u * u).max(0.0).sqrt()
    })
}

/// A Gaussian random surface: white noise (PCG, `seed`) blurred by a periodic Gaussian of
/// standard deviation `corr` texels, scaled to RMS height `rms`.
pub fn gaussian(n: usize, corr: f64, rms: f64, seed: u64, s: f64) -> Result<HeightMap> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut a: Vec<f64> = (0..n * n).map(|_| rng.random::<f64>() - 0.5).collect();
    let rad = (3.0 * corr).ceil() as isize;
    let k: Vec<f64> = (-rad..=rad)
        .map(|d| (-(d * d) as f64 / (2.0 * corr * corr)).exp())
        .collect();
    // Separable: along each row into `b`, then along each column back into `a`.
    let mut b = vec![0.0; n * n];
    blur_periodic(&a, &mut b, n, &k, rad, 1);
    blur_periodic(&b, &mut a, n, &k, rad, n);
    let mean = a.iter().sum::<f64>() / a.len() as f64;
    let sd = (a.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / a.len() as f64).sqrt();
    let h = a.iter().map(|v| (v - mean) / sd * rms).collect();
    HeightMap::from_heights(n, n, h, s, Border::Wrap)
}

/// One pass of the periodic blur of [`gaussian`] over the `n × n` grid `src` into `dst`: the
/// kernel `k` (centred at `rad`) along x (`stride = 1`) or along y (`stride = n`), wrapping.
fn blur_periodic(src: &[f64], dst: &mut [f64], n: usize, k: &[f64], rad: isize, stride: usize) {
    let ni = n as isize;
    for i in 0..n {
        for j in 0..n {
            // The coordinate the kernel runs along, and the cell's offset without it.
            let (along, base) = if stride == 1 { (j, i * n) } else { (i, j) };
            let mut v = 0.0;
            for (t, kv) in k.iter().enumerate() {
                let q = (along as isize + t as isize - rad).rem_euclid(ni) as usize;
                v += kv * src[base + q * stride];
            }
            dst[i * n + j] = v;
        }
    }
}

/// A plain-weave pattern of period `period` texels (a multiple of 4 works best): warp threads
/// along y and weft threads along x, each a rounded ridge of height `amp` that dips under the
/// crossing thread every other crossing.
pub fn woven(n: usize, period: usize, amp: f64, s: f64) -> Result<HeightMap> {
    let p = period as f64 * s;
    let tau = std::f64::consts::TAU;
    HeightMap::from_fn(n, n, s, Border::Wrap, |x, y| {
        let u = x / p;
        let v = y / p;
        // Ridge profiles across each thread family (two threads per period).
        let warp_profile = (tau * u).cos().abs();
        let weft_profile = (tau * v).cos().abs();
        // Over/under modulation along each thread.
        let warp = amp
            * warp_profile
            * (0.6 + 0.4 * (tau * v / 2.0 + std::f64::consts::PI * (2.0 * u).floor()).sin());
        let weft = amp
            * weft_profile
            * (0.6 - 0.4 * (tau * u / 2.0 + std::f64::consts::PI * (2.0 * v).floor()).sin());
        warp.max(weft)
    })
}

/// Encode `values` (row-major, `width × height`, copied to R, G and B) as an OpenEXR float image
/// — for tests and examples that need EXR height maps, including deliberately bad ones (NaN).
///
/// # Errors
/// An encoder failure, as [`crate::MapError::InvalidParameter`].
pub fn exr_bytes(width: u32, height: u32, values: &[f32]) -> Result<Vec<u8>> {
    if values.len() != (width as usize) * (height as usize) {
        return Err(crate::MapError::InvalidParameter {
            name: "values",
            value: format!("{} values", values.len()),
            reason: "must hold width × height values",
        });
    }
    let img = image::Rgb32FImage::from_fn(width, height, |x, y| {
        let v = values[(y * width + x) as usize];
        image::Rgb([v, v, v])
    });
    let mut out = Vec::new();
    image::DynamicImage::ImageRgb32F(img)
        .write_to(
            &mut std::io::Cursor::new(&mut out),
            image::ImageFormat::OpenExr,
        )
        .map_err(|e| crate::MapError::InvalidParameter {
            name: "values",
            value: format!("EXR ({e})"),
            reason: "cannot be encoded as EXR",
        })?;
    Ok(out)
}

/// The 16 direction pairs `(i, o)` (unit vectors, local frame) at which height-map materials are
/// compared with the gonioreflectometer (tests/visibility.rs, examples/farfield_table.rs): θ ≤ 60°,
/// across and along the fixtures' grooves (y), in and out of the plane of incidence.
#[must_use]
pub fn farfield_pairs() -> Vec<(glam::DVec3, glam::DVec3)> {
    use meso_core::frame::spherical_direction_deg as d;
    [
        (0.0, 0.0, 0.0, 0.0),
        (20.0, 0.0, 20.0, 180.0),
        (40.0, 0.0, 40.0, 180.0),
        (60.0, 0.0, 60.0, 180.0),
        (60.0, 0.0, 20.0, 180.0),
        (50.0, 0.0, 10.0, 0.0),
        (30.0, 0.0, 0.0, 0.0),
        (60.0, 0.0, 0.0, 0.0),
        (45.0, 90.0, 45.0, 270.0),
        (60.0, 90.0, 30.0, 270.0),
        (40.0, 45.0, 40.0, 225.0),
        (55.0, 30.0, 35.0, 200.0),
        (60.0, 10.0, 55.0, 170.0),
        (25.0, 120.0, 50.0, 300.0),
        (60.0, 180.0, 60.0, 0.0),
        (35.0, 160.0, 15.0, 350.0),
    ]
    .iter()
    .map(|&(ti, pi, to, po)| (d(ti, pi), d(to, po)))
    .collect()
}
