//! The facets of a height map as an NDF (`represent = "facets"`): every facet normal, merged per
//! ≈ 0.8° bin, as a delta sum, with each bin's own visibility from the heights
//! ([`crate::visibility::BinnedVisibility`]) — built by [`facets_with_visibility`], stored by
//! [`crate::facet_cache`], loaded into materials by [`crate::resolver`].

use crate::facets::NormalMode;
use crate::fit::{merge_entries, Entry};
use crate::gonio::GonioParams;
use crate::heightmap::HeightMap;
use crate::horizon::HorizonStats;
use crate::radiosity::LazyRadiosity;
use crate::visibility::BinnedVisibility;
use glam::DVec3;
use meso_core::material::VisibilityModel;
use meso_core::ndf::{DeltaSum, Ndf, WeightedNormal};
use meso_core::transfer::Transfer;
use std::sync::Arc;

/// The visibility of a `represent = "facets"` NDF: [`BinnedVisibility`] (each normal bin's
/// facets, lit and seen jointly, from the heights) as the normal-conditioned model, and the
/// map's horizon statistics for `shadowing = "horizon"`.
#[derive(Clone, Debug)]
pub struct FacetVisibility {
    /// Per-bin facet horizons.
    pub bins: Arc<BinnedVisibility>,
    /// The whole map's horizon statistics.
    pub horizon: HorizonStats,
    /// The light between the map's facets (Lambert facets by radiosity, glossy ones, and
    /// Lambert ones on maps over the radiosity's size, by path tracing:
    /// [`traced_interreflection`]), built on first use; `None` where the map cannot be
    /// traced again (then Lambert facets get the sky-view estimate of
    /// `meso_core::convolution::deltas_interreflection`, glossy ones the single bounce).
    pub radiosity: Option<Arc<LazyRadiosity>>,
}

impl VisibilityModel for FacetVisibility {
    fn g(&self, i: DVec3, o: DVec3) -> f64 {
        self.horizon.visibility(i) * self.horizon.visibility(o)
    }
    fn g_given_normal(&self, i: DVec3, o: DVec3, m: DVec3) -> f64 {
        self.bins.given_normal(i, o, m)
    }
    fn g_given_deltas(
        &self,
        i: DVec3,
        o: DVec3,
        normals: &[WeightedNormal],
        ks: &[u32],
        out: &mut [f64],
    ) {
        // Built for this very delta sum (bin k = delta k): answer by index.
        if normals.len() == self.bins.bins() {
            self.bins.joint_many(i, o, ks, out);
        } else {
            meso_core::visibility::g_given_each_normal(self, i, o, normals, ks, out);
        }
    }
    fn sky_views(&self, normals: &[WeightedNormal]) -> Option<&[f32]> {
        // Built for this very delta sum (bin k = delta k).
        (normals.len() == self.bins.bins()).then(|| self.bins.sky_views())
    }
    fn interreflected(&self, transfer: &Transfer, i: DVec3, o: DVec3) -> Option<[f64; 3]> {
        let lazy = self.radiosity.as_ref()?;
        match transfer {
            Transfer::Mirror { .. } => return None,
            // The radiosity is built (or tried) for Lambert facets only.
            Transfer::Lambert { albedo } => {
                if let Ok(r) = lazy.get() {
                    return Some(r.multi_bounce(*albedo, i, o, None));
                }
            }
            _ => {}
        }
        // Glossy facets, and Lambert facets on a map over the radiosity's size.
        Some(
            lazy.tracer()
                .ok()?
                .measure(transfer, i, o, &traced_interreflection()),
        )
    }
    fn interreflection_solved(&self, transfer: &Transfer) -> Result<(), String> {
        match (&self.radiosity, transfer) {
            (_, Transfer::Mirror { .. }) => {
                Err("the light between perfect mirror facets cannot be traced".into())
            }
            (Some(r), Transfer::Lambert { .. }) if r.get().is_ok() => Ok(()),
            (Some(r), _) => r.tracer().map(|_| ()).map_err(str::to_owned),
            (None, _) => Err("light between facets is traced only on a wrapped height map with `normals = \"triangles\"`"
                .into()),
        }
    }
    fn conditions_on_normal(&self) -> bool {
        true
    }
}

/// Rays per side of the path tracing that gives the light between facets where no radiosity
/// holds it (glossy facets; Lambert facets on maps over [`crate::radiosity::MAX_PATCHES`]):
/// `256²` paths per direction pair. Measured on half-cylinders and their grooves with Beckmann
/// α = 0.1 and 0.05 facets: the relative RMSE between seeds of the part beyond the single bounce
/// is 4–16 % with 128², 2–6 % with 256² (≈ 17 ms a pair) and 2–3 % with 512² (≈ 68 ms a pair;
/// docs/heightmaps.md, "Light between glossy facets").
pub const TRACED_RAYS_PER_SIDE: usize = 256;
/// Scattering events followed per traced path (`0.8³² ≈ 0.08 %` of the light of Lambert facets
/// of albedo 0.8 is left after as many; glossy paths rarely survive them; the
/// gonioreflectometer's check follows 8).
pub const TRACED_BOUNCES: usize = 32;

/// How the light between facets is path traced where no radiosity holds it
/// (`interreflection = true` with Phong or microfacet facets, or Lambert facets on a map of
/// more than [`crate::radiosity::MAX_PATCHES`] patches): the gonioreflectometer's paths on the
/// map's own triangles ([`crate::Gonio::measure`]), counting only the light that has scattered
/// at least once before ([`GonioParams::first_bounce`] = 2), since the facets' own single
/// bounce comes from the NDF and its visibility; [`TRACED_RAYS_PER_SIDE`]² paths of at most
/// [`TRACED_BOUNCES`] events, a fixed seed (the same paths for every direction pair, so the
/// result is smooth in the directions and repeatable).
#[must_use]
pub fn traced_interreflection() -> GonioParams {
    GonioParams {
        rays_per_side: TRACED_RAYS_PER_SIDE,
        shadowing: true,
        seed: 0x6c6f_7373_7921,
        bounces: TRACED_BOUNCES,
        first_bounce: 2,
    }
}

/// The estimated peak memory (bytes) of [`facets_with_visibility`] on a map of `cols × rows`
/// cells with `per_cell` facets each and `samples` height samples: the facets and their bin
/// entries, each facet's horizons at [`crate::visibility::AZIMUTHS`] azimuths (per sample point)
/// and their binned copy, and the horizon map.
#[must_use]
pub fn facets_bytes(cols: usize, rows: usize, per_cell: usize, samples: usize) -> u64 {
    let facets = (cols as u64)
        .saturating_mul(rows as u64)
        .saturating_mul(per_cell as u64);
    let points = crate::visibility::points_per_facet(facets as usize) as u64;
    let horizons = 4 * crate::visibility::AZIMUTHS as u64;
    facets
        .saturating_mul(32 + 40 + 8 + horizons * points + horizons + 8)
        .saturating_add((samples as u64).saturating_mul(48))
}

/// The facets of a height map as a delta-sum NDF (merged per ≈ 0.8° bin of the fit's entry
/// grid, each bin's area-weighted mean normal) with each bin's visibility
/// ([`crate::visibility`]).
///
/// # Errors
/// A degenerate map (no facet with positive weight).
pub fn facets_with_visibility(
    map: &HeightMap,
    mode: NormalMode,
) -> Result<(Ndf, FacetVisibility), String> {
    facets_with_visibility_progress(map, mode, &|_, _| {})
}

/// [`facets_with_visibility`], reporting the horizon march's progress (`rows_done(done,
/// total)` in chunks of facets, from worker threads; see
/// [`crate::visibility::facet_horizons_of`]).
///
/// # Errors
/// A degenerate map (no facet with positive weight).
pub fn facets_with_visibility_progress(
    map: &HeightMap,
    mode: NormalMode,
    rows_done: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Ndf, FacetVisibility), String> {
    let facets = crate::facets::FacetNormals::from_heightmap(map, mode);
    let entries: Vec<Entry> = facets
        .normals
        .iter()
        .zip(&facets.weights)
        .map(|(n, w)| Entry::new(*n, *w))
        .collect();
    let mut merged = Vec::new();
    merge_entries(&[&entries], &mut merged);
    merged.retain(|e| e.w > 0.0);
    let normals: Vec<WeightedNormal> = merged
        .iter()
        .map(|e| WeightedNormal {
            normal: e.m.normalize(),
            weight: e.w,
        })
        .collect();
    let deltas = DeltaSum::new(normals).map_err(|e| e.to_string())?;
    let bins: Vec<u32> = entries
        .iter()
        .map(|e| merged.binary_search_by_key(&e.bin, |m| m.bin).unwrap_or(0) as u32)
        .collect();
    // Horizons of at most MAX_FACETS_PER_BIN facets per bin, each standing for its share.
    let (chosen, factor) = crate::visibility::facets_to_march(&bins, merged.len());
    const CHUNK: usize = 256;
    rows_done(0, chosen.len().div_ceil(CHUNK).max(1));
    let horizons = crate::visibility::facet_horizons_of(map, mode, &chosen, rows_done);
    if chosen.is_empty() {
        rows_done(1, 1);
    }
    let weights: Vec<f64> = chosen
        .iter()
        .zip(&factor)
        .map(|(&f, s)| facets.weights[f as usize] * s)
        .collect();
    let chosen_bins: Vec<u32> = chosen.iter().map(|&f| bins[f as usize]).collect();
    drop(bins);
    let exact: Vec<DVec3> = deltas.normals().iter().map(|n| n.normal).collect();
    let bins = BinnedVisibility::new(&weights, &horizons, &chosen_bins, &exact);
    drop(horizons);
    let horizon = crate::horizon::HorizonMap::compute(map).total_stats();
    Ok((
        Ndf::Deltas(deltas),
        FacetVisibility {
            bins: Arc::new(bins),
            horizon,
            radiosity: None,
        },
    ))
}
