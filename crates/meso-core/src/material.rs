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

use crate::convolution::{effective_brdf_with, Accuracy, Form, Visibility};
use crate::display::Num;
use crate::frame::spherical_direction_deg;
use crate::ndf::{
    Cylinder, DeltaSum, Distribution, Harmonics, Microfacet, Mixture, Ndf, PhongLobe, PhongPeaks,
    Radial, Sphere, Tabulated, VonMisesFisher, WeightedNormal,
};
use crate::transfer::{Fresnel, PhongVariant, Transfer};
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
    /// microgeometry (`[shadowing] kind = "visibility"`, `interreflection = true`; Lambert
    /// facets; `meso_core::convolution::deltas_interreflection`).
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
    /// [`Visibility`].
    #[must_use]
    pub fn convolved(&self, i: DVec3, o: DVec3) -> [f64; 3] {
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
            let extra =
                crate::convolution::deltas_interreflection(d, &self.transfer, h.as_ref(), i, o);
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

/// A view of one TOML table that remembers which keys were used, to reject unknown ones.
struct Fields<'a> {
    name: String,
    table: &'a toml::Table,
    used: Vec<&'static str>,
}

impl<'a> Fields<'a> {
    fn new(name: impl Into<String>, table: &'a toml::Table) -> Fields<'a> {
        Fields {
            name: name.into(),
            table,
            used: Vec::new(),
        }
    }

    fn get(&mut self, key: &'static str) -> Option<&'a toml::Value> {
        self.used.push(key);
        self.table.get(key)
    }

    fn finish(self) -> Result<(), MaterialError> {
        for k in self.table.keys() {
            if !self.used.contains(&k.as_str()) {
                let known = self.used.join(", ");
                // A textured material (height map over uv) only means something on an object.
                let hint = if self.name == "material" && k == "texture" {
                    "; a [texture] table makes a bump- or NDF-mapped material for scene files                      (`meso render`, docs/scene-format.md)"
                } else {
                    ""
                };
                return err(format!(
                    "{}: unknown key `{k}` (known here: {known}){hint}",
                    self.name
                ));
            }
        }
        Ok(())
    }

    fn number(&mut self, key: &'static str) -> Result<Option<f64>, MaterialError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => number(v).map(Some).ok_or_else(|| {
                MaterialError(format!("{} {key}: expected a number, got {v}", self.name))
            }),
        }
    }

    fn req_number(&mut self, key: &'static str) -> Result<f64, MaterialError> {
        self.number(key)?
            .ok_or_else(|| MaterialError(format!("{}: missing `{key}`", self.name)))
    }

    /// A finite number ≥ `min` (and ≤ `max`).
    fn bounded(
        &mut self,
        key: &'static str,
        min: f64,
        max: f64,
    ) -> Result<Option<f64>, MaterialError> {
        let v = self.number(key)?;
        if let Some(x) = v {
            if !(x.is_finite() && x >= min && x <= max) {
                return err(format!(
                    "{} {key}: must be a finite number in [{}, {}], got {}",
                    self.name,
                    Num(min),
                    Num(max),
                    Num(x)
                ));
            }
        }
        Ok(v)
    }

    fn string(&mut self, key: &'static str) -> Result<Option<&'a str>, MaterialError> {
        match self.get(key) {
            None => Ok(None),
            Some(toml::Value::String(s)) => Ok(Some(s.as_str())),
            Some(v) => err(format!("{} {key}: expected a string, got {v}", self.name)),
        }
    }

    fn boolean(&mut self, key: &'static str) -> Result<Option<bool>, MaterialError> {
        match self.get(key) {
            None => Ok(None),
            Some(toml::Value::Boolean(b)) => Ok(Some(*b)),
            Some(v) => err(format!(
                "{} {key}: expected true or false, got {v}",
                self.name
            )),
        }
    }

    fn array(&mut self, key: &'static str, len: usize) -> Result<Option<Vec<f64>>, MaterialError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => {
                let a = numbers(v).ok_or_else(|| {
                    MaterialError(format!("{} {key}: expected an array of numbers", self.name))
                })?;
                if len > 0 && a.len() != len {
                    return err(format!(
                        "{} {key}: expected {len} numbers, got {}",
                        self.name,
                        a.len()
                    ));
                }
                if let Some(x) = a.iter().find(|x| !x.is_finite()) {
                    return err(format!("{} {key}: {x} is not a finite number", self.name));
                }
                Ok(Some(a))
            }
        }
    }

    /// An RGB triple in `[0, max]`.
    fn rgb(&mut self, key: &'static str, max: f64) -> Result<Option<[f64; 3]>, MaterialError> {
        let Some(a) = self.array(key, 3)? else {
            return Ok(None);
        };
        if let Some(x) = a.iter().find(|x| !(**x >= 0.0 && **x <= max)) {
            return err(format!(
                "{} {key}: colour components must be in [0, {}], got {}",
                self.name,
                Num(max),
                Num(*x)
            ));
        }
        Ok(Some([a[0], a[1], a[2]]))
    }
}

fn number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

fn numbers(v: &toml::Value) -> Option<Vec<f64>> {
    v.as_array()?.iter().map(number).collect()
}

/// An axis: `[theta_deg, phi_deg]` or a vector `[x, y, z]`.
fn axis(fields: &mut Fields<'_>, key: &'static str) -> Result<Option<DVec3>, MaterialError> {
    let Some(a) = fields.array(key, 0)? else {
        return Ok(None);
    };
    match a.len() {
        2 => {
            if !(0.0..=180.0).contains(&a[0]) {
                return err(format!(
                    "{} {key}: theta must be in [0, 180] degrees, got {}",
                    fields.name, a[0]
                ));
            }
            Ok(Some(spherical_direction_deg(a[0], a[1])))
        }
        3 => {
            let v = DVec3::new(a[0], a[1], a[2]);
            if !(v.is_finite() && v.length() > 1e-12) {
                return err(format!(
                    "{} {key}: [{}, {}, {}] is not a direction (zero length)",
                    fields.name, a[0], a[1], a[2]
                ));
            }
            Ok(Some(v.normalize()))
        }
        n => err(format!(
            "{} {key}: expected [theta_deg, phi_deg] or [x, y, z], got {n} numbers",
            fields.name
        )),
    }
}

/// Largest exponent accepted anywhere (beyond it a lobe is a delta; use `kind = "deltas"`).
pub const MAX_EXPONENT: f64 = 1e7;

/// Most lobes of a `phong-peaks` NDF (the quadrature's cost grows as the square of the count).
pub const MAX_PHONG_LOBES: usize = 256;
/// Most normals of a `deltas` NDF.
pub const MAX_DELTAS: usize = 100_000;
/// Most cells of a `tabulated` NDF.
pub const MAX_TABLE_CELLS: usize = 1 << 20;

fn parse_lobes(
    f: &mut Fields<'_>,
    with_exponent: bool,
) -> Result<Vec<(DVec3, f64, f64)>, MaterialError> {
    let name = f.name.clone();
    let Some(v) = f.get("lobes") else {
        return err(format!("{name}: missing `lobes`"));
    };
    let Some(arr) = v.as_array() else {
        return err(format!("{name} lobes: expected an array of tables"));
    };
    if arr.is_empty() {
        return err(format!("{name} lobes: the list is empty"));
    }
    let (limit, what) = if with_exponent {
        (MAX_PHONG_LOBES, "phong-peaks lobes")
    } else {
        (MAX_DELTAS, "delta normals")
    };
    if arr.len() > limit {
        return err(format!(
            "{name} lobes: {} {what} is above the limit of {limit}",
            arr.len()
        ));
    }
    let mut out = Vec::with_capacity(arr.len());
    for (k, item) in arr.iter().enumerate() {
        let Some(t) = item.as_table() else {
            return err(format!("{name} lobes[{}]: expected a table", k + 1));
        };
        let mut lf = Fields::new(format!("{name} lobes[{}]", k + 1), t);
        let ax = axis(&mut lf, "axis")?
            .ok_or_else(|| MaterialError(format!("{name} lobes[{}]: missing `axis`", k + 1)))?;
        let w = lf.req_number("weight")?;
        if !(w.is_finite() && w >= 0.0) {
            return err(format!(
                "{name} lobes[{}] weight: must be a finite number >= 0, got {}",
                k + 1,
                Num(w)
            ));
        }
        let e = if with_exponent {
            let e = lf.req_number("exponent")?;
            if !(e.is_finite() && (0.0..=MAX_EXPONENT).contains(&e)) {
                return err(format!(
                    "{name} lobes[{}] exponent: must be a finite number in [0, {}], got {}",
                    k + 1,
                    Num(MAX_EXPONENT),
                    Num(e)
                ));
            }
            e
        } else {
            0.0
        };
        lf.finish()?;
        out.push((ax, w, e));
    }
    if out.iter().map(|l| l.1).sum::<f64>() <= 0.0 {
        return err(format!("{name} lobes: the weights sum to zero"));
    }
    Ok(out)
}

fn ndf_err(e: crate::NdfError) -> MaterialError {
    MaterialError(format!("[ndf]: {e}"))
}

/// Parse an inline NDF table (also used for `of = { … }` in harmonics and tabulated NDFs).
fn parse_ndf(name: &str, t: &toml::Table, depth: usize) -> Result<Ndf, MaterialError> {
    let mut f = Fields::new(name, t);
    let kind = f
        .string("kind")?
        .ok_or_else(|| MaterialError(format!("{name}: missing `kind`")))?;
    let ndf = match kind {
        "phong-peaks" => {
            let lobes = parse_lobes(&mut f, true)?;
            Ndf::PhongPeaks(
                PhongPeaks::new(
                    lobes
                        .into_iter()
                        .map(|(a, w, e)| PhongLobe::new(a, w, e))
                        .collect(),
                )
                .map_err(ndf_err)?,
            )
        }
        "deltas" => {
            let lobes = parse_lobes(&mut f, false)?;
            Ndf::Deltas(
                DeltaSum::new(
                    lobes
                        .into_iter()
                        .map(|(a, w, _)| WeightedNormal {
                            normal: a,
                            weight: w,
                        })
                        .collect(),
                )
                .map_err(ndf_err)?,
            )
        }
        "sphere" => Ndf::Sphere(Sphere),
        "cylinder" => {
            let ax = axis(&mut f, "axis")?.unwrap_or(DVec3::X);
            let half = f.boolean("half")?.unwrap_or(false);
            Ndf::Cylinder(Cylinder::new(ax, half).map_err(ndf_err)?)
        }
        "vmf" => {
            let ax = axis(&mut f, "axis")?.unwrap_or(DVec3::Z);
            let kappa = f
                .bounded("kappa", 1e-6, MAX_EXPONENT)?
                .ok_or_else(|| MaterialError(format!("{name}: missing `kappa`")))?;
            Ndf::VonMisesFisher(VonMisesFisher::new(ax, kappa).map_err(ndf_err)?)
        }
        "beckmann" | "ggx" => {
            let dist = if kind == "ggx" {
                Distribution::Ggx
            } else {
                Distribution::Beckmann
            };
            let (ax, ay) = alphas(&mut f)?;
            Ndf::Microfacet(Microfacet::new(dist, ax, ay).map_err(ndf_err)?)
        }
        "mixture" => Ndf::Mixture(parse_mixture(&mut f)?),
        "harmonics" => {
            let band = f.bounded("band", 0.0, crate::ndf::harmonics::MAX_BAND as f64)?;
            let coeffs = f.array("coefficients", 0)?;
            let of = f.get("of");
            match (coeffs, of) {
                (Some(c), None) => {
                    let lmax = match band {
                        Some(b) => b as usize,
                        None => ((c.len() as f64).sqrt() as usize).saturating_sub(1),
                    };
                    Ndf::Harmonics(Harmonics::from_coeffs(lmax, c).map_err(ndf_err)?)
                }
                (None, Some(v)) => {
                    let inner = sub_ndf(name, v, depth)?;
                    let lmax = band.unwrap_or(16.0) as usize;
                    Ndf::Harmonics(Harmonics::project(lmax, 4, |m| inner.eval(m)).map_err(ndf_err)?)
                }
                _ => {
                    return err(format!(
                        "{name}: harmonics need exactly one of `coefficients` or `of`"
                    ))
                }
            }
        }
        "tabulated" => {
            let nz = f.bounded("n_z", 1.0, 4096.0)?.unwrap_or(64.0) as usize;
            let np = f.bounded("n_phi", 1.0, 8192.0)?.unwrap_or(128.0) as usize;
            if nz * np > MAX_TABLE_CELLS {
                return err(format!(
                    "{name}: {nz} × {np} cells is above the limit {MAX_TABLE_CELLS}"
                ));
            }
            let grid = crate::grid::EqualAreaGrid::new(nz, np);
            let values = f.array("values", 0)?;
            let of = f.get("of");
            match (values, of) {
                (Some(v), None) => {
                    Ndf::Tabulated(Tabulated::from_values(grid, v).map_err(ndf_err)?)
                }
                (None, Some(v)) => {
                    let inner = sub_ndf(name, v, depth)?;
                    Ndf::Tabulated(Tabulated::from_fn(grid, 4, |m| inner.eval(m)).map_err(ndf_err)?)
                }
                _ => {
                    return err(format!(
                        "{name}: tabulated NDFs need exactly one of `values` or `of`"
                    ))
                }
            }
        }
        "radial" => {
            let theta = f
                .array("theta", 0)?
                .ok_or_else(|| MaterialError(format!("{name}: missing `theta` (degrees)")))?;
            let density = f
                .array("density", 0)?
                .ok_or_else(|| MaterialError(format!("{name}: missing `density` (1/sr)")))?;
            let theta = theta.into_iter().map(f64::to_radians).collect();
            Ndf::Radial(Radial::new(theta, density).map_err(ndf_err)?)
        }
        other => {
            return err(format!(
                "{name} kind: unknown NDF kind \"{other}\" (known: phong-peaks, deltas, sphere, \
                 cylinder, vmf, beckmann, ggx, mixture, harmonics, tabulated, radial, heightmap, map)"
            ))
        }
    };
    f.finish()?;
    Ok(ndf)
}

fn sub_ndf(name: &str, v: &toml::Value, depth: usize) -> Result<Ndf, MaterialError> {
    if depth > 2 {
        return err(format!("{name} of: NDFs nested too deeply"));
    }
    let t = v
        .as_table()
        .ok_or_else(|| MaterialError(format!("{name} of: expected a table")))?;
    let inner = parse_ndf(&format!("{name} of"), t, depth + 1)?;
    if inner.is_singular() {
        return err(format!(
            "{name} of: a {} NDF is singular and cannot be projected or tabulated",
            inner.kind()
        ));
    }
    Ok(inner)
}

/// `kind = "mixture"`: `lobes = [ { kind = "ggx" | "beckmann", alpha = …, weight = … }, … ]`
/// (`alpha_x` and `alpha_y` instead of `alpha` for an anisotropic lobe).
fn parse_mixture(f: &mut Fields<'_>) -> Result<Mixture, MaterialError> {
    let name = f.name.clone();
    let Some(v) = f.get("lobes") else {
        return err(format!(
            "{name}: a mixture needs `lobes = [ {{ kind = \"ggx\", alpha = 0.1, weight = 1 }}, … ]`"
        ));
    };
    let Some(arr) = v.as_array() else {
        return err(format!("{name} lobes: expected an array of tables"));
    };
    if arr.is_empty() {
        return err(format!("{name} lobes: the list is empty"));
    }
    let limit = crate::ndf::mixture::MAX_MIXTURE_LOBES;
    if arr.len() > limit {
        return err(format!(
            "{name} lobes: {} mixture lobes is above the limit of {limit}",
            arr.len()
        ));
    }
    let mut out = Vec::with_capacity(arr.len());
    for (k, item) in arr.iter().enumerate() {
        let Some(t) = item.as_table() else {
            return err(format!("{name} lobes[{}]: expected a table", k + 1));
        };
        let mut lf = Fields::new(format!("{name} lobes[{}]", k + 1), t);
        let dist = match lf.string("kind")? {
            Some("ggx") => Distribution::Ggx,
            Some("beckmann") => Distribution::Beckmann,
            Some(other) => {
                return err(format!(
                    "{name} lobes[{}] kind: unknown lobe kind \"{other}\" (known: ggx, beckmann)",
                    k + 1
                ))
            }
            None => return err(format!("{name} lobes[{}]: missing `kind`", k + 1)),
        };
        let (ax, ay) = alphas(&mut lf)?;
        let w = lf.req_number("weight")?;
        if !(w.is_finite() && w >= 0.0) {
            return err(format!(
                "{name} lobes[{}] weight: must be a finite number >= 0, got {}",
                k + 1,
                Num(w)
            ));
        }
        lf.finish()?;
        let mf = Microfacet::new(dist, ax, ay)
            .map_err(|e| MaterialError(format!("{name} lobes[{}]: {e}", k + 1)))?;
        out.push((mf, w));
    }
    if out.iter().map(|l| l.1).sum::<f64>() <= 0.0 {
        return err(format!("{name} lobes: the weights sum to zero"));
    }
    Mixture::new(out).map_err(ndf_err)
}

fn alphas(f: &mut Fields<'_>) -> Result<(f64, f64), MaterialError> {
    let lo = crate::ndf::microfacet::MIN_ALPHA;
    let a = f.bounded("alpha", lo, 10.0)?;
    let ax = f.bounded("alpha_x", lo, 10.0)?;
    let ay = f.bounded("alpha_y", lo, 10.0)?;
    match (a, ax, ay) {
        (Some(a), None, None) => Ok((a, a)),
        (None, Some(x), Some(y)) => Ok((x, y)),
        _ => err(format!(
            "{}: give either `alpha` or both `alpha_x` and `alpha_y`",
            f.name
        )),
    }
}

fn parse_fresnel(f: &mut Fields<'_>) -> Result<Fresnel, MaterialError> {
    let kind = f.string("fresnel")?.unwrap_or("none");
    let fr = match kind {
        "none" => Fresnel::None,
        "dielectric" => {
            let eta = f.bounded("eta", 1e-3, 100.0)?.ok_or_else(|| {
                MaterialError(format!("{}: a dielectric needs `eta` (a number)", f.name))
            })?;
            Fresnel::Dielectric { eta }
        }
        "conductor" => {
            let eta = f.array("eta", 3)?;
            let k = f.array("k", 3)?;
            match (eta, k) {
                (Some(e), Some(k)) => {
                    if e.iter().chain(&k).any(|x| *x < 0.0) {
                        return err(format!("{}: conductor eta and k must be >= 0", f.name));
                    }
                    Fresnel::Conductor {
                        eta: [e[0], e[1], e[2]],
                        k: [k[0], k[1], k[2]],
                    }
                }
                _ => {
                    return err(format!(
                        "{}: a conductor needs `eta = [r, g, b]` and `k = [r, g, b]`",
                        f.name
                    ))
                }
            }
        }
        "schlick" => {
            let f0 = f.rgb("f0", 1.0)?.ok_or_else(|| {
                MaterialError(format!("{}: schlick needs `f0 = [r, g, b]`", f.name))
            })?;
            Fresnel::Schlick { f0 }
        }
        other => {
            return err(format!(
                "{} fresnel: unknown \"{other}\" (known: none, conductor, dielectric, schlick)",
                f.name
            ))
        }
    };
    Ok(fr)
}

fn parse_transfer(t: &toml::Table) -> Result<Transfer, MaterialError> {
    let mut f = Fields::new("[transfer]", t);
    let kind = f
        .string("kind")?
        .ok_or_else(|| MaterialError("[transfer]: missing `kind`".into()))?;
    let tr = match kind {
        "phong" => {
            let exponent = f
                .bounded("exponent", 0.0, MAX_EXPONENT)?
                .ok_or_else(|| MaterialError("[transfer]: missing `exponent`".into()))?;
            let specular = f.rgb("specular", 1e6)?.unwrap_or([1.0; 3]);
            let variant = match f.string("variant")?.unwrap_or("half") {
                "half" => PhongVariant::Half,
                "reflect" => PhongVariant::Reflect,
                other => {
                    return err(format!(
                        "[transfer] variant: unknown \"{other}\" (known: half, reflect)"
                    ))
                }
            };
            Transfer::Phong {
                exponent,
                specular,
                variant,
            }
        }
        "lambert" => Transfer::Lambert {
            albedo: f.rgb("albedo", 1.0)?.unwrap_or([1.0; 3]),
        },
        "mirror" => Transfer::Mirror {
            fresnel: parse_fresnel(&mut f)?,
            specular: f.rgb("specular", 1.0)?.unwrap_or([1.0; 3]),
        },
        "microfacet" => {
            let dist = match f.string("distribution")?.unwrap_or("ggx") {
                "ggx" => Distribution::Ggx,
                "beckmann" => Distribution::Beckmann,
                other => {
                    return err(format!(
                        "[transfer] distribution: unknown \"{other}\" (known: beckmann, ggx)"
                    ))
                }
            };
            let (ax, ay) = alphas(&mut f)?;
            Transfer::Microfacet {
                distribution: Microfacet::new(dist, ax, ay)
                    .map_err(|e| MaterialError(format!("[transfer]: {e}")))?,
                fresnel: parse_fresnel(&mut f)?,
            }
        }
        other => {
            return err(format!(
                "[transfer] kind: unknown \"{other}\" (known: phong, lambert, mirror, microfacet)"
            ))
        }
    };
    f.finish()?;
    Ok(tr)
}

impl MaterialSpec {
    /// Parse and validate material TOML; relative `file` paths are taken from `dir`.
    ///
    /// # Errors
    /// A [`MaterialError`] naming the table, the key and the problem.
    pub fn parse(text: &str, dir: &Path) -> Result<MaterialSpec, MaterialError> {
        let doc: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            MaterialError(format!("not valid TOML: {}", e.message()))
        })?;
        let mut top = Fields::new("material", &doc);
        let name = top.string("name")?.map(str::to_owned);
        let form = match top.string("form")? {
            None => None,
            Some("multiple-surface") => Some(Form::MultipleSurface),
            Some("microfacet") => Some(Form::Microfacet),
            Some(o) => {
                return err(format!(
                    "form: unknown \"{o}\" (known: multiple-surface, microfacet)"
                ))
            }
        };
        let ndf = match top.get("ndf") {
            None => NdfSpec::Inline(Ndf::surface_normal()),
            Some(v) => {
                let t = v
                    .as_table()
                    .ok_or_else(|| MaterialError("[ndf]: expected a table".into()))?;
                match t.get("kind").and_then(|k| k.as_str()) {
                    Some(k @ ("heightmap" | "map")) => {
                        let file = t.get("file").and_then(|f| f.as_str()).ok_or_else(|| {
                            MaterialError(format!("[ndf]: kind = \"{k}\" needs `file = \"…\"`"))
                        })?;
                        NdfSpec::External {
                            kind: k.to_owned(),
                            table: t.clone(),
                            file: dir.join(file),
                        }
                    }
                    _ => NdfSpec::Inline(parse_ndf("[ndf]", t, 0)?),
                }
            }
        };
        let transfer = match top.get("transfer") {
            None => return err("[transfer]: missing (every material needs a transfer function)"),
            Some(v) => parse_transfer(
                v.as_table()
                    .ok_or_else(|| MaterialError("[transfer]: expected a table".into()))?,
            )?,
        };
        let diffuse = match top.get("diffuse") {
            None => [0.0; 3],
            Some(v) => {
                let t = v
                    .as_table()
                    .ok_or_else(|| MaterialError("[diffuse]: expected a table".into()))?;
                let mut f = Fields::new("[diffuse]", t);
                let a = f
                    .rgb("albedo", 1.0)?
                    .ok_or_else(|| MaterialError("[diffuse]: missing `albedo`".into()))?;
                f.finish()?;
                a
            }
        };
        let shadowing = match top.get("shadowing") {
            None => None,
            Some(v) => {
                let t = v
                    .as_table()
                    .ok_or_else(|| MaterialError("[shadowing]: expected a table".into()))?;
                let mut f = Fields::new("[shadowing]", t);
                let k = match f.string("kind")? {
                    Some("none") => ShadowingKind::None,
                    Some("smith") => ShadowingKind::Smith,
                    Some("horizon") => ShadowingKind::Horizon,
                    Some("visibility") => {
                        if f.boolean("interreflection")?.unwrap_or(false) {
                            ShadowingKind::VisibilityInterreflected
                        } else {
                            ShadowingKind::Visibility
                        }
                    }
                    Some(o) => {
                        return err(format!(
                            "[shadowing] kind: unknown \"{o}\" (known: visibility, horizon, smith, none)"
                        ))
                    }
                    None => return err("[shadowing]: missing `kind`"),
                };
                f.finish()?;
                Some(k)
            }
        };
        let accuracy = match top.get("quadrature") {
            None => Accuracy::default(),
            Some(v) => {
                let t = v
                    .as_table()
                    .ok_or_else(|| MaterialError("[quadrature]: expected a table".into()))?;
                let mut f = Fields::new("[quadrature]", t);
                let d = Accuracy::default();
                let radial = f
                    .bounded("radial", 2.0, 128.0)?
                    .map_or(d.radial, |x| x as usize);
                let azimuth = f
                    .bounded("azimuth", 4.0, 1024.0)?
                    .map_or(d.azimuth, |x| x as usize);
                f.finish()?;
                Accuracy { radial, azimuth }
            }
        };
        top.finish()?;
        if let (NdfSpec::Inline(n), Transfer::Mirror { .. }) = (&ndf, &transfer) {
            if n.is_singular() {
                return err(format!(
                    "[transfer] kind = \"mirror\" on a {} NDF is a Dirac BRDF with no pointwise \
                     value; use a continuous NDF or a rough `microfacet` transfer",
                    n.kind()
                ));
            }
        }
        Ok(MaterialSpec {
            name,
            ndf,
            transfer,
            diffuse,
            form,
            shadowing,
            accuracy,
        })
    }

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
            && !matches!(self.transfer, Transfer::Lambert { .. })
        {
            return err(
                "[shadowing] interreflection = true needs Lambert facets ([transfer] kind = \
                 \"lambert\"): the estimate of the light between facets assumes they scatter \
                 diffusely",
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
