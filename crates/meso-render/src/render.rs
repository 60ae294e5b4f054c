//! The renderer: direct illumination of the first visible surface.
//!
//! For each pixel and sample, a jittered camera ray finds the first surface; its outgoing
//! radiance towards the camera is
//!
//! ```text
//! L_o = Σ_lights  f(wi, wo) · weight · max(0, wi_local.z) · V
//! ```
//!
//! with one light sample per light (and one environment sample) per pixel sample, `weight` the
//! light sample's `L/pdf` ([`crate::light::LightSample`]), `wi_local.z` the cosine with the
//! **shading** normal, and `V` the visibility along a shadow ray. Shadow rays start on the
//! **geometric** normal's side (offset along it), and light from below the geometric surface
//! (`n_g · wi ≤ 0`) is discarded, so smooth-shaded meshes do not leak light through their
//! silhouettes. No interreflection (the paper's shading is local).
//!
//! Footprints: with several samples per pixel, each sample's ray differentials are fitted to its
//! stratum of the pixel (a `2^k × 2^k` grid that the first `spp` Sobol points fill evenly when
//! `spp` is a power of two ≥ 4, else the whole pixel): the differentials shrink to the stratum
//! and `ShadingPoint::filter_uv` moves to its centre, so that filtering materials (NDF-mapped)
//! converge to the pixel's box filter as `spp` grows instead of blurring every sample over a
//! whole pixel around a random point.
//!
//! Sampling: a per-pixel Owen-scrambled Sobol sequence; dimensions 0–1 jitter the pixel, then
//! two per light in scene order, then two for the environment. At one sample per pixel the
//! camera ray goes through the pixel centre and the sequence is only evaluated for lights that
//! need random numbers. Tiles of `tile_size²` pixels are rendered in parallel with rayon (one
//! row of tiles per job, written straight into the image); the per-sample loop does not
//! allocate.
//!
//! Two shading paths give the same image to rounding:
//! * **stream** (used when every material is [`Shader::direction_only`] and none needs surface
//!   parameters, e.g. every meso-core material, Phong lobes, Lambert): a tile's camera hits
//!   are gathered into arrays and shaded light by light, the BRDF through
//!   [`Shader::eval_pairs`] across many points at once (see `render/stream.rs`);
//! * **per hit** (everything else, e.g. the bump- and NDF-mapped materials, or
//!   [`RenderOptions::per_hit`]): each hit is shaded on its own, as described below.
//!
//! Fast paths (see `crates/meso-render/README.md` for measurements): ray differentials and
//! sphere texture coordinates are computed only when some material reads them
//! ([`Shader::needs_surface_parameters`]); shadow rays skip lights below the geometric normal
//! and do not test the surface they leave (it cannot be hit again: a planar primitive, or a
//! sphere seen from outside); the BRDF is evaluated for all light samples of a point in one
//! [`Shader::eval_many`] call before any shadow ray is traced, and shadow rays are traced only
//! where it is non-zero.

use crate::camera::{Ray, RayGen};
use crate::geometry::ShadingPoint;
use crate::image::Image;
use crate::light::LightSample;
use crate::sampling::{PixelSampler, MAX_SAMPLES_PER_PIXEL};
use crate::scene::{Scene, Skip};
use crate::shader::Shader;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

mod primary;
mod stream;

/// Per-call overrides of the scene's image settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Override the image width (pixels).
    pub width: Option<u32>,
    /// Override the image height (pixels).
    pub height: Option<u32>,
    /// Override the samples per pixel (clamped to 1..=65536).
    pub spp: Option<u32>,
    /// Seed of the sample scrambling; different seeds give independent noise.
    pub seed: u32,
    /// Tile edge in pixels (tiles are the unit of parallel work and of progress).
    pub tile_size: u32,
    /// Shade every hit on its own (the per-hit path) even where the stream path applies
    /// (see the module docs). Both give the same image to rounding; for tests and timing.
    pub per_hit: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: None,
            height: None,
            spp: None,
            seed: 0,
            tile_size: 32,
            per_hit: false,
        }
    }
}

/// Render `scene`. `progress(done_tiles, total_tiles)` is called (from worker threads) after
/// each tile. The result holds linear radiance (W/(m²·sr)) per pixel.
#[must_use]
pub fn render(
    scene: &Scene,
    opts: &RenderOptions,
    progress: Option<&(dyn Fn(usize, usize) + Sync)>,
) -> Image {
    let w = opts.width.unwrap_or(scene.image.width).max(1);
    let h = opts.height.unwrap_or(scene.image.height).max(1);
    let spp = opts
        .spp
        .unwrap_or(scene.image.spp)
        .clamp(1, MAX_SAMPLES_PER_PIXEL);
    let mut ctx = PixelContext::new(scene, w, h, spp, opts.seed);
    ctx.stream &= !opts.per_hit;
    let ts = opts.tile_size.max(1);
    let (tx, ty) = (w.div_ceil(ts), h.div_ceil(ts));
    let total = (tx * ty) as usize;
    let done = AtomicUsize::new(0);
    let mut img = Image::new(w, h);
    // One band (a row of tiles) per job, written straight into the image (no per-tile
    // buffers kept alive until the end: at 1024² those were 12 MB of fresh pages per frame).
    img.pixels_mut()
        .par_chunks_mut((w * ts) as usize)
        .enumerate()
        .for_each(|(band, pixels)| {
            let y0 = band as u32 * ts;
            let y1 = (y0 + ts).min(h);
            let mut buf = Vec::with_capacity((ts * ts) as usize);
            let mut scratch = ShadeScratch::default();
            for t in 0..tx {
                let (x0, x1) = (t * ts, (t * ts + ts).min(w));
                buf.clear();
                if ctx.stream {
                    STREAM_SCRATCH.with_borrow_mut(|s| {
                        stream::render_tile(scene, &ctx, (x0, x1), (y0, y1), s, &mut buf);
                    });
                } else {
                    for y in y0..y1 {
                        for x in x0..x1 {
                            buf.push(trace_pixel(scene, &ctx, x, y, &mut scratch));
                        }
                    }
                }
                let tw = (x1 - x0) as usize;
                for (r, row) in buf.chunks_exact(tw).enumerate() {
                    let at = r * w as usize + x0 as usize;
                    pixels[at..at + tw].copy_from_slice(row);
                }
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                if let Some(p) = progress {
                    p(d, total);
                }
            }
        });
    img
}

thread_local! {
    /// The stream path's storage, one per worker thread (allocated on first use).
    static STREAM_SCRATCH: std::cell::RefCell<stream::StreamScratch> =
        std::cell::RefCell::new(stream::StreamScratch::default());
}

/// Per-render constants, hoisted out of the pixel loop.
struct PixelContext {
    w: u32,
    h: u32,
    spp: u32,
    seed: u32,
    /// Some material reads `uv` or the footprint: trace ray differentials.
    params: bool,
    /// Primary rays without differentials.
    rays: RayGen,
    /// Every material is direction-only and none needs surface parameters: shade tiles by
    /// streams ([`stream`]).
    stream: bool,
    /// Side of the grid of pixel strata the samples' footprints are fitted to when `spp > 1`
    /// ([`strata`], [`to_stratum`]).
    strata: u32,
}

impl PixelContext {
    fn new(scene: &Scene, w: u32, h: u32, spp: u32, seed: u32) -> PixelContext {
        let params = scene
            .materials()
            .iter()
            .any(|m| m.needs_surface_parameters());
        PixelContext {
            w,
            h,
            spp,
            seed,
            params,
            rays: RayGen::new(&scene.camera, w, h),
            stream: !params && scene.materials().iter().all(|m| m.direction_only()),
            strata: strata(spp),
        }
    }
}

/// One pixel: with one sample, the ray through the pixel centre and a deferred sampler (no
/// Sobol evaluation unless an area or environment light asks for one); with more, jittered
/// Sobol samples. Differentials only when a material needs them.
#[inline]
fn trace_pixel(
    scene: &Scene,
    c: &PixelContext,
    x: u32,
    y: u32,
    scratch: &mut ShadeScratch,
) -> [f32; 3] {
    let a = if c.spp == 1 {
        let sampler = PixelSampler::deferred(x, y, c.seed, 0);
        trace_sample(scene, c, x, y, &sampler, [0.5, 0.5], scratch, false).0
    } else {
        // `Σ w·L / Σ w` with each sample's `Shader::sample_weight` (1 for every material but a
        // bump map weighted by view, where it is the plain mean to the bit); the plain mean
        // when no sample weighs anything.
        let (mut acc, mut plain, mut weight) = (DVec3::ZERO, DVec3::ZERO, 0.0);
        for s in 0..c.spp {
            let (sampler, j) = jittered(x, y, c.seed, s);
            let (l, w) = trace_sample(scene, c, x, y, &sampler, j, scratch, true);
            acc += w * l;
            plain += l;
            weight += w;
        }
        if weight > 0.0 {
            acc / weight
        } else {
            plain / f64::from(c.spp)
        }
    };
    [a.x as f32, a.y as f32, a.z as f32]
}

/// The eager sampler of sample `s` and its pixel jitter. Kept out of line so that the
/// one-sample path never evaluates the Sobol sequence speculatively.
#[inline(never)]
fn jittered(x: u32, y: u32, seed: u32, s: u32) -> (PixelSampler, [f64; 2]) {
    let smp = PixelSampler::new(x, y, seed, s);
    (smp, smp.get2(0))
}

/// The radiance along the camera ray through `(x + j[0], y + j[1])` and, when `weighted`, the
/// sample's weight in its pixel ([`Shader::sample_weight`] of the material it hit; 1 for the
/// background, and without `weighted`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn trace_sample(
    scene: &Scene,
    c: &PixelContext,
    x: u32,
    y: u32,
    sampler: &PixelSampler,
    j: [f64; 2],
    scratch: &mut ShadeScratch,
    weighted: bool,
) -> (DVec3, f64) {
    let (px, py) = (f64::from(x) + j[0], f64::from(y) + j[1]);
    let (hit, d) = if c.params {
        let rd = scene.camera.generate_ray(px, py, c.w, c.h);
        (scene.primary_hit(&rd.ray, Some(&rd), true), rd.ray.d)
    } else {
        let ray = c.rays.ray(px, py);
        (scene.primary_hit(&ray, None, false), ray.d)
    };
    match hit {
        Some((mut sp, skip)) => {
            if c.spp > 1 {
                to_stratum(&mut sp, j, c.strata);
            }
            let w = if weighted {
                scene
                    .shader(sp.material)
                    .map_or(1.0, |s| s.sample_weight(&sp, sp.frame.to_local(-d)))
            } else {
                1.0
            };
            (shade_impl(scene, &sp, -d, sampler, scratch, skip), w)
        }
        None => (background(scene, d), 1.0),
    }
}

/// Fit the footprint of a sample at pixel offset `j` to its stratum of an `n × n` grid of the
/// pixel: the filter centre moves to the stratum's centre (`filter_uv`) and the differentials
/// shrink by `n`. With the stratified jitter (one sample per stratum, or the same number in
/// each) the samples' footprints tile the pixel, so a filtering material converges to the
/// pixel's box filter as `spp` grows and no sample filters around a random point. With `n = 1`
/// every sample filters the whole pixel around its centre (what one sample does).
fn to_stratum(sp: &mut ShadingPoint, j: [f64; 2], n: u32) {
    let n = f64::from(n);
    let centre = |t: f64| ((t * n).floor().min(n - 1.0) + 0.5) / n;
    let (ox, oy) = (centre(j[0]) - j[0], centre(j[1]) - j[1]);
    sp.filter_uv = sp.uv + sp.duvdx * ox + sp.duvdy * oy;
    let s = 1.0 / n;
    sp.dpdx *= s;
    sp.dpdy *= s;
    sp.duvdx *= s;
    sp.duvdy *= s;
}

/// The side of the grid of strata that the samples of a pixel fill evenly: `spp` a power of two
/// ≥ 4 gives `2^⌊log₂(spp)/2⌋` (the first `2^k` points of the pixel's Owen-scrambled Sobol
/// sequence put the same number of points in each stratum); otherwise 1 (the whole pixel).
fn strata(spp: u32) -> u32 {
    if spp >= 4 && spp.is_power_of_two() {
        1 << (spp.trailing_zeros() / 2)
    } else {
        1
    }
}

/// The average radiance of pixel `(x, y)` of a `w × h` image over `spp` samples (what
/// [`render()`] computes for that pixel). With `spp == 1` the sample is the pixel centre;
/// otherwise the pixel is jittered with the sampler's dimensions 0–1.
#[inline]
#[must_use]
#[allow(clippy::too_many_arguments)]
pub fn render_pixel(
    scene: &Scene,
    x: u32,
    y: u32,
    w: u32,
    h: u32,
    spp: u32,
    seed: u32,
    scratch: &mut ShadeScratch,
) -> [f32; 3] {
    let spp = spp.clamp(1, MAX_SAMPLES_PER_PIXEL);
    trace_pixel(
        scene,
        &PixelContext::new(scene, w, h, spp, seed),
        x,
        y,
        scratch,
    )
}

fn background(scene: &Scene, d: DVec3) -> DVec3 {
    match &scene.environment {
        Some(env) if scene.environment_visible => env.radiance(d),
        _ => DVec3::from_array(scene.image.background.map(f64::from)),
    }
}

/// The number of light samples handed to [`crate::Shader::eval_many`] at once.
pub const LIGHT_BATCH: usize = 16;

/// Reusable per-thread storage for the light samples of one shading point (about 1.5 KB),
/// so that shading does not even clear memory per pixel. Create one per tile or thread.
#[derive(Clone, Debug)]
pub struct ShadeScratch {
    wi_local: [DVec3; LIGHT_BATCH],
    wi_world: [DVec3; LIGHT_BATCH],
    /// `L/pdf · cos θi`.
    weight: [DVec3; LIGHT_BATCH],
    dist: [f64; LIGHT_BATCH],
    f: [[f32; 3]; LIGHT_BATCH],
}

impl Default for ShadeScratch {
    fn default() -> Self {
        ShadeScratch {
            wi_local: [DVec3::ZERO; LIGHT_BATCH],
            wi_world: [DVec3::ZERO; LIGHT_BATCH],
            weight: [DVec3::ZERO; LIGHT_BATCH],
            dist: [0.0; LIGHT_BATCH],
            f: [[0.0; 3]; LIGHT_BATCH],
        }
    }
}

/// Light samples gathered at one shading point, waiting for BRDF evaluation and shadow rays.
struct Batch<'a> {
    scene: &'a Scene,
    shader: &'a dyn Shader,
    sp: &'a ShadingPoint,
    wo_l: DVec3,
    origin: DVec3,
    eps: f64,
    /// The surface the shadow rays start on, when they cannot hit it again.
    skip: Skip,
    sum: DVec3,
    n: usize,
    s: &'a mut ShadeScratch,
}

impl Batch<'_> {
    /// Queue one light sample (after the geometric-normal and cosine tests).
    #[inline(always)]
    fn push(&mut self, ls: LightSample) {
        if self.sp.geometric_normal.dot(ls.wi) <= 0.0 {
            return;
        }
        let wi_l = self.sp.frame.to_local(ls.wi);
        if wi_l.z <= 0.0 {
            return;
        }
        let k = self.n;
        self.s.wi_local[k] = wi_l;
        self.s.wi_world[k] = ls.wi;
        self.s.weight[k] = ls.weight * wi_l.z;
        self.s.dist[k] = ls.dist;
        self.n += 1;
        if self.n == LIGHT_BATCH {
            self.flush();
        }
    }

    /// Evaluate the BRDF for the gathered samples, trace their shadow rays, add to `sum`.
    #[inline]
    fn flush(&mut self) {
        let (scene, sp, origin, eps) = (self.scene, self.sp, self.origin, self.eps);
        let n = self.n;
        if n == 0 {
            return;
        }
        self.shader
            .eval_many(sp, self.wo_l, &self.s.wi_local[..n], &mut self.s.f[..n]);
        for k in 0..n {
            let f = self.s.f[k];
            if f[0] <= 0.0 && f[1] <= 0.0 && f[2] <= 0.0 {
                continue;
            }
            let ray = Ray {
                o: origin,
                d: self.s.wi_world[k],
            };
            let d = self.s.dist[k];
            let tmax = if d.is_finite() {
                d * (1.0 - 1e-9) - eps
            } else {
                f64::INFINITY
            };
            if scene.occluded_skip(&ray, tmax, self.skip) {
                continue;
            }
            self.sum +=
                DVec3::new(f64::from(f[0]), f64::from(f[1]), f64::from(f[2])) * self.s.weight[k];
        }
        self.n = 0;
    }
}

/// Outgoing radiance at `sp` towards the unit world direction `wo` (one sample per light).
/// Convenience form of [`shade_with`] with a fresh scratch.
#[must_use]
pub fn shade(scene: &Scene, sp: &ShadingPoint, wo: DVec3, sampler: &PixelSampler) -> DVec3 {
    shade_with(scene, sp, wo, sampler, &mut ShadeScratch::default())
}

/// Outgoing radiance at `sp` towards the unit world direction `wo` (one sample per light),
/// using `scratch` for the light samples (gathered in batches of [`LIGHT_BATCH`]).
/// Allocation-free.
#[inline]
#[must_use]
pub fn shade_with(
    scene: &Scene,
    sp: &ShadingPoint,
    wo: DVec3,
    sampler: &PixelSampler,
    scratch: &mut ShadeScratch,
) -> DVec3 {
    shade_impl(scene, sp, wo, sampler, scratch, Skip::None)
}

/// [`shade_with`], with shadow rays that leave out the surface `skip`.
#[inline]
fn shade_impl(
    scene: &Scene,
    sp: &ShadingPoint,
    wo: DVec3,
    sampler: &PixelSampler,
    scratch: &mut ShadeScratch,
    skip: Skip,
) -> DVec3 {
    let Some(shader) = scene.shader(sp.material) else {
        return DVec3::ZERO;
    };
    let p = sp.position;
    let eps = shadow_eps(p);
    let mut batch = Batch {
        scene,
        shader,
        sp,
        wo_l: sp.frame.to_local(wo),
        origin: p + sp.geometric_normal * eps,
        eps,
        skip,
        sum: DVec3::ZERO,
        n: 0,
        s: scratch,
    };
    for (k, light) in scene.lights.iter().enumerate() {
        // Point and directional lights need no random numbers: skip the Sobol evaluation.
        let u = if light.is_delta() {
            [0.5, 0.5]
        } else {
            sampler.get2(2 + 2 * k as u32)
        };
        if let Some(ls) = light.sample(p, u) {
            batch.push(ls);
        }
    }
    if let Some(env) = &scene.environment {
        if let Some(ls) = env.sample(sampler.get2(2 + 2 * scene.lights.len() as u32)) {
            batch.push(ls);
        }
    }
    batch.flush();
    batch.sum
}

/// The offset of a shadow ray's origin along the geometric normal at `p` (world units; both
/// shading paths), relative to the point's magnitude so that it survives f64 rounding.
#[inline]
fn shadow_eps(p: DVec3) -> f64 {
    shadow_eps_xyz(p.x, p.y, p.z)
}

/// [`shadow_eps`] of the point `(x, y, z)` (for loops over coordinate arrays).
#[inline(always)]
fn shadow_eps_xyz(x: f64, y: f64, z: f64) -> f64 {
    1e-9 * (1.0 + x.abs().max(y.abs()).max(z.abs()))
}

#[cfg(test)]
mod strata_tests {
    use super::*;

    /// The footprints fitted by [`to_stratum`] tile the pixel only if the jitter of the first
    /// `spp` samples fills the `strata(spp)²` grid evenly: check it for several pixels and seeds.
    #[test]
    fn jitter_fills_the_strata_evenly() {
        for spp in [4u32, 8, 16, 32, 64, 256] {
            let n = strata(spp);
            assert!(n >= 2 && n * n <= spp);
            for (x, y, seed) in [(0, 0, 0), (17, 3, 0), (5, 900, 7), (1023, 1023, 42)] {
                let mut count = vec![0u32; (n * n) as usize];
                for s in 0..spp {
                    let (_, j) = jittered(x, y, seed, s);
                    let (a, b) = ((j[0] * f64::from(n)) as u32, (j[1] * f64::from(n)) as u32);
                    count[(b * n + a) as usize] += 1;
                }
                assert!(
                    count.iter().all(|&c| c == spp / (n * n)),
                    "spp {spp}, pixel ({x}, {y}), seed {seed}: {count:?}"
                );
            }
        }
        assert_eq!(strata(1), 1);
        assert_eq!(strata(2), 1);
        assert_eq!(strata(12), 1);
    }

    #[test]
    fn stratum_footprints_tile_the_pixel() {
        let mut sp = crate::material::local_point(glam::DVec2::new(0.3, 0.7), 0.1);
        sp.duvdy = glam::DVec2::new(0.0, 0.2);
        let base = sp;
        to_stratum(&mut sp, [0.9, 0.1], 2);
        // Stratum (1, 0): centre (0.75, 0.25), offset (−0.15, 0.15) pixels.
        assert!((sp.filter_uv - glam::DVec2::new(0.3 - 0.015, 0.7 + 0.03)).length() < 1e-12);
        assert!((sp.duvdx - base.duvdx * 0.5).length() < 1e-15);
        assert!((sp.duvdy - base.duvdy * 0.5).length() < 1e-15);
    }
}
