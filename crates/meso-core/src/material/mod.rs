//! The TOML material format (documented in `docs/material-format.md`).
//!
//! A material is an NDF (`[ndf]`), a facet transfer function (`[transfer]`), an optional Lambert
//! term (`[diffuse]`), the convolution form (`form`), and for NDFs from height maps a masking
//! model (`[shadowing]`). Angles in the file are degrees; axes are `[theta_deg, phi_deg]` in the
//! local frame (θ from the normal, φ from the tangent) or, where noted, `[x, y, z]` vectors.
//!
//! Parsing is two-step: [`MaterialSpec::parse`] checks the syntax and every value; NDFs that live
//! in other files (`kind = "heightmap"`, `kind = "map"`) stay as [`NdfSpec::External`] until a
//! [`NdfResolver`] (the `meso-maps` crate) loads them. [`Material::from_toml_str`] and
//! [`Material::from_file`] do both steps with the core resolver, which refuses external NDFs.
//!
//! Writing is the inverse: [`MaterialSpec::to_toml`] (and [`Material::to_spec`]) give the file of
//! a material, written so that it reads back to the same value exactly.
//!
//! The module is split by concern: the types and the build step here, the reader in `parse`,
//! the writer in `write`.

mod parse;
mod write;

pub use parse::{FRESNEL_KINDS, NDF_KINDS, TRANSFER_KINDS};

use crate::convolution::{effective_brdf_with, Accuracy, Form, Visibility};
use crate::ndf::Ndf;
use crate::transfer::Transfer;
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// An error in a material file: what is wrong and where (`[table] key`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct MaterialError(pub String);

fn err<T>(msg: impl Into<String>) -> Result<T, MaterialError> {
    Err(MaterialError(msg.into()))
}

/// The largest file meso reads as a material (1 MiB).
pub const MAX_MATERIAL_BYTES: u64 = 1 << 20;

/// The masking–shadowing choice of a material (`[shadowing] kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ShadowingKind {
    /// No masking or shadowing.
    None,
    /// Smith masking–shadowing derived from the NDF.
    #[default]
    Smith,
    /// Filtered horizon angles of the height map (needs an NDF from a height map or map file).
    Horizon,
    /// The height map's own visibility of each facet normal, lit from `i` and seen from `o`
    /// jointly (`G(i, o | m)`, from the heights; needs a resolver model that conditions on the
    /// normal, e.g. `represent = "facets"`). The default wherever one is available.
    Visibility,
    /// [`ShadowingKind::Visibility`] plus the light reflected more than once inside the
    /// microgeometry (`[shadowing] kind = "visibility"`, `interreflection = true`; Lambert,
    /// Phong or microfacet facets; `meso_core::convolution::deltas_interreflection`).
    VisibilityInterreflected,
}

pub use crate::visibility::VisibilityModel;

/// The `[ndf]` table, parsed.
#[derive(Clone, Debug, PartialEq)]
pub enum NdfSpec {
    /// An NDF fully described in the file.
    Inline(Ndf),
    /// An NDF to be loaded from another file by a [`NdfResolver`]: the `kind` and the raw table
    /// (with `file` already resolved against the material file's folder).
    External {
        /// `"heightmap"` or `"map"`.
        kind: String,
        /// The whole `[ndf]` table.
        table: toml::Table,
        /// The referenced file, absolute or relative to the working directory.
        file: PathBuf,
    },
}

/// What a resolver returns for an external NDF.
#[derive(Clone, Debug)]
pub struct ResolvedNdf {
    /// The NDF itself (e.g. the fitted lobes of a pyramid texel).
    pub ndf: Ndf,
    /// The height map's own masking model, if it has one (used by `shadowing = "horizon"`).
    pub horizon: Option<Arc<dyn VisibilityModel>>,
    /// The form to use by default for this NDF (the microfacet form for height maps).
    pub default_form: Form,
}

/// Loads NDFs that live in other files.
pub trait NdfResolver {
    /// Load the NDF of kind `kind` described by `table`, whose `file` is `file`.
    ///
    /// # Errors
    /// Any problem with the file or the table, as a message naming it.
    fn resolve(
        &self,
        kind: &str,
        table: &toml::Table,
        file: &Path,
    ) -> Result<ResolvedNdf, MaterialError>;
}

/// The core resolver: knows no external NDFs.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoExternalNdfs;

impl NdfResolver for NoExternalNdfs {
    fn resolve(&self, kind: &str, _: &toml::Table, _: &Path) -> Result<ResolvedNdf, MaterialError> {
        err(format!(
            "[ndf] kind = \"{kind}\" needs the height-map support of the `meso` tool (meso-maps)"
        ))
    }
}

/// A parsed and validated material file, before external NDFs are loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialSpec {
    /// Optional display name.
    pub name: Option<String>,
    /// The NDF.
    pub ndf: NdfSpec,
    /// The facet transfer function.
    pub transfer: Transfer,
    /// Lambert albedo added as `albedo/π` (RGB), zero by default.
    pub diffuse: [f64; 3],
    /// The convolution form, if the file names one.
    pub form: Option<Form>,
    /// The masking choice, if the file names one.
    pub shadowing: Option<ShadowingKind>,
    /// Quadrature accuracy.
    pub accuracy: Accuracy,
}

/// A material ready to evaluate.
#[derive(Clone, Debug)]
pub struct Material {
    /// Optional display name.
    pub name: Option<String>,
    /// The NDF.
    pub ndf: Ndf,
    /// The facet transfer function.
    pub transfer: Transfer,
    /// Lambert albedo (RGB); the BRDF adds `albedo/π`.
    pub diffuse: [f64; 3],
    /// The convolution form.
    pub form: Form,
    /// The masking choice of the microfacet form.
    pub shadowing: ShadowingKind,
    /// The height map's masking model, for `ShadowingKind::Horizon`.
    pub horizon: Option<Arc<dyn VisibilityModel>>,
    /// Quadrature accuracy.
    pub accuracy: Accuracy,
}

impl Material {
    /// A material from its parts, multiple-surface form, no diffuse term.
    #[must_use]
    pub fn new(ndf: Ndf, transfer: Transfer) -> Material {
        Material {
            name: None,
            ndf,
            transfer,
            diffuse: [0.0; 3],
            form: Form::MultipleSurface,
            shadowing: ShadowingKind::None,
            horizon: None,
            accuracy: Accuracy::default(),
        }
    }

    /// Parse a material from TOML text with inline NDFs only.
    ///
    /// # Errors
    /// A [`MaterialError`] naming the table, key and problem.
    pub fn from_toml_str(text: &str) -> Result<Material, MaterialError> {
        MaterialSpec::parse(text, Path::new("."))?.build(&NoExternalNdfs)
    }

    /// Read a material file; external NDFs are loaded with `resolver`.
    ///
    /// # Errors
    /// Unreadable or oversized files, and every [`MaterialError`]; messages start with the path.
    pub fn from_file(path: &Path, resolver: &dyn NdfResolver) -> Result<Material, MaterialError> {
        let text = read_limited(path)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        MaterialSpec::parse(&text, dir)
            .and_then(|s| s.build(resolver))
            .map_err(|e| MaterialError(format!("{}: {}", path.display(), e.0)))
    }

    /// The effective BRDF (RGB, 1/sr, without the cosine) for unit directions in the local frame,
    /// both above the surface; 0 otherwise.
    #[must_use]
    pub fn brdf(&self, i: DVec3, o: DVec3) -> [f64; 3] {
        if i.z <= 0.0 || o.z <= 0.0 {
            return [0.0; 3];
        }
        let mut f = self.convolved(i, o);
        for (c, d) in f.iter_mut().zip(self.diffuse) {
            *c += d / std::f64::consts::PI;
        }
        f
    }

    /// The convolution part of [`Material::brdf`] (Eq. 2/8 with the material's form and
    /// masking choice, no diffuse term), 1/sr: the one place a [`ShadowingKind`] becomes a
    /// [`Visibility`]. The light between facets (`interreflection = true`) is solved from the
    /// geometry where the visibility model can ([`VisibilityModel::interreflected`]).
    #[must_use]
    pub fn convolved(&self, i: DVec3, o: DVec3) -> [f64; 3] {
        self.convolved_with(i, o, true)
    }

    /// [`Material::convolved`] with the light between facets estimated from the sky views
    /// rather than solved (`solve_bounces = false`): what the interactive plans
    /// ([`crate::shading::Policy::Interactive`]: the renderer, the editor) evaluate, since
    /// solving it costs a radiosity solve per direction pair.
    #[must_use]
    pub fn convolved_with(&self, i: DVec3, o: DVec3, solve_bounces: bool) -> [f64; 3] {
        let horizon = self.horizon.as_ref();
        let custom = |a: DVec3, b: DVec3| horizon.map_or(1.0, |h| h.g(a, b));
        let vis = match self.shadowing {
            ShadowingKind::Smith => Visibility::Smith,
            ShadowingKind::None => Visibility::None,
            ShadowingKind::Horizon => Visibility::Custom(&custom),
            ShadowingKind::Visibility | ShadowingKind::VisibilityInterreflected => match horizon {
                Some(h) => Visibility::GivenNormal(h.as_ref()),
                None => Visibility::None,
            },
        };
        let mut f = effective_brdf_with(
            &self.ndf,
            &self.transfer,
            self.form,
            vis,
            i,
            o,
            self.accuracy,
        );
        if let (ShadowingKind::VisibilityInterreflected, Some(h), Ndf::Deltas(d)) =
            (self.shadowing, horizon, &self.ndf)
        {
            let extra = crate::convolution::deltas_interreflection(
                d,
                &self.transfer,
                h.as_ref(),
                i,
                o,
                solve_bounces,
            );
            for (c, e) in f.iter_mut().zip(extra) {
                *c += e;
            }
        }
        f
    }
}

/// Read a material file's text: at most [`MAX_MATERIAL_BYTES`] bytes actually read (so
/// `/dev/zero` and FIFOs are limited too), UTF-8; errors name the file.
///
/// # Errors
/// The file cannot be read, is too large, or is not UTF-8.
pub fn read_limited(path: &Path) -> Result<String, MaterialError> {
    let bytes = crate::io::read_limited(path, MAX_MATERIAL_BYTES).map_err(|e| {
        if e.kind() == std::io::ErrorKind::FileTooLarge {
            MaterialError(format!(
                "{}: too large for a material file (limit {MAX_MATERIAL_BYTES} bytes)",
                path.display()
            ))
        } else {
            MaterialError(format!("{}: cannot read: {e}", path.display()))
        }
    })?;
    String::from_utf8(bytes)
        .map_err(|_| MaterialError(format!("{}: not UTF-8 text", path.display())))
}

/// Largest conductor `eta` and `k` component accepted (the dielectric `eta`'s bound, 100):
/// real metals have `eta` below 10 and `k` below 20, and far larger values overflow Fresnel's
/// terms to NaN.
pub const MAX_CONDUCTOR: f64 = 100.0;

/// Largest exponent accepted anywhere (beyond it a lobe is a delta; use `kind = "deltas"`).
pub const MAX_EXPONENT: f64 = 1e7;

/// Most lobes of a `phong-peaks` NDF (the quadrature's cost grows as the square of the count).
pub const MAX_PHONG_LOBES: usize = 256;
/// Most normals of a `deltas` NDF.
pub const MAX_DELTAS: usize = 100_000;
/// Most cells of a `tabulated` NDF.
pub const MAX_TABLE_CELLS: usize = 1 << 20;

impl MaterialSpec {
    /// Load external NDFs with `resolver` and fix the defaults: the multiple-surface form for inline
    /// NDFs, the resolver's form (microfacet) for height maps; Smith masking in the microfacet form
    /// unless the file says otherwise.
    ///
    /// # Errors
    /// A resolver error, or `shadowing = "horizon"` without a height map.
    pub fn build(self, resolver: &dyn NdfResolver) -> Result<Material, MaterialError> {
        let (ndf, horizon, default_form) = match self.ndf {
            NdfSpec::Inline(n) => (n, None, Form::MultipleSurface),
            NdfSpec::External { kind, table, file } => {
                let r = resolver.resolve(&kind, &table, &file)?;
                (r.ndf, r.horizon, r.default_form)
            }
        };
        let form = self.form.unwrap_or(default_form);
        let conditioned = horizon.as_ref().is_some_and(|h| h.conditions_on_normal());
        let shadowing = match (self.shadowing, form) {
            (Some(s), _) => s,
            (None, Form::Microfacet) if conditioned => ShadowingKind::Visibility,
            (None, Form::Microfacet) => ShadowingKind::Smith,
            (None, Form::MultipleSurface) => ShadowingKind::None,
        };
        if shadowing == ShadowingKind::Horizon && horizon.is_none() {
            return err(
                "[shadowing] kind = \"horizon\" needs an NDF from a height map or map file",
            );
        }
        if shadowing == ShadowingKind::VisibilityInterreflected
            && matches!(self.transfer, Transfer::Mirror { .. })
        {
            return err(
                "[shadowing] interreflection = true needs facets with a BRDF (lambert, phong or \
                 microfacet): the light between perfect mirror facets cannot be traced; use \
                 [transfer] kind = \"microfacet\" with a small alpha",
            );
        }
        if matches!(
            shadowing,
            ShadowingKind::Visibility | ShadowingKind::VisibilityInterreflected
        ) && !conditioned
        {
            return err(
                "[shadowing] kind = \"visibility\" needs a height-map NDF that keeps its facets' \
                 visibility ([ndf] kind = \"heightmap\" with represent = \"facets\")",
            );
        }
        if let Transfer::Mirror { .. } = self.transfer {
            if ndf.is_singular() {
                return err(if conditioned {
                    "[transfer] kind = \"mirror\" needs a continuous NDF: a height map's facets \
                     (represent = \"facets\", the default) are a sum of deltas; use a rough facet \
                     (kind = \"microfacet\") or represent = \"lobes\""
                } else {
                    "[transfer] kind = \"mirror\" needs a continuous NDF"
                });
            }
        }
        Ok(Material {
            name: self.name,
            ndf,
            transfer: self.transfer,
            diffuse: self.diffuse,
            form,
            shadowing,
            horizon,
            accuracy: self.accuracy,
        })
    }
}
