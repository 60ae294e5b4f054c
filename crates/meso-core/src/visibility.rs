//! Masking–shadowing models supplied from outside the core (a height map's own geometry):
//! the one trait the convolution ([`crate::convolution::Visibility::GivenNormal`]), the
//! materials ([`crate::material::ShadowingKind`]) and the fast evaluators
//! ([`crate::shading::FastBrdf`]) read.
//!
//! # Conventions
//! Directions are unit vectors in the local frame (normal +z), pointing away from the surface:
//! `i` towards the light, `o` towards the viewer. Every value is a probability in `[0, 1]`.
//!
//! * [`VisibilityModel::g`] — `G(i, o)`: the fraction of the microsurface both lit from `i` and
//!   seen from `o` (not conditioned on the facet normal; e.g. filtered horizon angles).
//! * [`VisibilityModel::g_given_normal`] — `G(i, o | m)`: the same fraction among the facets of
//!   normal `m`. This is what tells bumps from grooves: positive and negative half-cylinders
//!   share an NDF, but only the facets in the creases are hidden.
//! * [`VisibilityModel::g_given_deltas`] — `G(i, o | m_k)` for many deltas `k` of a delta-sum
//!   NDF at once, addressed by their index: what the convolution of a height map's facets calls
//!   once per direction pair, so that a model can do its per-pair work (the directions'
//!   azimuth and elevation) once, not once per delta.

use crate::ndf::WeightedNormal;
use crate::transfer::Transfer;
use glam::DVec3;

/// A masking–shadowing model supplied by a resolver (e.g. from a height map): probabilities in
/// `[0, 1]` for unit directions in the local frame (module docs).
pub trait VisibilityModel: Send + Sync + std::fmt::Debug {
    /// `G(i, o)`: the fraction of facets both lit from `i` and seen from `o`.
    fn g(&self, i: DVec3, o: DVec3) -> f64;

    /// `G(i, o | m)`: the fraction of the facets of normal `m` both lit from `i` and seen from
    /// `o`; models that do not know which normals are hidden return [`VisibilityModel::g`].
    fn g_given_normal(&self, i: DVec3, o: DVec3, m: DVec3) -> f64 {
        let _ = m;
        self.g(i, o)
    }

    /// `G(i, o | m_k)` for the deltas `ks` (indices into `normals`, the delta-sum NDF's normals
    /// in order) written to `out[..ks.len()]`. The default asks
    /// [`VisibilityModel::g_given_normal`] for each; a model built for that very NDF answers by
    /// index with its per-pair work done once.
    fn g_given_deltas(
        &self,
        i: DVec3,
        o: DVec3,
        normals: &[WeightedNormal],
        ks: &[u32],
        out: &mut [f64],
    ) {
        g_given_each_normal(self, i, o, normals, ks, out);
    }

    /// The cosine-weighted share of each delta's facet hemisphere that sees the sky (not the
    /// surface itself), `s_k = (1/π) ∫_{sky} (ω·m_k)⁺ dω`, indexed like the delta sum's
    /// `normals`: what the inter-reflection estimate needs
    /// ([`crate::convolution::deltas_interreflection`]). `None` for models that do not know it.
    fn sky_views(&self, normals: &[WeightedNormal]) -> Option<&[f32]> {
        let _ = normals;
        None
    }

    /// The BRDF (1/sr, RGB) of the light that scatters more than once between facets of BRDF
    /// `transfer` inside the microgeometry, for light `i` and view `o`, when the model can solve
    /// it from the geometry itself (e.g. a height map's facets: `meso_maps::FacetRadiosity` for
    /// Lambert facets, path tracing on the map's triangles for glossy ones); what
    /// [`crate::convolution::deltas_interreflection`] adds to the single bounce. `None` (the
    /// default) for models that cannot: the convolution then estimates it from the deltas' sky
    /// views (Lambert facets) or leaves it out (other facets).
    fn interreflected(&self, transfer: &Transfer, i: DVec3, o: DVec3) -> Option<[f64; 3]> {
        let _ = (transfer, i, o);
        None
    }

    /// Whether [`VisibilityModel::interreflected`] solves the light between facets of BRDF
    /// `transfer` from the geometry (`Ok`), or why not (`Err`, a sentence): then the
    /// inter-reflection of `interreflection = true` is the sky-view estimate for Lambert facets
    /// ([`crate::convolution::deltas_interreflection`]) and left out for others, which a
    /// command reports to its user. May build what `interreflected` needs (it would be built at
    /// the first evaluation anyway).
    ///
    /// # Errors
    /// The reason the geometry's own solution is not available (the default: this model has
    /// none).
    fn interreflection_solved(&self, transfer: &Transfer) -> Result<(), String> {
        let _ = transfer;
        Err("this visibility model cannot trace the light between facets".into())
    }

    /// Whether [`VisibilityModel::g_given_normal`] depends on the normal (then
    /// [`crate::material::ShadowingKind::Visibility`] is available and the default).
    fn conditions_on_normal(&self) -> bool {
        false
    }
}

/// [`VisibilityModel::g_given_deltas`] answered normal by normal through
/// [`VisibilityModel::g_given_normal`] (the trait's default; for models whose fast path does not
/// apply to the NDF at hand).
pub fn g_given_each_normal<M: VisibilityModel + ?Sized>(
    model: &M,
    i: DVec3,
    o: DVec3,
    normals: &[WeightedNormal],
    ks: &[u32],
    out: &mut [f64],
) {
    for (v, &k) in out.iter_mut().zip(ks) {
        *v = model.g_given_normal(i, o, normals[k as usize].normal);
    }
}
