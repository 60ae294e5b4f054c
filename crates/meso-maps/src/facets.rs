//! Meso-normals of a height map, with their microsurface-area weights (Eq. 1).
//!
//! # The surface
//! The height map is the piecewise-linear surface a renderer would displace: every grid cell
//! (corners `(i, j)`, `(i, j+1)`, `(i+1, j)`, `(i+1, j+1)`) is split along the diagonal from
//! `(i, j)` to `(i+1, j+1)`, i.e. from `(x, y)` to `(x+S, y+S)`, into
//! * triangle **A** = `(i,j), (i,j+1), (i+1,j+1)` (the half with `y − y_i < x − x_j`), slopes
//!   `∂h/∂x = (h₀₁ − h₀₀)/S`, `∂h/∂y = (h₁₁ − h₀₁)/S`;
//! * triangle **B** = `(i,j), (i+1,j+1), (i+1,j)`, slopes `∂h/∂x = (h₁₁ − h₁₀)/S`,
//!   `∂h/∂y = (h₁₀ − h₀₀)/S`.
//!
//! Each facet's unit normal is `(−∂h/∂x, −∂h/∂y, 1)/‖·‖`. Its weight is its **true area** in
//! units of one cell's projected area, `½ / n_z` for a triangle (its projected area is `S²/2`):
//! normalised, these weights are the paper's Eq. 1 density `n(m)` — normals per unit of
//! *microsurface* area, `∫ n dω = 1` — the convention of `meso_core::ndf`. The microfacet form
//! turns it into `D = n / ∫_{z>0} n (m·z) dω`, so the projected (macro-area) share of a facet is
//! `D(m)(m·z)` (`meso_core::convolution`).
//!
//! [`NormalMode::CentralDifferences`] instead gives one normal per cell, from the gradient of
//! the bilinear patch at the cell centre, `∂h/∂x = ((h₀₁ − h₀₀) + (h₁₁ − h₁₀))/(2S)` (and
//! likewise for y), with area weight `1/n_z`: smooth data agree with the triangles, creases do not.

use crate::heightmap::{HeightMap, NormalMap};
use glam::DVec3;

/// How meso-normals are derived from heights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NormalMode {
    /// Two flat triangles per grid cell (the default; exact for the displaced surface).
    #[default]
    Triangles,
    /// One normal per cell from central differences at the cell centre.
    CentralDifferences,
}

/// Per-cell meso-normals: `per_cell` normals for each of `cols × rows` cells, with their true
/// (microsurface) areas as weights, in units of one cell's projected area (a cell's projected
/// shares `weight · n_z` sum to 1).
#[derive(Clone, Debug, PartialEq)]
pub struct FacetNormals {
    /// Cells along x.
    pub cols: usize,
    /// Cells along y.
    pub rows: usize,
    /// Normals per cell (2 for triangles, 1 otherwise).
    pub per_cell: usize,
    /// Unit normals; cell `(r, c)` owns `normals[(r·cols + c)·per_cell ..][..per_cell]`.
    pub normals: Vec<DVec3>,
    /// Microsurface area of each facet (cell units: projected share / `n_z`).
    pub weights: Vec<f64>,
}

#[inline]
fn normal_from_slopes(gx: f64, gy: f64) -> DVec3 {
    DVec3::new(-gx, -gy, 1.0).normalize()
}

/// The facets of cell `(row, col)` of a height map, as [`FacetNormals::from_heightmap`] stores
/// them: `(unit normal, area weight)` pairs, the first `n` of the array (2 for triangles, 1 for
/// central differences). The extraction computes its facets here on the fly instead of storing
/// them all (32 bytes per facet).
#[inline]
#[must_use]
pub(crate) fn cell_facets(
    map: &HeightMap,
    mode: NormalMode,
    row: usize,
    col: usize,
) -> ([(DVec3, f64); 2], usize) {
    let s = map.texel_size();
    let (i, j) = (row as isize, col as isize);
    let h00 = map.at(i, j);
    let h01 = map.at(i, j + 1);
    let h10 = map.at(i + 1, j);
    let h11 = map.at(i + 1, j + 1);
    match mode {
        NormalMode::Triangles => {
            let a = normal_from_slopes((h01 - h00) / s, (h11 - h01) / s);
            let b = normal_from_slopes((h11 - h10) / s, (h10 - h00) / s);
            ([(a, 0.5 / a.z), (b, 0.5 / b.z)], 2)
        }
        NormalMode::CentralDifferences => {
            let gx = ((h01 - h00) + (h11 - h10)) / (2.0 * s);
            let gy = ((h10 - h00) + (h11 - h01)) / (2.0 * s);
            let n = normal_from_slopes(gx, gy);
            ([(n, 1.0 / n.z), (n, 0.0)], 1)
        }
    }
}

impl FacetNormals {
    /// The meso-normals of a height map.
    #[must_use]
    pub fn from_heightmap(map: &HeightMap, mode: NormalMode) -> FacetNormals {
        match Self::try_from_heightmap(map, mode) {
            Ok(f) => f,
            Err(e) => std::alloc::handle_alloc_error(
                std::alloc::Layout::from_size_align(e.bytes as usize, 8)
                    .unwrap_or(std::alloc::Layout::new::<DVec3>()),
            ),
        }
    }

    /// [`FacetNormals::from_heightmap`], with an error instead of an abort when the memory for
    /// the normals (32 bytes per facet) is not there.
    ///
    /// # Errors
    /// The failed allocation.
    pub fn try_from_heightmap(
        map: &HeightMap,
        mode: NormalMode,
    ) -> Result<FacetNormals, meso_core::budget::AllocError> {
        let (cols, rows) = (map.cells_x(), map.cells_y());
        let per_cell = match mode {
            NormalMode::Triangles => 2,
            NormalMode::CentralDifferences => 1,
        };
        let mut normals = meso_core::budget::try_with_capacity(cols * rows * per_cell)?;
        let mut weights = meso_core::budget::try_with_capacity(cols * rows * per_cell)?;
        for i in 0..rows {
            for j in 0..cols {
                let (facets, n) = cell_facets(map, mode, i, j);
                for (normal, w) in &facets[..n] {
                    normals.push(*normal);
                    weights.push(*w);
                }
            }
        }
        Ok(FacetNormals {
            cols,
            rows,
            per_cell,
            normals,
            weights,
        })
    }

    /// The normals of a tangent-space normal map: one per texel, standing for one texel of
    /// projected area, hence the area weight `1/n_z` (normal maps have `n_z > 0`).
    #[must_use]
    pub fn from_normal_map(map: &NormalMap) -> FacetNormals {
        FacetNormals {
            cols: map.width(),
            rows: map.height(),
            per_cell: 1,
            normals: map.normals().to_vec(),
            weights: map.normals().iter().map(|n| 1.0 / n.z).collect(),
        }
    }

    /// Iterate over `(normal, weight)` of the cells in rows `r0..r1`, columns `c0..c1`.
    pub fn footprint(
        &self,
        r0: usize,
        r1: usize,
        c0: usize,
        c1: usize,
    ) -> impl Iterator<Item = (DVec3, f64)> + '_ {
        (r0..r1).flat_map(move |r| {
            let a = (r * self.cols + c0) * self.per_cell;
            let b = (r * self.cols + c1) * self.per_cell;
            self.normals[a..b]
                .iter()
                .copied()
                .zip(self.weights[a..b].iter().copied())
        })
    }

    /// All `(normal, area weight)` pairs with weights normalised to sum to 1: the Eq. 1 density
    /// of the whole map as a sum of deltas.
    #[must_use]
    pub fn normalized(&self) -> Vec<(DVec3, f64)> {
        let total: f64 = self.weights.iter().sum();
        self.normals
            .iter()
            .zip(&self.weights)
            .map(|(n, w)| (*n, w / total))
            .collect()
    }

    /// Every facet as a delta of the core's delta-sum NDF (`Ndf::Deltas`, Eq. 3, weights the
    /// normalised true areas): the exact Eq. 1 density of the whole map, unmerged (for the
    /// binned form with per-bin visibility see `crate::facet_ndf::facets_with_visibility`).
    ///
    /// # Errors
    /// No facet with a positive weight.
    pub fn to_deltas(&self) -> Result<meso_core::ndf::Ndf, meso_core::NdfError> {
        let normals = self
            .normals
            .iter()
            .zip(&self.weights)
            .map(|(n, w)| meso_core::ndf::WeightedNormal {
                normal: *n,
                weight: *w,
            })
            .collect();
        Ok(meso_core::ndf::Ndf::Deltas(meso_core::ndf::DeltaSum::new(
            normals,
        )?))
    }
}

/// The facets of a height map or a normal map, computed cell by cell when asked for, in the
/// order and with the values [`FacetNormals`] would store: what the extraction reads instead of
/// a stored copy of every facet (32 bytes each, 67 MB for a 1024² height map).
#[derive(Clone, Copy, Debug)]
pub(crate) enum FacetSource<'a> {
    /// A height map's triangles or central differences.
    Heights(&'a HeightMap, NormalMode),
    /// A normal map's texels (area weight `1/n_z`).
    Normals(&'a NormalMap),
}

impl FacetSource<'_> {
    /// Cells along x.
    pub(crate) fn cols(&self) -> usize {
        match self {
            FacetSource::Heights(m, _) => m.cells_x(),
            FacetSource::Normals(n) => n.width(),
        }
    }
    /// Cells along y.
    pub(crate) fn rows(&self) -> usize {
        match self {
            FacetSource::Heights(m, _) => m.cells_y(),
            FacetSource::Normals(n) => n.height(),
        }
    }
    /// The facets of cell `(row, col)`: the first `n` pairs of the array.
    #[inline]
    pub(crate) fn cell(&self, row: usize, col: usize) -> ([(DVec3, f64); 2], usize) {
        match self {
            FacetSource::Heights(m, mode) => cell_facets(m, *mode, row, col),
            FacetSource::Normals(nm) => {
                let n = nm.normals()[row * nm.width() + col];
                ([(n, 1.0 / n.z), (n, 0.0)], 1)
            }
        }
    }
}
