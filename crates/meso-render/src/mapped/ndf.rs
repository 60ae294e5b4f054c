//! [`NdfMapped`]: the NDF-mapped material, shaded from the pyramid's filtered lobes (module docs
//! of [`crate::mapped`]).

use super::*;

/// One node of a texel's filtered NDF (general facet transfers only): a unit normal with its
/// projected-area weight.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    n: DVec3,
    w: f64,
}

/// One fitted lobe of a texel, as the spherical Gaussian `c·exp(κ(a·m − 1))` of the same mean
/// cosine ([`sg::kappa_same_mean_cos`]: the lobe's projected area normalises it, see
/// [`NdfMapped`]'s docs): the constants of [`phong_texel`]'s loop, built by [`meso_core::sg`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct SgLobe {
    /// Unit axis.
    axis: DVec3,
    /// `κ · axis`.
    ka: DVec3,
    /// Concentration κ.
    kappa: f64,
    /// `η/2` of the Phong peak.
    half_eta: f64,
    /// `ln` of the Phong peak's normalisation over the Gaussian's.
    ln_ratio: f64,
    /// Area weight ÷ the texel's projected area × the Gaussian's normalisation `κ/(1 − e^{−2κ})`
    /// (without its `1/2π`, which the product integral's `2π` cancels).
    w: f64,
}

impl SgLobe {
    /// The lobe of the Phong peak `(axis, η)` with Gaussian concentration `kappa` and weight
    /// `w` (normalisation included).
    fn new(axis: DVec3, eta: f64, kappa: f64, w: f64) -> SgLobe {
        // Phong: (η + 2)/(8π); Gaussian: sg::normaliser(κ) = κ/(2π(1 − e^{−2κ})).
        let ratio = 0.25 * (eta + 2.0) / sg::normaliser_2pi(kappa);
        SgLobe {
            axis,
            ka: axis * kappa,
            kappa,
            half_eta: 0.5 * eta,
            ln_ratio: ratio.ln(),
            w,
        }
    }
}

/// One level of the filtered pyramid.
#[derive(Clone, Debug)]
struct NodeLevel {
    cols: usize,
    rows: usize,
    span: f64,
    /// Per texel, its lobes `lobes[lobe_start[t]..lobe_start[t + 1]]`.
    lobe_start: Vec<u32>,
    lobes: Vec<SgLobe>,
    /// Nodes for a general facet transfer (empty otherwise).
    node_start: Vec<u32>,
    nodes: Vec<Node>,
    horizon: Option<Vec<HorizonStats>>,
}

/// Nodes per fitted lobe (general transfers only): the axis and a ring of 6.
const RING: usize = 6;
/// Weight of the axis node.
const AXIS_WEIGHT: f64 = 0.25;

/// Replace a Phong peak by 7 weighted nodes (area weights) with the lobe's mean cosine.
fn lobe_nodes(axis: DVec3, weight: f64, exponent: f64, out: &mut Vec<Node>) {
    let mean = sg::phong_peak_mean_cos(exponent);
    let c = ((mean - AXIS_WEIGHT) / (1.0 - AXIS_WEIGHT)).clamp(-1.0, 1.0);
    if c > 1.0 - 1e-9 {
        out.push(Node { n: axis, w: weight });
        return;
    }
    let s = (1.0 - c * c).max(0.0).sqrt();
    let f = Frame::from_normal_tangent(axis, DVec3::X);
    out.push(Node {
        n: axis,
        w: weight * AXIS_WEIGHT,
    });
    for k in 0..RING {
        let a = std::f64::consts::TAU * k as f64 / RING as f64;
        out.push(Node {
            n: f.to_world(DVec3::new(s * a.cos(), s * a.sin(), c))
                .normalize(),
            w: weight * (1.0 - AXIS_WEIGHT) / RING as f64,
        });
    }
}

/// The projected area `E[m_z⁺]` of a Phong peak `((1 + a·m)/2)^(η/2)` (normalised over the
/// sphere) whose axis has `z = a_z`: the part of the lobe below the horizon covers nothing.
/// `η/(η + 4) · a_z` (which counts that part negatively) when the lobe lies above the horizon
/// to within 12 of its standard deviations `2/√η`; otherwise a quadrature over the angle α
/// from the axis with the azimuth integrated in closed form,
/// `∫₀^{2π} max(0, c + s cos φ) dφ = 2(c·acos(−c/s) + √(s² − c²))` for `|c| < s`.
fn peak_projected_area(a_z: f64, eta: f64) -> f64 {
    let a_z = a_z.clamp(-1.0, 1.0);
    let reach = 24.0 / eta.max(1e-9).sqrt();
    if a_z.acos() + reach < std::f64::consts::FRAC_PI_2 {
        return sg::phong_peak_mean_cos(eta) * a_z;
    }
    let s_a = (1.0 - a_z * a_z).max(0.0).sqrt();
    let amax = reach.min(std::f64::consts::PI);
    const N: usize = 512;
    let (mut num, mut den) = (0.0, 0.0);
    for k in 0..N {
        let a = (k as f64 + 0.5) / N as f64 * amax;
        let (sa, ca) = a.sin_cos();
        let d = (0.5 * (1.0 + ca)).powf(0.5 * eta) * sa;
        let (c, s) = (a_z * ca, s_a * sa);
        let g = if c >= s {
            std::f64::consts::TAU * c
        } else if c <= -s {
            0.0
        } else {
            2.0 * (c * (-c / s).acos() + (s * s - c * c).sqrt())
        };
        num += d * g;
        den += d * std::f64::consts::TAU;
    }
    if den > 0.0 {
        num / den
    } else {
        a_z.max(0.0)
    }
}

/// Per level and lobe of `pyramid`, the lobe's share of its texel's projected area (the
/// shares of a texel sum to 1, or are all 0 when nothing faces up).
///
/// Level 0 takes `w·E[m_z⁺]` per lobe ([`peak_projected_area`]): exact for its lobes, which are
/// the map's own normals (one cell of projected area per texel). A coarser texel collects the
/// level-0 lobes of its footprint and hands each one's projected area to its own lobes by
/// responsibility, `∝ w_l · peak_l(a_j)` (the mixture's posterior at the level-0 normal). So a
/// lobe gets the projected area of the normals it stands for, not `w·E[m_z⁺]` of its own
/// shape: a fit can make the two very different near the horizon, where a texel's area weight
/// `1/n_z` is large (100 for a normal-map texel tilted up to `n_z = 0.01`) but its projected
/// area one cell, and any spread or axis lift of the lobe that stands for it multiplies that
/// (see the module docs, "Steep maps"). Cost: one log-density per level-0 lobe, level and
/// lobe of the covering texel; the levels run in parallel.
fn projected_shares(pyramid: &Pyramid) -> Vec<Vec<f64>> {
    use rayon::prelude::*;
    let Some(l0) = pyramid.levels.first() else {
        return Vec::new();
    };
    let per_texel = |l: &meso_maps::Level, mut mass: Vec<f64>| -> Vec<f64> {
        for t in 0..l.texels() {
            let (a, b) = (l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize);
            let total: f64 = mass[a..b].iter().sum();
            for m in &mut mass[a..b] {
                *m = if total > 0.0 { *m / total } else { 0.0 };
            }
        }
        mass
    };
    // Level 0: projected area per lobe, one cell per texel.
    let base = per_texel(
        l0,
        l0.lobes
            .iter()
            .map(|p| p.weight * peak_projected_area(p.axis.z, p.exponent))
            .collect(),
    );
    let mut out = vec![base.clone()];
    out.par_extend(pyramid.levels[1..].par_iter().enumerate().map(|(k1, l)| {
        let k = k1 + 1;
        let mut mass = vec![0.0f64; l.lobes.len()];
        let mut logr = Vec::with_capacity(8);
        for row in 0..l0.rows {
            for col in 0..l0.cols {
                let ct = row * l0.cols + col;
                let pt = (row >> k).min(l.rows - 1) * l.cols + (col >> k).min(l.cols - 1);
                let (pa, pb) = (l.lobe_start[pt] as usize, l.lobe_start[pt + 1] as usize);
                if pa == pb {
                    continue;
                }
                let (ca, cb) = (l0.lobe_start[ct] as usize, l0.lobe_start[ct + 1] as usize);
                for (lobe, &mj) in l0.lobes.range(ca, cb).zip(&base[ca..cb]) {
                    let m = lobe.axis;
                    if mj <= 0.0 {
                        continue;
                    }
                    // Log responsibilities (log-sum-exp: sharp lobes underflow).
                    logr.clear();
                    let mut best = f64::NEG_INFINITY;
                    for p in l.lobes.range(pa, pb) {
                        let x = 0.5 * (1.0 + p.axis.dot(m));
                        let v = if x > 0.0 && p.weight > 0.0 {
                            p.weight.ln() + (p.exponent + 2.0).ln() + 0.5 * p.exponent * x.ln()
                        } else {
                            f64::NEG_INFINITY
                        };
                        best = best.max(v);
                        logr.push(v);
                    }
                    if best == f64::NEG_INFINITY {
                        // Opposite every lobe: the nearest axis takes it.
                        let near = (pa..pb)
                            .max_by(|&x, &y| {
                                l.lobes
                                    .get(x)
                                    .axis
                                    .dot(m)
                                    .total_cmp(&l.lobes.get(y).axis.dot(m))
                            })
                            .unwrap_or(pa);
                        mass[near] += mj;
                        continue;
                    }
                    let z: f64 = logr.iter().map(|v| (v - best).exp()).sum();
                    for (i, v) in logr.iter().enumerate() {
                        mass[pa + i] += mj * (v - best).exp() / z;
                    }
                }
            }
        }
        per_texel(l, mass)
    }));
    out
}

/// The Phong facets' response of one texel, `E[(m·h)^η (m·i)⁺]` over its projected area
/// (`m_z`-weighted, normalised), in closed form from its lobes (see [`NdfMapped`]).
/// `lambda = η + 1` is the Gaussian of the transfer (same integral over the sphere:
/// [`sg::kappa_transfer`]). The product of the lobe and the transfer's Gaussian is
/// [`sg::product`] written out on the lobe's precomputed `κa`, with its `r − κ` kept apart for
/// the shape corrections (no allocation, one `exp` per lobe).
#[inline]
fn phong_texel(lobes: &[SgLobe], wi: DVec3, h: DVec3, eta: f64, lambda: f64) -> f64 {
    let mut sum = 0.0;
    for l in lobes {
        let kah = l.ka.dot(h);
        let r = (l.kappa * l.kappa + lambda * (2.0 * kah + lambda))
            .max(1e-24)
            .sqrt();
        let inv_r = 1.0 / r;
        // Axis of the product Gaussian (unnormalised: × r).
        let m = l.ka + lambda * h;
        let mh = (kah + lambda) * inv_r;
        // Nothing to reflect when the product's axis faces away from the half vector or lies
        // below the macro surface (it has no projected area there).
        if mh <= 0.0 || m.z <= 0.0 {
            continue;
        }
        // r − κ without cancellation.
        let r_minus_k = lambda * (2.0 * kah + lambda) / (r + l.kappa);
        // exp(r − κ − λ) × (the Phong transfer / its Gaussian) × (the Phong peak / its
        // Gaussian)^β, both ratios taken at the product's axis m*: a sharp lobe gives exactly
        // (a·h)^η, a lobe much broader than the transfer its exact density at h. In between
        // the peak's ratio varies over the product's spread; β = (λ/(λ + κ))² (calibrated
        // against a quadrature, see the tests) keeps the error under 1% of the peak.
        let am = (l.kappa + lambda * l.axis.dot(h)) * inv_r;
        let am_minus_1 = -(r_minus_k - lambda * l.axis.dot(h)) * inv_r;
        let beta = lambda / (lambda + l.kappa);
        let beta = beta * beta;
        let e = (r_minus_k - lambda * mh
            + eta * mh.ln()
            + beta
                * (l.half_eta * (0.5 * (1.0 + am)).max(1e-300).ln() - l.kappa * am_minus_1
                    + l.ln_ratio))
            .exp();
        // (1 − e^{−2r}) / r, and E[(m·i)(m·z)] = (A/r) i_z + (1 − 3A/r)(m*·i)(m*·z).
        let (mass, a_r) = (sg::integral_per_2pi(r), sg::mean_cos(r) * inv_r);
        let q = a_r * wi.z + (1.0 - 3.0 * a_r) * m.dot(wi) * m.z * inv_r * inv_r;
        if q > 0.0 {
            sum += l.w * mass * q * e;
        }
    }
    sum
}

/// A material reading an NDF pyramid (see the module docs): the filtered bump map.
#[derive(Clone, Debug)]
pub struct NdfMapped {
    levels: Vec<NodeLevel>,
    facet: Facet,
    diffuse: [f32; 3],
    texels_per_uv: f64,
    shadowing: bool,
    footprint_scale: f64,
    sharp_magnification: bool,
    box_filter: bool,
}

/// Most taps of one shading call: 8 for the trilinear filter, up to 10 × 10 + 6 × 6 for the
/// box filter.
const MAX_TAPS: usize = 136;
/// Up to [`MAX_TAPS`] `(level, texel, weight)` taps of the filter.
type Taps = ([(usize, usize, f64); MAX_TAPS], usize);

impl NdfMapped {
    /// The filtered material of `pyramid` with the facet transfer and diffuse term of
    /// `surface` (its NDF is ignored), `texels_per_uv` level-0 cells per unit of texture
    /// coordinate, and horizon shadowing of the light when `shadowing` is true (needs a
    /// pyramid extracted from a height map).
    ///
    /// # Errors
    /// A message for a bad `texels_per_uv`, or shadowing asked of a pyramid without horizon
    /// statistics (normal maps).
    pub fn new(
        pyramid: &Pyramid,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<NdfMapped, String> {
        check_scale(texels_per_uv)?;
        let facet = Facet::new(&surface.transfer);
        // Lambert facets read nodes too: their response clips `m·i` and `m·o` (see `texel`).
        let general = matches!(facet, Facet::General(_) | Facet::Lambert { .. });
        let mut levels = Vec::with_capacity(pyramid.levels.len());
        let shares = projected_shares(pyramid);
        for (k, l) in pyramid.levels.iter().enumerate() {
            if shadowing && l.horizon.is_none() {
                return Err(format!(
                    "level {k} of the pyramid has no horizon statistics (a normal map?): \
                     shadowing needs a height map"
                ));
            }
            let mut lobe_start = Vec::with_capacity(l.texels() + 1);
            let mut lobes = Vec::with_capacity(l.lobes.len());
            let mut node_start = Vec::new();
            let mut nodes = Vec::new();
            let mut tmp = Vec::new();
            lobe_start.push(0u32);
            if general {
                node_start.push(0u32);
            }
            let mut src = Vec::new();
            for t in 0..l.texels() {
                src.clear();
                src.extend(
                    l.lobes
                        .range(l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize),
                );
                // Each lobe's share of the texel's projected area (see `projected_shares`)
                // and its own projected area E[m_z⁺] per unit of weight.
                let share = &shares[k][l.lobe_start[t] as usize..l.lobe_start[t + 1] as usize];
                let mut any = false;
                for (p, &sh) in src.iter().zip(share) {
                    let e = peak_projected_area(p.axis.z, p.exponent);
                    if sh <= 0.0 || e <= 1e-12 {
                        continue;
                    }
                    any = true;
                    let kappa = sg::kappa_same_mean_cos(p.exponent);
                    let norm = sg::normaliser_2pi(kappa);
                    lobes.push(SgLobe::new(p.axis, p.exponent, kappa, sh / e * norm));
                }
                if !any {
                    // No lobe faces up: shade as the flat surface.
                    let kappa = sg::kappa_same_mean_cos(meso_maps::limits::ETA_MAX);
                    lobes.push(SgLobe::new(
                        DVec3::Z,
                        meso_maps::limits::ETA_MAX,
                        kappa,
                        sg::normaliser_2pi(kappa)
                            / sg::phong_peak_mean_cos(meso_maps::limits::ETA_MAX),
                    ));
                }
                lobe_start.push(lobes.len() as u32);
                if general {
                    // Each lobe's nodes weighted by their projected area, scaled to the lobe's
                    // share.
                    let before = nodes.len();
                    for (p, &sh) in src.iter().zip(share) {
                        tmp.clear();
                        lobe_nodes(p.axis, 1.0, p.exponent, &mut tmp);
                        for n in &mut tmp {
                            n.w *= n.n.z.max(0.0);
                        }
                        let total: f64 = tmp.iter().map(|n| n.w).sum();
                        if sh > 0.0 && total > 0.0 {
                            nodes.extend(tmp.iter().filter(|n| n.w > 0.0).map(|n| Node {
                                n: n.n,
                                w: n.w / total * sh,
                            }));
                        }
                    }
                    let total: f64 = nodes[before..].iter().map(|n| n.w).sum();
                    if total > 0.0 {
                        for n in &mut nodes[before..] {
                            n.w /= total;
                        }
                    } else {
                        nodes.truncate(before);
                        nodes.push(Node {
                            n: DVec3::Z,
                            w: 1.0,
                        });
                    }
                    node_start.push(nodes.len() as u32);
                }
            }
            levels.push(NodeLevel {
                cols: l.cols,
                rows: l.rows,
                span: l.span as f64,
                lobe_start,
                lobes,
                node_start,
                nodes,
                horizon: if shadowing {
                    l.horizon.as_ref().map(meso_maps::Horizons::to_vec)
                } else {
                    None
                },
            });
        }
        if levels.is_empty() {
            return Err("the pyramid has no levels".into());
        }
        Ok(NdfMapped {
            levels,
            facet,
            diffuse: surface.diffuse.map(|a| (a * FRAC_1_PI) as f32),
            texels_per_uv,
            shadowing,
            footprint_scale: 1.0,
            sharp_magnification: false,
            box_filter: true,
        })
    }

    /// Number of pyramid levels in use.
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Use only levels `0..=max_level` (coarser footprints read `max_level`). For a tileable
    /// map any level whose texels cover whole periods describes the far field; capping skips
    /// coarse levels whose lobe fit is worse (compare their residuals in `meso map info`).
    #[must_use]
    pub fn with_max_level(mut self, max_level: usize) -> NdfMapped {
        self.levels.truncate(max_level.saturating_add(1).max(1));
        self
    }

    /// The sample's footprint at `sp` in level-0 cells (the ray differentials, which the
    /// renderer shrinks to the sample's stratum with several samples per pixel, times
    /// [`NdfMapped::with_footprint_scale`]).
    fn footprint_cells(&self, sp: &ShadingPoint) -> f64 {
        sp.uv_footprint() * self.texels_per_uv * self.footprint_scale
    }

    /// Below level 0 (footprints under √2 cells) read the cells overlapping a box narrower than
    /// the bilinear tent, down to the single cell under the point (see the module docs), so
    /// that supersampling converges to the bump map's cell averages; the default keeps the
    /// bilinear filter there, which shows magnified cells smoothly instead of as squares.
    #[must_use]
    pub fn with_sharp_magnification(mut self, sharp: bool) -> NdfMapped {
        self.sharp_magnification = sharp;
        self
    }

    /// Filter with a box the size of the sample's footprint (the bounding box of its
    /// ray-differential parallelogram): the texels it overlaps, weighted by overlap, on the
    /// level whose texels are a quarter to half its longer side (blended with the next coarser
    /// level, so zooming stays continuous) — the default, closer to the supersampled bump map
    /// on busy maps (see the module docs, "Steep maps"). `false`: the trilinear filter, 8 taps
    /// per shading call instead of up to 52.
    #[must_use]
    pub fn with_box_filter(mut self, on: bool) -> NdfMapped {
        self.box_filter = on;
        self
    }

    /// Multiply the ray-differential footprint by `scale` (> 0; default 1) before choosing the
    /// level of detail (for experiments; the renderer already fits the footprint to each
    /// sample's share of the pixel).
    #[must_use]
    pub fn with_footprint_scale(mut self, scale: f64) -> NdfMapped {
        if scale.is_finite() && scale > 0.0 {
            self.footprint_scale = scale;
        }
        self
    }

    /// The continuous level of detail used at `sp`: `log2(footprint in cells) − ½`, clamped to
    /// `[0, levels − 1]`.
    #[must_use]
    pub fn lod(&self, sp: &ShadingPoint) -> f64 {
        let fp = self.footprint_cells(sp);
        let top = (self.levels.len() - 1) as f64;
        if fp > 0.0 && fp.is_finite() {
            (fp.log2() - 0.5).clamp(0.0, top)
        } else if fp.is_finite() {
            0.0
        } else {
            top
        }
    }

    /// The taps at `sp`: trilinear, or with sharp magnification below level 0 (footprints
    /// under √2 cells) the cells
    /// overlapping a box of width `c = √(fp² − 1)` around the point (`c = 1` is the bilinear
    /// filter; the cell's own box plus this one have the footprint's variance), down to the
    /// single cell under the point.
    fn taps(&self, sp: &ShadingPoint) -> Taps {
        let fp = self.footprint_cells(sp);
        // Centred where the renderer puts the sample's filter (its stratum's centre).
        let (x, y) = (
            sp.filter_uv.x * self.texels_per_uv,
            sp.filter_uv.y * self.texels_per_uv,
        );
        let mut taps = [(0usize, 0usize, 0.0f64); MAX_TAPS];
        let mut n = 0;
        if self.sharp_magnification && fp.is_finite() && fp < std::f64::consts::SQRT_2 {
            let c = (fp * fp - 1.0).max(0.0).sqrt();
            let l = &self.levels[0];
            // Overlaps of [p − c/2, p + c/2] with the cells (at most two; weights sum to 1).
            let axis = |p: f64| -> [(i64, f64); 2] {
                if c < 1e-9 {
                    return [(p.floor() as i64, 1.0), (0, 0.0)];
                }
                let (lo, hi) = (p - 0.5 * c, p + 0.5 * c);
                let j = lo.floor();
                let w0 = ((j + 1.0).min(hi) - lo) / c;
                [(j as i64, w0), (j as i64 + 1, 1.0 - w0)]
            };
            for (r, wy) in axis(y) {
                for (cc, wx) in axis(x) {
                    let w = wx * wy;
                    if w <= 0.0 {
                        continue;
                    }
                    let col = cc.rem_euclid(l.cols as i64) as usize;
                    let row = r.rem_euclid(l.rows as i64) as usize;
                    taps[n] = (0, row * l.cols + col, w);
                    n += 1;
                }
            }
            return (taps, n);
        }
        if self.box_filter && fp.is_finite() && fp > 0.0 {
            return self.box_taps(sp, x, y);
        }
        let lod = self.lod(sp);
        let l0 = lod.floor() as usize;
        let l1 = (l0 + 1).min(self.levels.len() - 1);
        let t = lod - l0 as f64;
        for (lev, lw) in [(l0, 1.0 - t), (l1, t)] {
            if lw <= 0.0 {
                continue;
            }
            let l = &self.levels[lev];
            let tx = x / l.span - 0.5;
            let ty = y / l.span - 0.5;
            let (fx, fy) = (tx.floor(), ty.floor());
            let (ax, ay) = (tx - fx, ty - fy);
            for (dy, wy) in [(0i64, 1.0 - ay), (1, ay)] {
                for (dx, wx) in [(0i64, 1.0 - ax), (1, ax)] {
                    let w = lw * wx * wy;
                    if w <= 0.0 {
                        continue;
                    }
                    let c = (fx as i64 + dx).rem_euclid(l.cols as i64) as usize;
                    let r = (fy as i64 + dy).rem_euclid(l.rows as i64) as usize;
                    taps[n] = (lev, r * l.cols + c, w);
                    n += 1;
                }
            }
        }
        (taps, n)
    }

    /// The box filter's taps (see [`NdfMapped::with_box_filter`]) around `(x, y)` (in level-0
    /// cells).
    fn box_taps(&self, sp: &ShadingPoint, x: f64, y: f64) -> Taps {
        let k = self.texels_per_uv * self.footprint_scale;
        // The bounding box of the pixel's parallelogram in cells.
        let wx = ((sp.duvdx.x.abs() + sp.duvdy.x.abs()) * k).max(1e-9);
        let wy = ((sp.duvdx.y.abs() + sp.duvdy.y.abs()) * k).max(1e-9);
        let top = (self.levels.len() - 1) as f64;
        // Texels of an eighth to a quarter of the box's longer side: at most 10 × 10 (and 6 × 6
        // on the coarser level blended in).
        let lod = (wx.max(wy).log2() - 2.0).clamp(0.0, top);
        let l0 = lod.floor() as usize;
        let l1 = (l0 + 1).min(self.levels.len() - 1);
        let t = lod - l0 as f64;
        let mut taps = [(0usize, 0usize, 0.0f64); MAX_TAPS];
        let mut n = 0;
        for (lev, lw) in [(l0, 1.0 - t), (l1, t)] {
            if lw <= 0.0 {
                continue;
            }
            let l = &self.levels[lev];
            // Overlaps of [p − w/2, p + w/2] with the texels [c·s, (c + 1)·s), at most 10.
            let axis = |p: f64, w: f64| -> ([(i64, f64); 10], usize) {
                let mut out = [(0i64, 0.0f64); 10];
                let (lo, hi) = ((p - 0.5 * w) / l.span, (p + 0.5 * w) / l.span);
                let w = hi - lo;
                let mut m = 0;
                let mut c = lo.floor();
                while c < hi && m < 10 {
                    let o = ((c + 1.0).min(hi) - c.max(lo)) / w;
                    if o > 0.0 {
                        out[m] = (c as i64, o);
                        m += 1;
                    }
                    c += 1.0;
                }
                (out, m)
            };
            let ((ax, nx), (ay, ny)) = (axis(x, wx), axis(y, wy));
            let (sx, sy) = (
                ax[..nx].iter().map(|a| a.1).sum::<f64>(),
                ay[..ny].iter().map(|a| a.1).sum::<f64>(),
            );
            for &(r, wyr) in &ay[..ny] {
                for &(c, wxc) in &ax[..nx] {
                    if n == MAX_TAPS {
                        break;
                    }
                    let col = c.rem_euclid(l.cols as i64) as usize;
                    let row = r.rem_euclid(l.rows as i64) as usize;
                    taps[n] = (lev, row * l.cols + col, lw * wxc / sx * wyr / sy);
                    n += 1;
                }
            }
        }
        (taps, n)
    }

    /// The facets' response `E[f_μ(i, o; m) (m·i)⁺]` of texel `t` of level `l` (scalar for
    /// Phong and Lambert facets, whose colour is applied by the caller).
    #[inline]
    fn texel(&self, l: &NodeLevel, t: usize, wi: DVec3, wo: DVec3, h: DVec3) -> [f64; 3] {
        match self.facet {
            Facet::Phong { exponent, .. } => {
                let lobes = &l.lobes[l.lobe_start[t] as usize..l.lobe_start[t + 1] as usize];
                let eta = f64::from(exponent);
                [
                    phong_texel(lobes, wi, h, eta, sg::kappa_transfer(eta)),
                    0.0,
                    0.0,
                ]
            }
            Facet::Lambert { .. } => {
                let nodes = &l.nodes[l.node_start[t] as usize..l.node_start[t + 1] as usize];
                let mut a = 0.0;
                for nd in nodes {
                    if nd.n.dot(wo) > 0.0 {
                        a += nd.w * nd.n.dot(wi).max(0.0);
                    }
                }
                [a, 0.0, 0.0]
            }
            Facet::General(_) => {
                let nodes = &l.nodes[l.node_start[t] as usize..l.node_start[t + 1] as usize];
                let mut a = [0.0f64; 3];
                for nd in nodes {
                    let v = self.facet.lit(nd.n, wi, wo, h);
                    for c in 0..3 {
                        a[c] += nd.w * f64::from(v[c]);
                    }
                }
                a
            }
        }
    }
}

impl Shader for NdfMapped {
    fn eval(&self, sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        let mut out = [[0.0f32; 3]; 1];
        self.eval_many(sp, wo, &[wi], &mut out);
        out[0]
    }

    fn eval_many(&self, sp: &ShadingPoint, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
        for o in out.iter_mut() {
            *o = [0.0; 3];
        }
        if wo.z <= 0.0 {
            return;
        }
        let colour: [f64; 3] = match self.facet {
            Facet::Phong { specular, .. } => specular.map(f64::from),
            Facet::Lambert { albedo_pi } => albedo_pi.map(f64::from),
            Facet::General(_) => [1.0; 3],
        };
        let scalar = !matches!(self.facet, Facet::General(_));
        let (taps, ntaps) = self.taps(sp);
        for (k, &i) in wi.iter().enumerate() {
            let s = i + wo;
            let len = s.length();
            if i.z <= 0.0 || len <= 1e-12 {
                continue;
            }
            let h = s / len;
            let mut acc = [0.0f64; 3];
            let mut vis = 0.0f64;
            for &(lev, t, w) in &taps[..ntaps] {
                let l = &self.levels[lev];
                let v = self.texel(l, t, i, wo, h);
                if scalar {
                    acc[0] += w * v[0];
                } else {
                    for c in 0..3 {
                        acc[c] += w * v[c];
                    }
                }
                if let Some(hz) = &l.horizon {
                    vis += w * hz[t].visibility(i);
                }
            }
            let v = if self.shadowing { vis } else { 1.0 };
            let s = v / i.z;
            for c in 0..3 {
                let a = if scalar { acc[0] * colour[c] } else { acc[c] };
                out[k][c] = (a * s) as f32 + self.diffuse[c];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `E[(m·h)^η (m·i)⁺ m_z⁺] / E[m_z⁺]` over one Phong peak `cos^η_n(α/2)` by a fine
    /// quadrature in the lobe's frame (independent of the Gaussian forms).
    fn quadrature(axis: DVec3, eta_n: f64, wi: DVec3, h: DVec3, eta: f64) -> f64 {
        let f = Frame::from_normal_tangent(axis, DVec3::X);
        let amax = (12.0 * 2.0 / eta_n.sqrt()).min(std::f64::consts::PI);
        let (na, np) = (600, 240);
        let (mut num, mut den) = (0.0, 0.0);
        for ia in 0..na {
            let a = (ia as f64 + 0.5) / na as f64 * amax;
            let d = (0.5 * (1.0 + a.cos())).powf(0.5 * eta_n) * a.sin();
            for ip in 0..np {
                let p = (ip as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
                let m = f.to_world(DVec3::new(a.sin() * p.cos(), a.sin() * p.sin(), a.cos()));
                let w = d * m.z.max(0.0);
                num += w * m.dot(h).max(0.0).powf(eta) * m.dot(wi).max(0.0);
                den += w;
            }
        }
        num / den
    }

    fn closed(axis: DVec3, eta_n: f64, wi: DVec3, h: DVec3, eta: f64) -> f64 {
        let kappa = sg::kappa_same_mean_cos(eta_n);
        let area = eta_n / (eta_n + 4.0) * axis.z;
        let lobe = SgLobe::new(axis, eta_n, kappa, sg::normaliser_2pi(kappa) / area);
        phong_texel(&[lobe], wi, h, eta, sg::kappa_transfer(eta))
    }

    /// The closed form of one lobe under Phong facets agrees with the quadrature, from a
    /// delta-like lobe to one broader than the facets' highlight, near and away from the peak.
    #[test]
    fn phong_lobe_closed_form_matches_quadrature() {
        let wo = DVec3::new(0.0, -0.5, 0.866).normalize();
        let mut worst = 0.0f64;
        for (eta_n, eta) in [
            (1e5, 40.0),
            (400.0, 40.0),
            (60.0, 40.0),
            (15.0, 20.0),
            (60.0, 200.0),
        ] {
            for (tilt, wi) in [
                (10.0f64, DVec3::new(-0.75, 0.35, 0.57)),
                (25.0, DVec3::new(-0.5, 0.3, 0.8)),
                (5.0, DVec3::new(0.2, 0.6, 0.77)),
            ] {
                let wi = wi.normalize();
                let h = (wi + wo).normalize();
                let t = tilt.to_radians();
                let axis = DVec3::new(-t.sin() * 0.8, -t.sin() * 0.6, t.cos()).normalize();
                let q = quadrature(axis, eta_n, wi, h, eta);
                let c = closed(axis, eta_n, wi, h, eta);
                // Relative to the lobe's value at its peak (h on the axis), so that the far
                // tails, where both are tiny, do not dominate.
                let peak = quadrature(axis, eta_n, wi, axis, eta).max(q);
                worst = worst.max((c - q).abs() / peak);
            }
        }
        // Measured: at most 0.94% (η_n = 15 under η = 20).
        assert!(worst < 0.015, "worst error {worst} of the peak");
    }

    /// `E[m_z⁺]` of a Phong peak: the closed form above the horizon and the quadrature across
    /// it agree with a brute-force quadrature of the peak over the sphere (in the lobe's frame),
    /// and a lobe at the horizon covers far more than `μ a_z` says.
    #[test]
    fn peak_projected_area_matches_quadrature() {
        for (a_z, eta) in [
            (0.9f64, 40.0f64),
            (0.5, 4.0),
            (0.3, 40.0),
            (0.05, 4.0),
            (0.05, 100.0),
            (0.05, 1e4),
            (0.2, 1e6),
        ] {
            let axis = DVec3::new((1.0 - a_z * a_z).sqrt(), 0.0, a_z);
            let f = Frame::from_normal_tangent(axis, DVec3::Y);
            let (na, np) = (4000, 720);
            let amax = (40.0 / f64::sqrt(eta)).min(std::f64::consts::PI);
            let (mut num, mut den) = (0.0, 0.0);
            for ia in 0..na {
                let a = (ia as f64 + 0.5) / na as f64 * amax;
                let d = (0.5 * (1.0 + a.cos())).powf(0.5 * eta) * a.sin();
                for ip in 0..np {
                    let p = (ip as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
                    let m = f.to_world(DVec3::new(a.sin() * p.cos(), a.sin() * p.sin(), a.cos()));
                    num += d * m.z.max(0.0);
                    den += d;
                }
            }
            let want = num / den;
            let got = peak_projected_area(a_z, eta);
            assert!(
                (got - want).abs() < 2e-3 * want,
                "a_z {a_z}, η {eta}: {got} vs {want}"
            );
        }
        // A lobe of η = 100 at a_z = 0.05: several times μ a_z.
        assert!(peak_projected_area(0.05, 100.0) > 2.0 * 0.05 * 100.0 / 104.0);
    }

    /// The Gaussian of a Phong peak keeps its mean cosine `η/(η + 4)`
    /// ([`sg::kappa_same_mean_cos`]).
    #[test]
    fn peak_kappa_keeps_the_mean_cosine() {
        for eta in [0.5, 4.0, 40.0, 1e3, 1e6] {
            let mu = eta / (eta + 4.0);
            let k = sg::kappa_same_mean_cos(eta);
            assert!(
                (sg::mean_cos(k) - mu).abs() < 1e-9 * (1.0 + 1.0 / (1.0 - mu)),
                "{eta}: {k}"
            );
        }
    }
}
