//! Stream shading: the render loop's fast path when every material depends on the local
//! directions only ([`Shader::direction_only`]).
//!
//! The per-hit path shades each camera hit in turn: a light sample, a shader call and a shadow
//! ray per light, with a full [`crate::ShadingPoint`] moved around for each. Here a tile's hits
//! are gathered into a structure of arrays of up to [`STREAM_CHUNK`] points, and the chunk is
//! shaded light by light:
//!
//! 1. the light sample of every point (point and directional lights in a flat loop; area and
//!    environment lights through the point's sampler, with the same dimensions as the per-hit
//!    path);
//! 2. the local incident direction, masked by the geometric-normal and cosine tests;
//! 3. one [`Shader::eval_pairs`] call per run of points with the same material, so the lobe
//!    kernel runs across points, 8 (AVX2) or 16 (AVX-512) at a time;
//! 4. shadow rays where the BRDF is non-zero.
//!
//! Each hit sums its lights in the same order as the per-hit path (lights in scene order, then
//! the environment); a pixel's samples may be added in another order (misses at once, hits
//! when their chunk is shaded). Both paths therefore give the same image up to f64 rounding of
//! the sums and the f32 rounding of the BRDF kernels (`stream_matches_per_hit_path` in
//! `crates/meso-render/tests/stream.rs`).

use super::primary::{RowHits, ROW};
use super::{background, PixelContext};
use crate::camera::Ray;
use crate::light::LightSample;
use crate::sampling::PixelSampler;
use crate::scene::{Scene, Skip};
use glam::DVec3;

/// Camera hits shaded together (a multiple of the kernels' block sizes).
pub(crate) const STREAM_CHUNK: usize = 256;
const _: () = assert!(STREAM_CHUNK.is_multiple_of(2 * BLOCK));

/// `STREAM_CHUNK` values of one quantity (allocated once per thread). A fixed size, so that
/// indices reduced modulo `STREAM_CHUNK` need no bounds checks.
type Lane<T> = Box<[T; STREAM_CHUNK]>;

fn lane<T: Copy>(v: T) -> Lane<T> {
    Box::new([v; STREAM_CHUNK])
}

fn lanes3<T: Copy>(v: T) -> [Lane<T>; 3] {
    [lane(v), lane(v), lane(v)]
}

/// Per-thread storage of the stream path (about 60 KB, allocated once per tile batch).
pub(crate) struct StreamScratch {
    /// The current tile's radiance sums per pixel (taken out while the tile renders).
    acc: Vec<DVec3>,
    /// The current row segment's camera rays and hits.
    row: Box<RowHits>,
    n: usize,
    /// Index of the hit's pixel in the tile buffer.
    slot: Lane<u32>,
    /// Pixel and sample index, to rebuild the sampler for area and environment lights.
    px: Lane<u32>,
    py: Lane<u32>,
    sample: Lane<u32>,
    material: Lane<u32>,
    skip: Lane<Skip>,
    /// The offset of the shadow-ray origin along the geometric normal.
    eps: Lane<f64>,
    p: [Lane<f64>; 3],
    ng: [Lane<f64>; 3],
    /// Shading frame: tangent, bitangent, normal (world).
    t: [Lane<f64>; 3],
    b: [Lane<f64>; 3],
    nrm: [Lane<f64>; 3],
    /// Direction to the viewer, local frame.
    wo: [Lane<f32>; 3],
    /// The current light: world direction, distance, `L/pdf · cos θi` (0 when masked).
    wi: [Lane<f64>; 3],
    dist: Lane<f64>,
    weight: [Lane<f64>; 3],
    /// The current light: local direction (below the horizon when masked) and the BRDF.
    wi_local: [Lane<f32>; 3],
    f: [Lane<f32>; 3],
    /// The BRDF scattered back to the hits (0 where unlit or shadowed).
    fs: [Lane<f32>; 3],
    /// Radiance of each hit so far.
    sum: [Lane<f64>; 3],
    /// The current light's lit hits (indices) and their gathered local directions and
    /// materials (the input of `eval_pairs`).
    lit: Lane<u32>,
    gi: [Lane<f32>; 3],
    go: [Lane<f32>; 3],
    gm: Lane<u32>,
}

impl Default for StreamScratch {
    fn default() -> Self {
        StreamScratch {
            acc: Vec::new(),
            row: Box::default(),
            n: 0,
            slot: lane(0),
            px: lane(0),
            py: lane(0),
            sample: lane(0),
            material: lane(0),
            skip: lane(Skip::None),
            eps: lane(0.0),
            p: lanes3(0.0),
            ng: lanes3(0.0),
            t: lanes3(0.0),
            b: lanes3(0.0),
            nrm: lanes3(0.0),
            wo: lanes3(0.0),
            wi: lanes3(0.0),
            dist: lane(0.0),
            weight: lanes3(0.0),
            wi_local: lanes3(0.0),
            f: lanes3(0.0),
            fs: lanes3(0.0),
            sum: lanes3(0.0),
            lit: lane(0),
            gi: lanes3(0.0),
            go: lanes3(0.0),
            gm: lane(0),
        }
    }
}

/// Render the pixels `x0..x1 × y0..y1` into `buf` (row-major, cleared by the caller) by
/// stream shading. Primary rays go in stages over a row of the tile (all rays, then all
/// closest hits, then the hits' frames into the chunk), so that the long-latency square roots
/// and divisions of neighbouring pixels overlap instead of forming one chain per pixel.
pub(crate) fn render_tile(
    scene: &Scene,
    c: &PixelContext,
    (x0, x1): (u32, u32),
    (y0, y1): (u32, u32),
    s: &mut StreamScratch,
    buf: &mut Vec<[f32; 3]>,
) {
    let tw = (x1 - x0) as usize;
    // The tile's radiance sums, kept in the scratch between tiles (no allocation per tile).
    let mut acc = std::mem::take(&mut s.acc);
    acc.clear();
    acc.resize(tw * (y1 - y0) as usize, DVec3::ZERO);
    for y in y0..y1 {
        for k in 0..c.spp {
            let mut xa = x0;
            while xa < x1 {
                let xb = (xa + ROW as u32).min(x1);
                s.row.trace(scene, c, (xa, xb), y, k);
                let base = (y - y0) as usize * tw + (xa - x0) as usize;
                // Runs of consecutive hits go into the chunk as slices; misses see the
                // background.
                let n = s.row.n.min(ROW);
                let mut j = 0;
                while j < n {
                    if !s.row.hit[j] {
                        let r = &s.row;
                        let d = DVec3::new(r.d[0][j], r.d[1][j], r.d[2][j]);
                        acc[base + j] += background(scene, d);
                        j += 1;
                        continue;
                    }
                    let mut end = j + 1;
                    while end < n && s.row.hit[end] {
                        end += 1;
                    }
                    while j < end {
                        let take = (end - j).min(STREAM_CHUNK - s.n);
                        push_run(s, j..j + take, base, (xa, y, k));
                        j += take;
                        if s.n == STREAM_CHUNK {
                            shade_chunk(scene, c, s, &mut acc);
                        }
                    }
                }
                xa = xb;
            }
        }
    }
    shade_chunk(scene, c, s, &mut acc);
    let inv = 1.0 / f64::from(c.spp);
    buf.extend(acc.iter().map(|a| {
        let a = if c.spp == 1 { *a } else { *a * inv };
        [a.x as f32, a.y as f32, a.z as f32]
    }));
    s.acc = acc;
}

/// Append hits `js` of the current row segment (all hits, and room for them in the chunk)
/// to the chunk; hit `j` is pixel `base + j` of the tile buffer, at image `(xa + j, y)`,
/// sample `k`.
#[inline]
fn push_run(
    s: &mut StreamScratch,
    js: std::ops::Range<usize>,
    base: usize,
    (xa, y, k): (u32, u32, u32),
) {
    let (i0, m) = (s.n, js.len());
    debug_assert!(i0 + m <= STREAM_CHUNK && js.end <= ROW);
    let dst = i0..i0 + m;
    let r = &*s.row;
    for (q, j) in js.clone().enumerate() {
        s.slot[i0 + q] = (base + j) as u32;
        s.px[i0 + q] = xa + j as u32;
    }
    s.py[dst.clone()].fill(y);
    s.sample[dst.clone()].fill(k);
    s.material[dst.clone()].copy_from_slice(&r.material[js.clone()]);
    s.skip[dst.clone()].copy_from_slice(&r.skip[js.clone()]);
    s.eps[dst.clone()].copy_from_slice(&r.eps[js.clone()]);
    for c in 0..3 {
        s.p[c][dst.clone()].copy_from_slice(&r.p[c][js.clone()]);
        s.ng[c][dst.clone()].copy_from_slice(&r.ng[c][js.clone()]);
        s.t[c][dst.clone()].copy_from_slice(&r.ft[c][js.clone()]);
        s.b[c][dst.clone()].copy_from_slice(&r.fb[c][js.clone()]);
        s.nrm[c][dst.clone()].copy_from_slice(&r.fnrm[c][js.clone()]);
        s.wo[c][dst.clone()].copy_from_slice(&r.wo[c][js.clone()]);
        s.sum[c][dst.clone()].fill(0.0);
    }
    s.n += m;
}

/// Shade every hit of the chunk (all lights, then the environment), add the radiance to the
/// hits' pixels in `acc` and empty the chunk.
///
/// The chunk's loops are compiled three times (AVX-512, AVX2 + FMA, baseline x86-64 or other
/// architectures) and the running CPU picks one, so that the flat loops over the chunk's
/// arrays (light samples, masks, the accumulation) use the widest vectors it has.
fn shade_chunk(scene: &Scene, c: &PixelContext, s: &mut StreamScratch, acc: &mut [DVec3]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the running CPU supports AVX-512F/VL, AVX2 and FMA (checked just above).
            unsafe { shade_chunk_avx512(scene, c, s, acc) };
            return;
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the running CPU supports AVX2 and FMA (checked just above).
            unsafe { shade_chunk_avx2(scene, c, s, acc) };
            return;
        }
    }
    shade_chunk_impl::<BLOCK>(scene, c, s, acc);
}

/// [`shade_chunk`] compiled for AVX2 + FMA (light samples 4 hits per block).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn shade_chunk_avx2(
    scene: &Scene,
    c: &PixelContext,
    s: &mut StreamScratch,
    acc: &mut [DVec3],
) {
    shade_chunk_impl::<BLOCK>(scene, c, s, acc);
}

/// [`shade_chunk`] compiled for AVX-512 (light samples 8 hits per block).
///
/// # Safety
/// The CPU must support AVX-512F, AVX-512VL, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
unsafe fn shade_chunk_avx512(
    scene: &Scene,
    c: &PixelContext,
    s: &mut StreamScratch,
    acc: &mut [DVec3],
) {
    shade_chunk_impl::<{ 2 * BLOCK }>(scene, c, s, acc);
}

/// The body of [`shade_chunk`]; `B` is the light-sample block size.
#[inline(always)]
fn shade_chunk_impl<const B: usize>(
    scene: &Scene,
    c: &PixelContext,
    s: &mut StreamScratch,
    acc: &mut [DVec3],
) {
    let n = s.n;
    if n == 0 {
        return;
    }
    for (k, light) in scene.lights.iter().enumerate() {
        match *light {
            crate::Light::Point {
                position,
                intensity,
            } => delta_samples::<B>(s, Some(position), DVec3::ZERO, intensity),
            crate::Light::Directional {
                direction,
                irradiance,
            } => delta_samples::<B>(s, None, direction, irradiance),
            _ => {
                for i in 0..n {
                    let sm = PixelSampler::deferred(s.px[i], s.py[i], c.seed, s.sample[i]);
                    let p = DVec3::new(s.p[0][i], s.p[1][i], s.p[2][i]);
                    set_sample(s, i, light.sample(p, sm.get2(2 + 2 * k as u32)));
                }
            }
        }
        light_pass(scene, s);
    }
    if let Some(env) = &scene.environment {
        let dim = 2 + 2 * scene.lights.len() as u32;
        for i in 0..n {
            let sm = PixelSampler::deferred(s.px[i], s.py[i], c.seed, s.sample[i]);
            set_sample(s, i, env.sample(sm.get2(dim)));
        }
        light_pass(scene, s);
    }
    for i in 0..n {
        acc[s.slot[i] as usize] += DVec3::new(s.sum[0][i], s.sum[1][i], s.sum[2][i]);
    }
    s.n = 0;
}

/// Hits per block of [`delta_samples`] (one AVX register of f64; twice that with AVX-512).
const BLOCK: usize = 4;

/// `B` values of each of three components.
type Block3<const B: usize> = [[f64; B]; 3];

/// Copy lanes `base..base + B` of three arrays into a block.
#[inline(always)]
fn load3<const B: usize>(v: &[Lane<f64>; 3], base: usize, out: &mut Block3<B>) {
    for c in 0..3 {
        out[c] = v[c][base..base + B].try_into().expect("block in range");
    }
}

/// Point-light (`Some(position)`) or directional (`None`, `wi = direction`) samples and the
/// masks for the whole chunk, `B` hits per block: the arithmetic of [`crate::Light::sample`]
/// and of the per-hit path's tests, in one flat loop over the chunk's arrays that the compiler
/// vectorises.
#[inline(always)]
fn delta_samples<const B: usize>(
    s: &mut StreamScratch,
    position: Option<DVec3>,
    direction: DVec3,
    power: DVec3,
) {
    let n = s.n;
    let point = position.is_some();
    let lp = position.unwrap_or(DVec3::ZERO).to_array();
    let dir = direction.to_array();
    let pw = power.to_array();
    let mut base = 0;
    // Blocks of local arrays: the compiler keeps them in vector registers.
    let (mut p, mut g, mut t, mut b, mut nn) = (
        [[1.0; B]; 3],
        [[0.0; B]; 3],
        [[0.0; B]; 3],
        [[0.0; B]; 3],
        [[0.0; B]; 3],
    );
    // Whole blocks: lanes past `n` (up to the chunk's capacity, a multiple of B) hold
    // stale but finite values and their results are never read.
    while base < n {
        load3(&s.p, base, &mut p);
        load3(&s.ng, base, &mut g);
        load3(&s.t, base, &mut t);
        load3(&s.b, base, &mut b);
        load3(&s.nrm, base, &mut nn);
        let mut u: Block3<B> = [[0.0; B]; 3];
        let mut l: [[f32; B]; 3] = [[0.0; B]; 3];
        let mut w: Block3<B> = [[0.0; B]; 3];
        let mut r = [f64::INFINITY; B];
        for j in 0..B {
            // As `Light::sample`: d = position − p, r = |d|, wi = d/r, weight = I/r².
            let (ux, uy, uz, a, ok_r) = if point {
                let (dx, dy, dz) = (lp[0] - p[0][j], lp[1] - p[1][j], lp[2] - p[2][j]);
                let r2 = dx * dx + dy * dy + dz * dz;
                r[j] = r2.sqrt();
                let inv = 1.0 / r[j];
                (dx * inv, dy * inv, dz * inv, inv * inv, r2 > 0.0)
            } else {
                (dir[0], dir[1], dir[2], 1.0, true)
            };
            let cg = g[0][j] * ux + g[1][j] * uy + g[2][j] * uz;
            let l0 = ux * t[0][j] + uy * t[1][j] + uz * t[2][j];
            let l1 = ux * b[0][j] + uy * b[1][j] + uz * b[2][j];
            let l2 = ux * nn[0][j] + uy * nn[1][j] + uz * nn[2][j];
            let ok = ok_r && cg > 0.0 && l2 > 0.0;
            u[0][j] = ux;
            u[1][j] = uy;
            u[2][j] = uz;
            for c in 0..3 {
                let wc = if point { pw[c] * a * l2 } else { pw[c] * l2 };
                w[c][j] = if ok { wc } else { 0.0 };
            }
            l[0][j] = if ok { l0 as f32 } else { 0.0 };
            l[1][j] = if ok { l1 as f32 } else { 0.0 };
            l[2][j] = if ok { l2 as f32 } else { -1.0 };
        }
        for c in 0..3 {
            s.wi[c][base..base + B].copy_from_slice(&u[c]);
            s.weight[c][base..base + B].copy_from_slice(&w[c]);
            s.wi_local[c][base..base + B].copy_from_slice(&l[c]);
        }
        s.dist[base..base + B].copy_from_slice(&r);
        base += B;
    }
}

/// Store the light sample of hit `i` after the per-hit path's tests: light from below the
/// geometric surface or the shading horizon is masked (zero weight, a below-horizon local
/// direction so the BRDF kernel returns 0).
#[inline(always)]
fn set_sample(s: &mut StreamScratch, i: usize, ls: Option<LightSample>) {
    let mut keep = None;
    if let Some(ls) = ls {
        let ng = DVec3::new(s.ng[0][i], s.ng[1][i], s.ng[2][i]);
        if ng.dot(ls.wi) > 0.0 {
            let wi = ls.wi;
            let l = DVec3::new(
                wi.dot(DVec3::new(s.t[0][i], s.t[1][i], s.t[2][i])),
                wi.dot(DVec3::new(s.b[0][i], s.b[1][i], s.b[2][i])),
                wi.dot(DVec3::new(s.nrm[0][i], s.nrm[1][i], s.nrm[2][i])),
            );
            if l.z > 0.0 {
                keep = Some((ls, l));
            }
        }
    }
    match keep {
        Some((ls, l)) => {
            let w = ls.weight * l.z;
            for c in 0..3 {
                s.wi[c][i] = ls.wi[c];
                s.weight[c][i] = w[c];
                s.wi_local[c][i] = l[c] as f32;
            }
            s.dist[i] = ls.dist;
        }
        None => {
            for c in 0..3 {
                s.weight[c][i] = 0.0;
            }
            s.wi_local[0][i] = 0.0;
            s.wi_local[1][i] = 0.0;
            s.wi_local[2][i] = -1.0;
        }
    }
}

/// Evaluate the BRDF for the current light at the lit hits of the chunk (gathered first, then
/// one [`crate::Shader::eval_pairs`] call per run of equal materials), trace their shadow rays
/// where the BRDF is non-zero and add their radiance.
#[inline(always)]
fn light_pass(scene: &Scene, s: &mut StreamScratch) {
    let n = s.n;
    // Gather the lit hits (masked ones have a below-horizon local direction).
    let mut m = 0;
    {
        let (lx, ly, lz) = (
            &s.wi_local[0][..n],
            &s.wi_local[1][..n],
            &s.wi_local[2][..n],
        );
        let (ox, oy, oz) = (&s.wo[0][..n], &s.wo[1][..n], &s.wo[2][..n]);
        let mat = &s.material[..n];
        let lit = &mut s.lit[..n];
        let [gi0, gi1, gi2] = &mut s.gi;
        let (gi0, gi1, gi2) = (&mut gi0[..n], &mut gi1[..n], &mut gi2[..n]);
        let [go0, go1, go2] = &mut s.go;
        let (go0, go1, go2) = (&mut go0[..n], &mut go1[..n], &mut go2[..n]);
        let gm = &mut s.gm[..n];
        for i in 0..n {
            if lz[i] > 0.0 {
                lit[m] = i as u32;
                gi0[m] = lx[i];
                gi1[m] = ly[i];
                gi2[m] = lz[i];
                go0[m] = ox[i];
                go1[m] = oy[i];
                go2[m] = oz[i];
                gm[m] = mat[i];
                m += 1;
            }
        }
    }
    let mut a = 0;
    while a < m {
        let mat = s.gm[a];
        let mut b = a + 1;
        while b < m && s.gm[b] == mat {
            b += 1;
        }
        let [f0, f1, f2] = &mut s.f;
        match scene.shader(crate::MaterialId(mat)) {
            Some(shader) => shader.eval_pairs(
                [&s.gi[0][a..b], &s.gi[1][a..b], &s.gi[2][a..b]],
                [&s.go[0][a..b], &s.go[1][a..b], &s.go[2][a..b]],
                [&mut f0[a..b], &mut f1[a..b], &mut f2[a..b]],
            ),
            None => {
                for f in [f0, f1, f2] {
                    f[a..b].fill(0.0);
                }
            }
        }
        a = b;
    }
    // Scatter the BRDF back to the hits (unlit and shadowed hits keep 0), then add
    // `f · weight` over the whole chunk in one flat loop that the compiler vectorises.
    for fc in &mut s.fs {
        fc[..n].fill(0.0);
    }
    let single = scene.single_convex_prim();
    for k in 0..m.min(STREAM_CHUNK) {
        let f = [s.f[0][k], s.f[1][k], s.f[2][k]];
        let i = s.lit[k] as usize % STREAM_CHUNK;
        // A lone convex primitive left on the lit side cannot shadow itself.
        let may_shadow = !(single && s.skip[i] != Skip::None);
        if may_shadow && (f[0] > 0.0 || f[1] > 0.0 || f[2] > 0.0) {
            let ray = Ray {
                // As the per-hit path: leave on the geometric normal's side.
                o: DVec3::new(s.p[0][i], s.p[1][i], s.p[2][i])
                    + DVec3::new(s.ng[0][i], s.ng[1][i], s.ng[2][i]) * s.eps[i],
                d: DVec3::new(s.wi[0][i], s.wi[1][i], s.wi[2][i]),
            };
            let d = s.dist[i];
            let tmax = if d.is_finite() {
                d * (1.0 - 1e-9) - s.eps[i]
            } else {
                f64::INFINITY
            };
            if scene.occluded_skip(&ray, tmax, s.skip[i]) {
                continue;
            }
        }
        for (c, fc) in f.iter().enumerate() {
            s.fs[c][i] = *fc;
        }
    }
    for c in 0..3 {
        let (sum, fs, w) = (&mut s.sum[c][..n], &s.fs[c][..n], &s.weight[c][..n]);
        for ((a, f), w) in sum.iter_mut().zip(fs).zip(w) {
            *a += f64::from(*f) * *w;
        }
    }
}
