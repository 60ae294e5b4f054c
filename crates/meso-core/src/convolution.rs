//! The convolution of Eq. 2 / Eq. 8: an NDF and a facet transfer function make the effective BRDF.
//!
//! # The two forms
//! **Multiple surface** (the default, §4): each facet is lit with its own cosine and nothing else
//! is tested,
//! ```text
//! f(i, o) = ∫_{S²} n(m) f_μ(i, o; m) max(0, m·i) dω_m / cos θ_i .
//! ```
//! For a delta sum this is the exact finite sum of Eq. 4 / Eq. 11. It is **neither reciprocal nor
//! energy conserving** in general: the `1/cos θ_i` and `max(0, m·i)` factors are not symmetric in
//! `i, o`, facets facing away from the viewer still reflect, and facets below the horizon are lit.
//! The tests measure by how much.
//!
//! **Microfacet** (Walter et al. 2007; Heitz 2014): facets are weighted by their projected area and
//! visibility,
//! ```text
//! f(i, o) = ∫_{z>0} D(m) f_μ(i, o; m) (i·m)⁺ (o·m)⁺ / (cos θ_i cos θ_o) dω_m · G₂(i, o),
//! D(m) = n(m) / ∫_{z>0} n (m·z) dω,   Λ(ω) = ∫ D(m) (ω·m)⁺ dω_m / cos θ_ω − 1,
//! G₂ = 1 / (1 + Λ(i) + Λ(o))   (height-correlated Smith, computed numerically for any NDF).
//! ```
//! With a mirror facet the integral collapses to the classic `D(h) F G₂ / (4 cos θ_i cos θ_o)`,
//! times the mirror's per-channel `specular` scale; it is reciprocal, and under a white furnace
//! it never gains energy (the scale is at most 1).
//!
//! # Quadrature
//! The integrals over normals are [`crate::integrate`]'s lobe-adapted quadrature ([`integrate`],
//! [`Accuracy`], [`Peak`], re-exported here where callers have always found them).
//!
//! # Closed form
//! [`phong_closed_form`] approximates Phong peaks × a Phong (N·H) transfer through the von
//! Mises–Fisher correspondence `cos^η(α/2) ≈ exp(κ₁(cos α − 1))` and `(m·H)^η ≈ exp(κ₂(m·H − 1))`
//! (κ₁ = (η+2)/4 and κ₂ = η+1 keep the lobes' integrals): a product of two vMF lobes is a vMF lobe,
//! whose integral is closed; the clamped cosine `max(0, m·i)` is averaged over that lobe exactly
//! through a small precomputed table. Errors are measured in docs/benchmarks.md.

use crate::frame::{half_vector, Frame};
pub use crate::integrate::{integrate, Accuracy, Peak};
use crate::ndf::{Ndf, PhongLobe};
use crate::quadrature::gauss_legendre;
use crate::transfer::Transfer;
use crate::visibility::VisibilityModel;
use glam::DVec3;
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Which convolution (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Form {
    /// `∫ n f_μ (m·i)⁺ dω / cos θ_i` — the multiple surface of §4 (default).
    #[default]
    MultipleSurface,
    /// Projected-area weighting with height-correlated Smith masking–shadowing.
    Microfacet,
}

/// The masking–shadowing term of the microfacet form.
#[derive(Clone, Copy)]
pub enum Visibility<'a> {
    /// Height-correlated Smith `G₂` computed numerically from the NDF (the default).
    Smith,
    /// No masking or shadowing (`G = 1`).
    None,
    /// A caller's model `G(i, o)` (e.g. filtered horizon angles of a height map), in `[0, 1]`.
    Custom(&'a (dyn Fn(DVec3, DVec3) -> f64 + Sync)),
    /// A caller's model conditioned on the facet normal, `G(i, o | m)` in `[0, 1]` (the
    /// fraction of the facets of normal `m` lit from `i` and seen from `o`, e.g. from a height
    /// map's geometry): applied inside the integral, so that bumps and grooves with the same NDF
    /// get different BRDFs. Delta sums ask it for all their deltas at once
    /// ([`VisibilityModel::g_given_deltas`]).
    GivenNormal(&'a dyn VisibilityModel),
}

/// The effective BRDF `f(i, o)` (RGB, 1/sr, no cosine factor) of an NDF with a facet transfer
/// function, in the given [`Form`] (Smith masking for the microfacet form). `i`, `o` are unit
/// directions in the local frame; 0 when either is below the surface.
#[must_use]
pub fn effective_brdf(
    ndf: &Ndf,
    transfer: &Transfer,
    form: Form,
    i: DVec3,
    o: DVec3,
    accuracy: Accuracy,
) -> [f64; 3] {
    effective_brdf_with(ndf, transfer, form, Visibility::Smith, i, o, accuracy)
}

/// [`effective_brdf`] with a chosen [`Visibility`] for the microfacet form (ignored by the
/// multiple-surface form, which tests no visibility).
#[must_use]
pub fn effective_brdf_with(
    ndf: &Ndf,
    transfer: &Transfer,
    form: Form,
    visibility: Visibility<'_>,
    i: DVec3,
    o: DVec3,
    accuracy: Accuracy,
) -> [f64; 3] {
    if i.z <= 0.0 || o.z <= 0.0 {
        return [0.0; 3];
    }
    match form {
        Form::MultipleSurface => {
            if let Transfer::Mirror { .. } = transfer {
                let Some(h) = half_vector(i, o) else {
                    return [0.0; 3];
                };
                let n = ndf.eval(h);
                let f = transfer.mirror_reflectance(i.dot(h)).unwrap_or([0.0; 3]);
                let c = n / (4.0 * o.dot(h) * i.z);
                return [f[0] * c, f[1] * c, f[2] * c];
            }
            let hint = transfer.peak(i, o);
            let r = integrate(ndf, accuracy, hint, |m| {
                let cos_mi = m.dot(i);
                if cos_mi <= 0.0 {
                    return [0.0; 3];
                }
                let fr = Frame::from_normal_tangent(m, DVec3::X);
                let v = transfer.eval(fr.to_local(i), fr.to_local(o));
                [v[0] * cos_mi, v[1] * cos_mi, v[2] * cos_mi]
            });
            [r[0] / i.z, r[1] / i.z, r[2] / i.z]
        }
        Form::Microfacet => {
            let masking = SmithMasking::new(ndf, accuracy);
            let given = match visibility {
                Visibility::GivenNormal(g) => Some(g),
                _ => None,
            };
            let g2 = match visibility {
                Visibility::Smith => 1.0 / (1.0 + masking.lambda(i) + masking.lambda(o)),
                Visibility::None | Visibility::GivenNormal(_) => 1.0,
                Visibility::Custom(g) => g(i, o).clamp(0.0, 1.0),
            };
            if let Transfer::Mirror { .. } = transfer {
                let Some(h) = half_vector(i, o) else {
                    return [0.0; 3];
                };
                if h.z <= 0.0 {
                    return [0.0; 3];
                }
                let d = ndf.eval(h) / masking.projected_area;
                let f = transfer.mirror_reflectance(i.dot(h)).unwrap_or([0.0; 3]);
                let g2 = given.map_or(g2, |g| g.g_given_normal(i, o, h).clamp(0.0, 1.0));
                let c = d * g2 / (4.0 * i.z * o.z);
                return [f[0] * c, f[1] * c, f[2] * c];
            }
            if let Ndf::Deltas(d) = ndf {
                // Exact finite sum; `g2` is 1 when the visibility is conditioned (inside).
                let r = deltas_microfacet(d, transfer, given, i, o);
                let s = g2 / (masking.projected_area * i.z * o.z);
                return [r[0] * s, r[1] * s, r[2] * s];
            }
            let hint = transfer.peak(i, o);
            let r = integrate(ndf, accuracy, hint, |m| {
                if m.z <= 0.0 {
                    return [0.0; 3];
                }
                let (ci, co) = (m.dot(i), m.dot(o));
                if ci <= 0.0 || co <= 0.0 {
                    return [0.0; 3];
                }
                let fr = Frame::from_normal_tangent(m, DVec3::X);
                let v = transfer.eval(fr.to_local(i), fr.to_local(o));
                if v == [0.0; 3] {
                    return v;
                }
                let c = ci * co * given.map_or(1.0, |g| g.g_given_normal(i, o, m).clamp(0.0, 1.0));
                [v[0] * c, v[1] * c, v[2] * c]
            });
            let s = g2 / (masking.projected_area * i.z * o.z);
            [r[0] * s, r[1] * s, r[2] * s]
        }
    }
}

/// The largest share of a delta sum's result that the normals outside a transfer's support cap
/// may hold for the cap alone to be summed ([`crate::transfer::Transfer::support`]).
pub const CAP_TAIL: f64 = 1e-5;

/// The share of a delta sum's result (before visibility) that may be summed without each
/// delta's own visibility: the smallest contributions whose total is at most this fraction take
/// the contribution-weighted mean `G` of the others, so the result moves by at most this
/// fraction of itself (`G ∈ [0, 1]`).
pub const VISIBILITY_TAIL: f64 = 1e-5;

/// `Σ_k w_k f_μ(i, o; m_k)(i·m_k)(o·m_k) G(i, o | m_k)` over the deltas above the horizon (the
/// microfacet integrand of a delta sum; `G = 1` without a normal-conditioned visibility `g`).
/// Transfers with a support cap visit only the normals in it when the rest cannot matter
/// ([`CAP_TAIL`]). Two passes: the contributions without `G`, then `G` for all but the smallest
/// ones that add up to at most [`VISIBILITY_TAIL`] of the total (found by a histogram of their
/// sizes in powers of two); the others take the contribution-weighted mean `G` of those
/// evaluated.
fn deltas_microfacet(
    d: &crate::ndf::DeltaSum,
    transfer: &Transfer,
    g: Option<&dyn VisibilityModel>,
    i: DVec3,
    o: DVec3,
) -> [f64; 3] {
    thread_local! {
        static SCRATCH: std::cell::RefCell<DeltaScratch> =
            const { std::cell::RefCell::new(DeltaScratch { contrib: Vec::new(), ks: Vec::new(), gs: Vec::new() }) };
    }
    SCRATCH.with(|c| deltas_microfacet_in(&mut c.borrow_mut(), d, transfer, g, i, o))
}

/// Per-thread buffers of [`deltas_microfacet`] (nothing allocates per pair once warm).
struct DeltaScratch {
    /// Contributing deltas and their contributions without `G`.
    contrib: Vec<(u32, [f64; 3])>,
    /// The deltas whose `G` is asked for, and the answers.
    ks: Vec<u32>,
    gs: Vec<f64>,
}

fn deltas_microfacet_in(
    s: &mut DeltaScratch,
    d: &crate::ndf::DeltaSum,
    transfer: &Transfer,
    g: Option<&dyn VisibilityModel>,
    i: DVec3,
    o: DVec3,
) -> [f64; 3] {
    s.contrib.clear();
    s.ks.clear();
    let h = half_vector(i, o);
    let normals = d.normals();
    // (peak, total) of the contributions found.
    let visit = |k: usize, contrib: &mut Vec<(u32, [f64; 3])>, acc: &mut (f64, f64)| {
        let wn = normals[k];
        let m = wn.normal;
        if m.z <= 0.0 {
            return;
        }
        let (ci, co) = (m.dot(i), m.dot(o));
        if ci <= 0.0 || co <= 0.0 {
            return;
        }
        let v = transfer.eval_facet(m, i, o, h);
        let c = wn.weight * ci * co;
        let v = [v[0] * c, v[1] * c, v[2] * c];
        let mx = v[0].max(v[1]).max(v[2]);
        if mx > 0.0 {
            acc.0 = acc.0.max(mx);
            acc.1 += mx;
            contrib.push((k as u32, v));
        }
    };
    // Transfers with a bounded support (Beckmann, sharp Phong) visit only the normals near
    // the half vector, when what the others could add (at most `bound`, the weights summing
    // to 1) is below CAP_TAIL of what the cap holds; otherwise every normal.
    let mut acc = (0.0f64, 0.0f64);
    let support = transfer.support(i, o);
    if let Some(sp) = support {
        d.for_each_in_cap(sp.axis, sp.cos_radius, |k| {
            if normals[k].normal.dot(sp.axis) >= sp.cos_radius {
                visit(k, &mut s.contrib, &mut acc);
            }
        });
    }
    if support.is_none_or(|sp| sp.bound > CAP_TAIL * acc.1) {
        s.contrib.clear();
        acc = (0.0, 0.0);
        for k in 0..normals.len() {
            visit(k, &mut s.contrib, &mut acc);
        }
    }
    let peak = acc.0;
    let Some(g) = g else {
        let mut r = [0.0; 3];
        for (_, v) in &s.contrib {
            for c in 0..3 {
                r[c] += v[c];
            }
        }
        return r;
    };
    // Ask for G of the deltas that matter, all at once; the contributions stay in order.
    let cut = tail_cut(&s.contrib, peak);
    s.ks.extend(
        s.contrib
            .iter()
            .filter(|(_, v)| v[0].max(v[1]).max(v[2]) >= cut)
            .map(|(k, _)| *k),
    );
    s.gs.clear();
    s.gs.resize(s.ks.len(), 1.0);
    g.g_given_deltas(i, o, d.normals(), &s.ks, &mut s.gs);
    let (mut acc, mut rest) = ([0.0; 3], [0.0; 3]);
    let (mut gsum, mut wsum) = (0.0, 0.0);
    let mut next = 0;
    for (_, v) in &s.contrib {
        let mx = v[0].max(v[1]).max(v[2]);
        if mx >= cut {
            let gk = s.gs[next].clamp(0.0, 1.0);
            next += 1;
            gsum += gk * mx;
            wsum += mx;
            for c in 0..3 {
                acc[c] += v[c] * gk;
            }
        } else {
            for c in 0..3 {
                rest[c] += v[c];
            }
        }
    }
    let gmean = if wsum > 0.0 { gsum / wsum } else { 1.0 };
    [
        acc[0] + rest[0] * gmean,
        acc[1] + rest[1] * gmean,
        acc[2] + rest[2] * gmean,
    ]
}

/// The size below which contributions are summed without their own visibility: the largest
/// power-of-two fraction of `peak` such that everything smaller adds up to at most
/// [`VISIBILITY_TAIL`] of the total.
fn tail_cut(contrib: &[(u32, [f64; 3])], peak: f64) -> f64 {
    const BUCKETS: usize = 64;
    if peak <= 0.0 {
        return 0.0;
    }
    // Bucket b holds contributions in (peak·2^{−b−1}, peak·2^{−b}].
    let mut sums = [0.0f64; BUCKETS];
    let mut total = 0.0;
    let inv = 1.0 / peak;
    for (_, v) in contrib {
        let mx = v[0].max(v[1]).max(v[2]);
        total += mx;
        let e = ((mx * inv).to_bits() >> 52) as i64 & 0x7ff;
        let b = (1022 - e).clamp(0, BUCKETS as i64 - 1) as usize;
        sums[b] += mx;
    }
    // Drop buckets from the smallest up while their sum stays within the tail.
    let budget = VISIBILITY_TAIL * total;
    let mut dropped = 0.0;
    let mut first_dropped = BUCKETS;
    for b in (1..BUCKETS).rev() {
        if dropped + sums[b] > budget {
            break;
        }
        dropped += sums[b];
        first_dropped = b;
    }
    if first_dropped >= BUCKETS {
        0.0
    } else {
        // Everything below peak·2^{−first_dropped} is in the tail.
        peak * 0.5f64.powi(first_dropped as i32)
    }
}

/// The light a delta sum of facets of BRDF `transfer` reflects after more than one bounce
/// inside the microgeometry, as a BRDF (RGB, 1/sr) to add to the single-bounce microfacet form.
/// With `solve`, a model that solves it from the geometry ([`VisibilityModel::interreflected`]:
/// a height map's facets, by radiosity for Lambert facets and path tracing for glossy ones)
/// answers; otherwise (or without `solve`, the interactive plans) Lambert facets' share is
/// estimated from a normal-conditioned visibility that knows each delta's sky view `s_k`
/// ([`VisibilityModel::sky_views`]), below. Zero for other facets or models that cannot say.
///
/// # Estimate from the sky views
/// The radiance the surface sends into its own concavities is taken as uniform: the mean
/// exitant radiance of the microsurface. Per unit irradiance of the light (weights `w_k`
/// summing to 1 over the microsurface, albedo `ρ`, `V_i(k)` the share of delta `k`'s facets
/// the light reaches, `V_o(k)` the share the viewer sees):
/// ```text
/// L₁ = ρ/π Σ w_k (m_k·i)⁺ V_i(k)                 first-bounce mean radiance
/// L  = L₁ / (1 − ρ (1 − s̄)),  s̄ = Σ w_k s_k      all further bounces (a geometric series)
/// Δf = Σ w_k (m_k·o)⁺ V_o(k) ρ (1 − s_k) L / (A cos θ_o cos θ_i)
/// ```
/// with `A = Σ w_k (m_k·z)⁺`: facet `k` receives `π (1 − s_k) L` from the surface it sees.
/// Measured against the ray-traced gonioreflectometer with 8 bounces in docs/heightmaps.md.
#[must_use]
pub fn deltas_interreflection(
    d: &crate::ndf::DeltaSum,
    transfer: &Transfer,
    g: &dyn VisibilityModel,
    i: DVec3,
    o: DVec3,
    solve: bool,
) -> [f64; 3] {
    if i.z <= 0.0 || o.z <= 0.0 {
        return [0.0; 3];
    }
    if let Some(f) = solve.then(|| g.interreflected(transfer, i, o)).flatten() {
        return f;
    }
    // The sky-view estimate assumes facets that scatter diffusely.
    let Transfer::Lambert { albedo } = *transfer else {
        return [0.0; 3];
    };
    let normals = d.normals();
    let Some(sky) = g.sky_views(normals) else {
        return [0.0; 3];
    };
    let s_mean: f64 = normals
        .iter()
        .zip(sky)
        .map(|(n, &s)| n.weight * f64::from(s))
        .sum();
    // V_i over the deltas facing the light, V_o over those facing the viewer.
    let facing = |w: DVec3| -> Vec<u32> {
        (0..normals.len() as u32)
            .filter(|&k| normals[k as usize].normal.dot(w) > 0.0)
            .collect()
    };
    let (ki, ko) = (facing(i), facing(o));
    let (mut vi, mut vo) = (vec![1.0; ki.len()], vec![1.0; ko.len()]);
    g.g_given_deltas(i, DVec3::Z, normals, &ki, &mut vi);
    g.g_given_deltas(DVec3::Z, o, normals, &ko, &mut vo);
    let lit: f64 = ki
        .iter()
        .zip(&vi)
        .map(|(&k, v)| {
            let n = normals[k as usize];
            n.weight * n.normal.dot(i) * v.clamp(0.0, 1.0)
        })
        .sum();
    let seen: f64 = ko
        .iter()
        .zip(&vo)
        .map(|(&k, v)| {
            let n = normals[k as usize];
            n.weight * n.normal.dot(o) * v.clamp(0.0, 1.0) * (1.0 - f64::from(sky[k as usize]))
        })
        .sum();
    let area = d.projected_area();
    albedo.map(|rho| {
        let l1 = rho / PI * lit;
        let l = l1 / (1.0 - rho * (1.0 - s_mean)).max(1e-6);
        seen * rho * l / (area * o.z * i.z)
    })
}

/// Smith masking computed numerically for an arbitrary NDF restricted to the upper hemisphere.
#[derive(Clone, Debug)]
pub struct SmithMasking<'a> {
    ndf: &'a Ndf,
    accuracy: Accuracy,
    /// `∫_{z>0} n(m)(m·z) dω` — the factor turning `n` into the microfacet `D`.
    pub projected_area: f64,
    /// Use the closed forms of Beckmann and GGX NDFs (false: quadrature for every NDF).
    closed_form: bool,
    /// The NDF is rotationally symmetric ([`Ndf::is_isotropic`]): projected areas by the 1-D
    /// rule of [`isotropic_projected_area`].
    isotropic: bool,
    /// A tabulated NDF's exact projected areas ([`crate::ndf::tabulated::ProjectedAreas`];
    /// `None` for other NDFs and for [`SmithMasking::numerical`]).
    tabulated: Option<crate::ndf::tabulated::ProjectedAreas<'a>>,
}

/// `∫_{z>0} n(m)(ω·m)⁺ dω_m` for an isotropic NDF `n` (a function of `θ_m` only) and `ω` with
/// `cos θ = u`, as a 1-D integral over `θ_m ∈ [0, π/2]` of `n(θ_m) sin θ_m` times the closed-form
/// azimuthal integral of the clamped cosine, `2π·(A acos(−A/B) + √(B² − A²))/π` with
/// `A = u cos θ_m`, `B = sin θ sin θ_m` (`2πA` where `A ≥ B`). Gauss–Legendre (12 nodes) on 48
/// intervals growing geometrically from `θ_m = 10⁻⁴` (so that lobes as sharp as η ≈ 10⁸ are
/// resolved), split at the kink `θ_m = π/2 − θ`; relative error < 1e-9 on Phong peaks with
/// η from 1 to 10⁶ (tested against the 2-D quadrature and closed forms).
#[must_use]
pub fn isotropic_projected_area(ndf: &Ndf, u: f64) -> f64 {
    axial_projected_area(|t| ndf.eval(DVec3::new(t.sin(), 0.0, t.cos())), u, false)
}

/// `∫ n(m)(ω·m)⁺ dω_m` for a density `n` symmetric about an axis, given as a function of the
/// angle `θ'` to the axis, and `ω` making cosine `u` with the axis: the rule of
/// [`isotropic_projected_area`] over `θ' ∈ [0, π/2]` (`full_sphere = false`: the upper
/// hemisphere about the axis) or over the whole sphere (`true`: 16 more uniform intervals on
/// `[π/2, π]`), split at both kinks `θ' = π/2 ∓ θ` of the clamped cosine.
#[must_use]
pub fn axial_projected_area(density: impl Fn(f64) -> f64, u: f64, full_sphere: bool) -> f64 {
    use std::f64::consts::FRAC_PI_2;
    const INTERVALS: usize = 48;
    const BACK: usize = 16;
    const FIRST: f64 = 1e-4;
    static GL: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    let (xs, ws) = GL.get_or_init(|| gauss_legendre(12));
    let u = u.clamp(-1.0, 1.0);
    let s = (1.0 - u * u).max(0.0).sqrt();
    let theta = u.acos();
    let kinks = [FRAC_PI_2 - theta, FRAC_PI_2 + theta];
    let ratio = (FRAC_PI_2 / FIRST).powf(1.0 / INTERVALS as f64);
    let ends = INTERVALS + 1 + if full_sphere { BACK } else { 0 };
    let mut sum = 0.0;
    let mut a = 0.0;
    for k in 0..ends {
        let b = if k < INTERVALS {
            FIRST * ratio.powi(k as i32)
        } else {
            FRAC_PI_2 * (1.0 + (k - INTERVALS) as f64 / BACK as f64)
        };
        // Split the interval at the kinks of the clamped cosine.
        let mut cuts = [b; 3];
        let mut nc = 0;
        for kk in kinks {
            if kk > a && kk < b {
                cuts[nc] = kk;
                nc += 1;
            }
        }
        cuts[nc] = b;
        for &c in &cuts[..=nc] {
            let (half, mid) = (0.5 * (c - a), 0.5 * (c + a));
            for (x, w) in xs.iter().zip(ws) {
                let t = mid + half * x;
                let (st, ct) = t.sin_cos();
                let n = density(t);
                let (aa, bb) = (u * ct, s * st.abs());
                let azimuthal = if aa >= bb {
                    2.0 * PI * aa
                } else if aa <= -bb {
                    0.0
                } else {
                    2.0 * (aa * (-aa / bb).acos() + (bb * bb - aa * aa).sqrt())
                };
                sum += w * half * n * st * azimuthal;
            }
            a = c;
        }
    }
    sum
}

impl<'a> SmithMasking<'a> {
    /// Prepare the masking function of `ndf`: closed forms for Beckmann and GGX NDFs and their
    /// mixtures (the common material's fast path), the exact cell-by-cell projected areas of a
    /// tabulated NDF ([`crate::ndf::tabulated::ProjectedAreas`]), quadrature for the others.
    #[must_use]
    pub fn new(ndf: &'a Ndf, accuracy: Accuracy) -> SmithMasking<'a> {
        Self::with(ndf, accuracy, true)
    }

    /// [`SmithMasking::new`] by quadrature for every NDF, Beckmann, GGX and tabulated NDFs
    /// included (the tests compare it with the closed forms and the exact tabulated areas).
    #[must_use]
    pub fn numerical(ndf: &'a Ndf, accuracy: Accuracy) -> SmithMasking<'a> {
        Self::with(ndf, accuracy, false)
    }

    fn with(ndf: &'a Ndf, accuracy: Accuracy, closed_form: bool) -> SmithMasking<'a> {
        let isotropic = ndf.is_isotropic();
        let tabulated = match ndf {
            Ndf::Tabulated(t) if closed_form => Some(t.projected_areas()),
            _ => None,
        };
        let z = match ndf {
            // Cell by cell, exactly.
            Ndf::Tabulated(_) if closed_form => tabulated.as_ref().map_or(0.0, |t| t.moment().z),
            Ndf::Deltas(d) => d.projected_area(),
            // `n = D/A` with `∫ D (m·z) dω = 1`: exactly `1/A`.
            Ndf::Microfacet(mf) if closed_form => 1.0 / mf.area_ratio(),
            // `P = Σ w_k / A_k` ([`crate::ndf::mixture`]).
            Ndf::Mixture(mx) if closed_form => mx.projected_area(),
            _ if isotropic => isotropic_projected_area(ndf, 1.0),
            _ => integrate(ndf, accuracy, None, |m| [m.z.max(0.0)])[0],
        };
        SmithMasking {
            ndf,
            accuracy,
            projected_area: z.max(1e-300),
            closed_form,
            isotropic,
            tabulated,
        }
    }

    /// `Λ(ω) = ∫_{z>0} D(m)(ω·m)⁺ dω_m / cos θ_ω − 1` (≥ 0 up to quadrature error); the closed
    /// form of Beckmann and GGX NDFs ([`crate::ndf::Microfacet::lambda`]) and of their mixtures
    /// ([`crate::ndf::Mixture::lambda`]), by quadrature otherwise.
    #[must_use]
    pub fn lambda(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        match (self.closed_form, self.ndf) {
            (true, Ndf::Microfacet(mf)) => return mf.lambda(w),
            (true, Ndf::Mixture(mx)) => return mx.lambda(w),
            _ => {}
        }
        (self.relative_projected_area(w) / w.z - 1.0).max(0.0)
    }

    /// The projected area of the microsurface towards `w` relative to its projected area
    /// towards the normal, `a(ω) = ∫_{z>0} n(m)(ω·m)⁺ dω_m / ∫_{z>0} n(m)(m·z) dω_m`
    /// (dimensionless; 1 at the normal for an NDF on the normal). Unlike `Λ = a/cos θ − 1` it is
    /// smooth up to and across the horizon, which makes it the quantity to tabulate. Exact for a
    /// tabulated NDF (but under [`SmithMasking::numerical`]), by quadrature for every other NDF
    /// (the closed forms give `Λ` directly).
    #[must_use]
    pub fn relative_projected_area(&self, w: DVec3) -> f64 {
        if self.isotropic {
            return isotropic_projected_area(self.ndf, w.z) / self.projected_area;
        }
        if let Some(t) = &self.tabulated {
            return t.area(w) / self.projected_area;
        }
        let [p] = integrate(self.ndf, self.accuracy, None, |m| {
            if m.z <= 0.0 {
                [0.0]
            } else {
                [w.dot(m).max(0.0)]
            }
        });
        p / self.projected_area
    }

    /// The mean facet normal over the upper hemisphere per unit projected area,
    /// `c = ∫_{z>0} n(m) m dω_m / ∫_{z>0} n(m)(m·z) dω_m` (so `c_z = 1`): the linear part of
    /// [`SmithMasking::relative_projected_area`], `a(ω) = ω·c` wherever no facet of the NDF faces
    /// away from `ω`. `+z` for isotropic NDFs; exact for tabulated ones (as the projected area).
    #[must_use]
    pub fn mean_normal(&self) -> DVec3 {
        if self.isotropic {
            return DVec3::Z;
        }
        if let Some(t) = &self.tabulated {
            let m = t.moment();
            return DVec3::new(m.x / self.projected_area, m.y / self.projected_area, 1.0);
        }
        let [x, y, _] = integrate(self.ndf, self.accuracy, None, |m| {
            if m.z <= 0.0 {
                [0.0; 3]
            } else {
                [m.x, m.y, m.z]
            }
        });
        DVec3::new(x / self.projected_area, y / self.projected_area, 1.0)
    }

    /// Smith `G₁(ω) = 1/(1 + Λ(ω))`.
    #[must_use]
    pub fn g1(&self, w: DVec3) -> f64 {
        1.0 / (1.0 + self.lambda(w))
    }
}

/// Rows (ln κ) of the clamped-cosine table.
const CC_NK: usize = 64;
/// Columns (c) of the clamped-cosine table.
const CC_NC: usize = 129;
/// ln κ of the first row: κ from e⁻⁴ …
const CC_LN_K0: f64 = -4.0;
/// … to e¹² (beyond: the vMF is a delta, E = max(0, c)).
const CC_LN_K1: f64 = 12.0;

/// The table of `E[max(0, m·i)]` over (ln κ, c) (`CC_NK × CC_NC`, row-major), filled once by
/// 1-D quadrature (the azimuthal average of the clamped cosine is closed).
fn clamped_cosine_table() -> &'static [f64] {
    const NK: usize = CC_NK;
    const NC: usize = CC_NC;
    const LN_K0: f64 = CC_LN_K0;
    const LN_K1: f64 = CC_LN_K1;
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let (xs, ws) = gauss_legendre(96);
        let mut t = Vec::with_capacity(NK * NC);
        for a in 0..NK {
            let kappa = (LN_K0 + (LN_K1 - LN_K0) * a as f64 / (NK - 1) as f64).exp();
            for b in 0..NC {
                let c = -1.0 + 2.0 * b as f64 / (NC - 1) as f64;
                let sn = (1.0 - c * c).max(0.0).sqrt();
                // w = cos α about the mean, density κ e^{κ(w−1)} / (1 − e^{−2κ}) on [−1, 1],
                // sampled through its inverse CDF so the nodes follow the mass.
                let mut e = 0.0;
                for (x, wt) in xs.iter().zip(&ws) {
                    let u = 0.5 * (x + 1.0);
                    let w = crate::sg::sample_cos(kappa, u);
                    let sw = (1.0 - w * w).max(0.0).sqrt();
                    // m·i = w c + sw sn cos ψ; average of max(0, A + B cos ψ) over ψ.
                    let (a0, b0) = (w * c, sw * sn);
                    let avg = if a0 >= b0 {
                        a0
                    } else if a0 <= -b0 {
                        0.0
                    } else {
                        (a0 * (-a0 / b0).acos() + (b0 * b0 - a0 * a0).sqrt()) / PI
                    };
                    e += 0.5 * wt * avg;
                }
                t.push(e);
            }
        }
        t
    })
}

/// `E[max(0, m·i)]` for `m` drawn from a vMF of concentration κ whose mean direction makes cosine
/// `c` with `i`: the table of [`clamped_cosine_table`] interpolated bilinearly (error < 1e-3).
fn clamped_cosine_mean(kappa: f64, c: f64) -> f64 {
    clamped_cosine_mean_grad(kappa, c).0
}

/// `E[max(0, m·i)]` for `m ~ vMF(κ)` whose mean makes cosine `c` with `i` (the bilinear
/// interpolant of the table behind [`phong_closed_form`]), with `∂E/∂κ` and `∂E/∂c` (the
/// derivatives of the interpolant; zero across a clamped edge). For analytic Jacobians of fits
/// to the closed form.
#[inline]
#[must_use]
pub fn clamped_cosine_mean_grad(kappa: f64, c: f64) -> (f64, f64, f64) {
    const NK: usize = CC_NK;
    const NC: usize = CC_NC;
    let t = clamped_cosine_table();
    let cc = c.clamp(-1.0, 1.0);
    let lk = kappa.max(1e-12).ln();
    if lk >= CC_LN_K1 {
        return (cc.max(0.0), 0.0, if c > 0.0 && c < 1.0 { 1.0 } else { 0.0 });
    }
    let sa = (NK - 1) as f64 / (CC_LN_K1 - CC_LN_K0);
    let sb = 0.5 * (NC - 1) as f64;
    let fa_raw = (lk - CC_LN_K0) * sa;
    let fa = fa_raw.clamp(0.0, (NK - 1) as f64);
    let fb = (cc + 1.0) * sb;
    let (a0, b0) = ((fa as usize).min(NK - 2), (fb as usize).min(NC - 2));
    let (ta, tb) = (fa - a0 as f64, fb - b0 as f64);
    let v00 = t[a0 * NC + b0];
    let v01 = t[a0 * NC + b0 + 1];
    let v10 = t[(a0 + 1) * NC + b0];
    let v11 = t[(a0 + 1) * NC + b0 + 1];
    let lo = v00 * (1.0 - tb) + v01 * tb;
    let hi = v10 * (1.0 - tb) + v11 * tb;
    let e = lo * (1.0 - ta) + hi * ta;
    let de_dk = if fa_raw > 0.0 && fa_raw < (NK - 1) as f64 {
        (hi - lo) * sa / kappa
    } else {
        0.0
    };
    let de_dc = if c > -1.0 && c < 1.0 {
        ((v01 - v00) * (1.0 - ta) + (v11 - v10) * ta) * sb
    } else {
        0.0
    };
    (e, de_dk, de_dc)
}

/// Closed-form approximation of Phong peaks convolved with a Phong (N·H) transfer in the
/// multiple-surface form, via the von Mises–Fisher correspondence (module docs). `lobes` weights
/// must sum to 1; `exponent` and `specular` are the transfer's. Returns RGB in 1/sr.
#[must_use]
pub fn phong_closed_form(
    lobes: &[PhongLobe],
    exponent: f64,
    specular: [f64; 3],
    i: DVec3,
    o: DVec3,
) -> [f64; 3] {
    if i.z <= 0.0 || o.z <= 0.0 {
        return [0.0; 3];
    }
    let Some(h) = half_vector(i, o) else {
        return [0.0; 3];
    };
    // The transfer (m·H)^η ≈ e^{κ₂(m·H − 1)}, κ₂ = η + 1 (same integral over the hemisphere:
    // [`crate::sg::kappa_transfer`]).
    let k2 = crate::sg::kappa_transfer(exponent);
    let mut s = 0.0;
    for l in lobes {
        // The NDF lobe as a normalised vMF with the same integral as the Phong peak: κ₁ = (η+2)/4
        // ([`crate::sg::kappa_same_integral`]).
        let k1 = crate::sg::kappa_same_integral(l.exponent);
        let p = crate::sg::product(l.axis, k1, h, k2);
        // ∫ vMF(μ, κ₁)(m) e^{κ₂(H·m−1)} max(0, m·i) dω
        //   = C(κ₁) e^{κ₃−κ₁−κ₂} · 2π(1−e^{−2κ₃})/κ₃ · E_{vMF(μ₃,κ₃)}[max(0, m·i)]
        let mass = p.ln_scale.exp() * crate::sg::integral(p.kappa);
        let mu3 = if p.kappa < 1e-9 {
            DVec3::Z
        } else {
            p.v / p.kappa
        };
        let c1 = crate::sg::normaliser(k1);
        s += l.weight * c1 * mass * clamped_cosine_mean(p.kappa, mu3.dot(i));
    }
    let c = s / i.z;
    [specular[0] * c, specular[1] * c, specular[2] * c]
}
