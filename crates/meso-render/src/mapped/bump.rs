//! [`BumpMapped`]: the bump-mapped ground truth, shaded texel by texel from the heights.

use super::*;
use meso_core::frame::half_vector;

/// A bump-mapped material shaded texel by texel from a height map (see the module docs):
/// the ground truth that [`NdfMapped`] filters.
#[derive(Clone, Debug)]
pub struct BumpMapped {
    cols: usize,
    rows: usize,
    /// Two facet normals per cell (triangles A and B), row-major.
    normals: Vec<[DVec3; 2]>,
    /// How a point finds whether it sees a direction, when shadowing is on.
    shadows: Option<Shadows>,
    facet: Facet,
    diffuse: [f32; 3],
    texels_per_uv: f64,
    /// Weight each sample by its facet's area seen from the viewer
    /// ([`BumpMapped::with_view_weighting`]).
    view_weighting: bool,
}

/// How a bump-mapped point finds whether it sees a direction (the light's, and with view
/// weighting the viewer's).
#[derive(Clone, Debug)]
enum Shadows {
    /// A ray traced from the point on the displaced surface (the tiled mesh of the heights,
    /// [`Gonio::sees`]): exact, for wrapped maps.
    Rays(Arc<Gonio>),
    /// The horizon angles of the nearest height sample along ±x and ±y, interpolated in
    /// azimuth ([`meso_maps::HorizonStats::visibility`]): clamped maps, and
    /// [`BumpMapped::new_horizon_shadowed`].
    Horizon(HorizonMap),
}

impl BumpMapped {
    /// A bump map of `map` with the facet transfer function and diffuse term of `surface` (its
    /// NDF is ignored), `texels_per_uv` height-map cells per unit of texture coordinate, and
    /// shadowing of the light when `shadowing` is true: a ray traced from the point on the
    /// displaced surface (the tiled mesh of the heights, as `meso gonio` traces it), or for a
    /// clamped map the horizon of the nearest height sample; with shadowing, weighted by view
    /// ([`BumpMapped::with_view_weighting`]), the viewer seen or hidden the same way.
    ///
    /// # Errors
    /// A message when `texels_per_uv` is not a finite positive number.
    pub fn new(
        map: &HeightMap,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<BumpMapped, String> {
        check_scale(texels_per_uv)?;
        let f = FacetNormals::from_heightmap(map, NormalMode::Triangles);
        let normals = f.normals.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
        Ok(BumpMapped {
            cols: f.cols,
            rows: f.rows,
            normals,
            shadows: shadowing.then(|| match Gonio::new(map) {
                Ok(g) => Shadows::Rays(Arc::new(g)),
                Err(_) => Shadows::Horizon(HorizonMap::compute(map)),
            }),
            facet: Facet::new(&surface.transfer),
            diffuse: surface.diffuse.map(|a| (a * FRAC_1_PI) as f32),
            texels_per_uv,
            view_weighting: shadowing,
        })
    }

    /// The most memory (bytes) a bump map of `cols × rows` cells holds: two facet normals a
    /// cell and, with `shadowing`, the shadow rays' tracer (16 bytes a height sample,
    /// [`Gonio::bytes`]; the horizons of a clamped map take half that).
    #[must_use]
    pub fn bytes(cols: usize, rows: usize, shadowing: bool) -> u64 {
        let cells = (cols as u64).saturating_mul(rows as u64);
        let normals = cells.saturating_mul(std::mem::size_of::<[DVec3; 2]>() as u64);
        let tracer = if shadowing {
            Gonio::bytes(cols + 1, rows + 1)
        } else {
            0
        };
        normals.saturating_add(tracer)
    }

    /// [`BumpMapped::new`] with shadowing by the horizon of the nearest height sample along ±x
    /// and ±y instead of rays, for every map: the model of the renderer before 2026-12-06 and
    /// of the pyramid's statistics (`meso_maps::HorizonMap`), kept to compare with. On steep
    /// maps, lights and views off those four azimuths see it 25–45 % too dark
    /// (docs/heightmaps.md, "Shadows of the bump map").
    ///
    /// # Errors
    /// As [`BumpMapped::new`].
    pub fn new_horizon_shadowed(
        map: &HeightMap,
        surface: &Material,
        texels_per_uv: f64,
    ) -> Result<BumpMapped, String> {
        let mut b = BumpMapped::new(map, surface, texels_per_uv, false)?;
        b.shadows = Some(Shadows::Horizon(HorizonMap::compute(map)));
        b.view_weighting = true;
        Ok(b)
    }

    /// A normal-mapped material shaded texel by texel: the normal of the texel under the
    /// point (nearest texel, wrapped), with the facet transfer and diffuse term of `surface`
    /// and `texels_per_uv` texels per unit of texture coordinate. A normal map has no heights,
    /// hence no shadowing of the light by its bumps.
    ///
    /// # Errors
    /// A message when `texels_per_uv` is not a finite positive number.
    pub fn from_normal_map(
        map: &NormalMap,
        surface: &Material,
        texels_per_uv: f64,
    ) -> Result<BumpMapped, String> {
        check_scale(texels_per_uv)?;
        let f = FacetNormals::from_normal_map(map);
        Ok(BumpMapped {
            cols: f.cols,
            rows: f.rows,
            normals: f.normals.iter().map(|&n| [n, n]).collect(),
            shadows: None,
            facet: Facet::new(&surface.transfer),
            diffuse: surface.diffuse.map(|a| (a * FRAC_1_PI) as f32),
            texels_per_uv,
            view_weighting: false,
        })
    }

    /// The facet normal (local frame) at texture coordinates `(u, v)` (glTF's orientation, `v`
    /// down the image): of the triangulated
    /// height map, or of the normal map's texel.
    #[must_use]
    pub fn normal_at(&self, u: f64, v: f64) -> DVec3 {
        let (x, y) = super::map_xy(u, v, self.texels_per_uv, self.rows);
        let (fx, fy) = (x.floor(), y.floor());
        let j = (fx as i64).rem_euclid(self.cols as i64) as usize;
        let i = (fy as i64).rem_euclid(self.rows as i64) as usize;
        // Triangle A is the half with y − y_i < x − x_j.
        let tri = usize::from(y - fy >= x - fx);
        self.normals[i * self.cols + j][tri]
    }

    /// With `on`, weight each pixel sample by the area of its facet the viewer sees,
    /// `(m·o)⁺/(m_z·o_z)` times the facet's visibility of the viewer (found as the light's,
    /// when shadowing: by a ray on the displaced surface), the pixel being their
    /// weighted mean ([`Shader::sample_weight`]): the displaced surface's look without its
    /// parallax, the truth that [`NdfMapped::with_view_weighting`] filters. Default: on with
    /// shadowing ([`BumpMapped::new`] with `shadowing`), off without and for normal maps (the
    /// plain average over the surface). One sample per pixel is unchanged.
    #[must_use]
    pub fn with_view_weighting(mut self, on: bool) -> BumpMapped {
        self.view_weighting = on;
        self
    }

    /// Whether the point at `(u, v)`, on its facet of normal `m`, sees the direction `w`: 1 or
    /// 0 (1 without shadowing).
    fn shadow(&self, u: f64, v: f64, m: DVec3, w: DVec3) -> f32 {
        let Some(shadows) = &self.shadows else {
            return 1.0;
        };
        let (x, y) = super::map_xy(u, v, self.texels_per_uv, self.rows);
        match shadows {
            Shadows::Rays(g) => f32::from(u8::from(g.sees(x, y, m, w))),
            Shadows::Horizon(h) => {
                let j = (x.round() as i64).rem_euclid(h.width as i64) as usize;
                let i = (y.round() as i64).rem_euclid(h.height as i64) as usize;
                h.sample_stats(i, j).visibility(w) as f32
            }
        }
    }
}

impl Shader for BumpMapped {
    /// "bump-mapped: C × R cells[, horizon shadowing][, view-weighted]".
    fn describe(&self) -> Option<String> {
        Some(format!(
            "bump-mapped: {} × {} cells{}{}",
            self.cols,
            self.rows,
            match self.shadows {
                Some(Shadows::Rays(_)) => ", ray-traced shadowing",
                Some(Shadows::Horizon(_)) => ", horizon shadowing",
                None => "",
            },
            if self.view_weighting {
                ", view-weighted"
            } else {
                ""
            }
        ))
    }

    /// With view weighting ([`BumpMapped::with_view_weighting`]), `(m·o)⁺/(m_z·o_z)` times the
    /// facet's visibility of the viewer; 1 otherwise.
    fn sample_weight(&self, sp: &ShadingPoint, wo: DVec3) -> f64 {
        if !self.view_weighting {
            return 1.0;
        }
        if wo.z <= 0.0 {
            return 0.0;
        }
        let m = self.normal_at(sp.uv.x, sp.uv.y);
        if m.z <= 0.0 {
            return 0.0;
        }
        let seen = m.dot(wo);
        if seen <= 0.0 {
            return 0.0;
        }
        seen / (m.z * wo.z) * f64::from(self.shadow(sp.uv.x, sp.uv.y, m, wo))
    }

    fn eval(&self, sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let Some(h) = half_vector(wi, wo) else {
            return [0.0; 3];
        };
        let m = self.normal_at(sp.uv.x, sp.uv.y);
        let v = self.facet.lit(m, wi, wo, h);
        // No ray for a facet that reflects nothing (turned away from the light).
        let s = if v == [0.0; 3] {
            0.0
        } else {
            self.shadow(sp.uv.x, sp.uv.y, m, wi) / wi.z as f32
        };
        [
            v[0] * s + self.diffuse[0],
            v[1] * s + self.diffuse[1],
            v[2] * s + self.diffuse[2],
        ]
    }
}
