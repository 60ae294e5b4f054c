//! Reading the material format: [`MaterialSpec::parse`] and the per-table parsers.

use super::{
    err, MaterialError, MaterialSpec, NdfSpec, ShadowingKind, MAX_CONDUCTOR, MAX_DELTAS,
    MAX_EXPONENT, MAX_PHONG_LOBES, MAX_TABLE_CELLS,
};
use crate::convolution::{Accuracy, Form};
use crate::display::Num;
use crate::frame::spherical_direction_deg;
use crate::ndf::{
    Cylinder, DeltaSum, Distribution, Harmonics, Microfacet, Mixture, Ndf, PhongLobe, PhongPeaks,
    Radial, Sphere, Tabulated, VonMisesFisher, WeightedNormal,
};
use crate::transfer::{Fresnel, PhongVariant, Transfer};
use glam::DVec3;
use std::path::Path;

/// A view of one TOML table that remembers which keys were used, to reject unknown ones.
struct Fields<'a> {
    name: String,
    table: &'a toml::Table,
    used: Vec<&'static str>,
}

/// The `weight` of lobe `k` (0-based) of the `name` lobes array: a finite number ≥ 0.
fn lobe_weight(lf: &mut Fields<'_>, name: &str, k: usize) -> Result<f64, MaterialError> {
    let w = lf.req_number("weight")?;
    if !(w.is_finite() && w >= 0.0) {
        return err(format!(
            "{name} lobes[{}] weight: must be a finite number >= 0, got {}",
            k + 1,
            Num(w)
        ));
    }
    Ok(w)
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
                    "; a [texture] table makes a bump- or NDF-mapped material for scene files \
                     (`meso render`, docs/scene-format.md)"
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
    axis_value(&a)
        .map(Some)
        .map_err(|e| MaterialError(format!("{} {key}: {e}", fields.name)))
}

/// The direction an axis' numbers stand for (`[theta_deg, phi_deg]`, or `[x, y, z]` normalised),
/// as [`MaterialSpec::parse`] reads it; the error says what is wrong with the numbers.
pub(super) fn axis_value(a: &[f64]) -> Result<DVec3, String> {
    match a.len() {
        2 => {
            if !(0.0..=180.0).contains(&a[0]) {
                return Err(format!(
                    "theta must be in [0, 180] degrees, got {}",
                    Num(a[0])
                ));
            }
            Ok(spherical_direction_deg(a[0], a[1]))
        }
        3 => {
            let v = DVec3::new(a[0], a[1], a[2]);
            // A vector whose length overflows (components near 1e300) is scaled down by its
            // largest component first; others are normalised as they are.
            let m = v.abs().max_element();
            let v = if v.is_finite() && !v.length().is_finite() {
                v / m
            } else {
                v
            };
            if !(v.is_finite() && v.length() > 1e-12) {
                return Err(format!(
                    "[{}, {}, {}] is not a direction (zero length)",
                    Num(a[0]),
                    Num(a[1]),
                    Num(a[2])
                ));
            }
            Ok(v.normalize())
        }
        n => Err(format!(
            "expected [theta_deg, phi_deg] or [x, y, z], got {n} numbers"
        )),
    }
}

/// The `lobes` array of `f`: a non-empty list of at most `limit` tables (`what` names the lobes
/// in the message), each as [`Fields`] named `… lobes[k]`; `missing` is the message when there
/// is no `lobes` key.
fn lobe_tables<'a>(
    f: &mut Fields<'a>,
    limit: usize,
    what: &str,
    missing: String,
) -> Result<Vec<Fields<'a>>, MaterialError> {
    let name = f.name.clone();
    let Some(v) = f.get("lobes") else {
        return err(missing);
    };
    let Some(arr) = v.as_array() else {
        return err(format!("{name} lobes: expected an array of tables"));
    };
    if arr.is_empty() {
        return err(format!("{name} lobes: the list is empty"));
    }
    if arr.len() > limit {
        return err(format!(
            "{name} lobes: {} {what} is above the limit of {limit}",
            arr.len()
        ));
    }
    arr.iter()
        .enumerate()
        .map(|(k, item)| match item.as_table() {
            Some(t) => Ok(Fields::new(format!("{name} lobes[{}]", k + 1), t)),
            None => err(format!("{name} lobes[{}]: expected a table", k + 1)),
        })
        .collect()
}

fn parse_lobes(
    f: &mut Fields<'_>,
    with_exponent: bool,
) -> Result<Vec<(DVec3, f64, f64)>, MaterialError> {
    let name = f.name.clone();
    let (limit, what) = if with_exponent {
        (MAX_PHONG_LOBES, "phong-peaks lobes")
    } else {
        (MAX_DELTAS, "delta normals")
    };
    let tables = lobe_tables(f, limit, what, format!("{name}: missing `lobes`"))?;
    let mut out = Vec::with_capacity(tables.len());
    for (k, mut lf) in tables.into_iter().enumerate() {
        let ax = axis(&mut lf, "axis")?
            .ok_or_else(|| MaterialError(format!("{name} lobes[{}]: missing `axis`", k + 1)))?;
        let w = lobe_weight(&mut lf, &name, k)?;
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

/// Every `[ndf] kind` the parser accepts, in the order of docs/material-format.md: the inline
/// kinds (each an [`Ndf`] variant, written back by [`MaterialSpec::to_toml`]) and the two
/// external ones (`heightmap`, `map`, kept as [`NdfSpec::External`]).
pub const NDF_KINDS: &[&str] = &[
    "phong-peaks",
    "deltas",
    "sphere",
    "cylinder",
    "vmf",
    "beckmann",
    "ggx",
    "student-t",
    "mixture",
    "harmonics",
    "tabulated",
    "radial",
    "heightmap",
    "map",
];

/// Every `[transfer] kind` the parser accepts.
pub const TRANSFER_KINDS: &[&str] = &["phong", "lambert", "mirror", "microfacet"];

/// Every `fresnel` the parser accepts (for `mirror` and `microfacet` transfers).
pub const FRESNEL_KINDS: &[&str] = &["none", "conductor", "dielectric", "schlick"];

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
        "beckmann" | "ggx" | "student-t" => {
            let dist = match kind {
                "ggx" => Distribution::Ggx,
                "beckmann" => Distribution::Beckmann,
                _ => student_t(&mut f, name)?,
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
            // The angle checks in the file's unit (degrees); `Radial::new` repeats them in
            // radians.
            let bad = |m: String| err(format!("{name}: radial NDF: {m}"));
            if theta.first().is_some_and(|t| *t != 0.0) {
                return bad(format!("the first angle must be 0, got {}°", Num(theta[0])));
            }
            for (k, w) in theta.windows(2).enumerate() {
                if w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater) {
                    return bad(format!(
                        "angles must increase strictly: node {} is {}° after {}°",
                        k + 1,
                        Num(w[1]),
                        Num(w[0])
                    ));
                }
            }
            if let Some(last) = theta.last().filter(|t| **t > 90.0) {
                return bad(format!(
                    "the last angle {}° is past the horizon (90°)",
                    Num(*last)
                ));
            }
            let theta = theta.into_iter().map(f64::to_radians).collect();
            Ndf::Radial(Radial::new(theta, density).map_err(ndf_err)?)
        }
        other => {
            return err(format!(
                "{name} kind: unknown NDF kind \"{other}\" (known: {})",
                NDF_KINDS.join(", ")
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
/// (`alpha_x` and `alpha_y` instead of `alpha` for an anisotropic lobe; `kind = "student-t"`
/// with its `gamma = …`).
fn parse_mixture(f: &mut Fields<'_>) -> Result<Mixture, MaterialError> {
    let name = f.name.clone();
    let tables = lobe_tables(
        f,
        crate::ndf::mixture::MAX_MIXTURE_LOBES,
        "mixture lobes",
        format!(
            "{name}: a mixture needs `lobes = [ {{ kind = \"ggx\", alpha = 0.1, weight = 1 }}, … ]`"
        ),
    )?;
    let mut out = Vec::with_capacity(tables.len());
    for (k, mut lf) in tables.into_iter().enumerate() {
        let dist = match lf.string("kind")? {
            Some("ggx") => Distribution::Ggx,
            Some("beckmann") => Distribution::Beckmann,
            Some("student-t") => student_t(&mut lf, &format!("{name} lobes[{}]", k + 1))?,
            Some(other) => {
                return err(format!(
                    "{name} lobes[{}] kind: unknown lobe kind \"{other}\" (known: ggx, beckmann, \
                     student-t)",
                    k + 1
                ))
            }
            None => return err(format!("{name} lobes[{}]: missing `kind`", k + 1)),
        };
        let (ax, ay) = alphas(&mut lf)?;
        let w = lobe_weight(&mut lf, &name, k)?;
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

/// `gamma = …` of a Student-t distribution (`where` names the table in errors).
fn student_t(f: &mut Fields<'_>, place: &str) -> Result<Distribution, MaterialError> {
    use crate::ndf::student_t::{MAX_GAMMA, MIN_GAMMA};
    let why = "(the area ratio ∫ D dω diverges as gamma → 1.5; 2 is GGX, large values approach \
               Beckmann)";
    match f.number("gamma")? {
        None => err(format!(
            "{place}: a student-t distribution needs `gamma = …` in [{MIN_GAMMA}, {MAX_GAMMA}] {why}"
        )),
        Some(g) if !(g.is_finite() && (MIN_GAMMA..=MAX_GAMMA).contains(&g)) => err(format!(
            "{place} gamma: must be a finite number in [{MIN_GAMMA}, {MAX_GAMMA}] {why}, got {}",
            Num(g)
        )),
        Some(gamma) => Ok(Distribution::StudentT { gamma }),
    }
}

fn alphas(f: &mut Fields<'_>) -> Result<(f64, f64), MaterialError> {
    let lo = crate::ndf::microfacet::MIN_ALPHA;
    let a = f.bounded("alpha", lo, 10.0)?;
    let ax = f.bounded("alpha_x", lo, 10.0)?;
    let ay = f.bounded("alpha_y", lo, 10.0)?;
    match (a, ax, ay) {
        (Some(a), None, None) => Ok((a, a)),
        (None, Some(x), Some(y)) => Ok((x, y)),
        _ => {
            // A key one or two letters off a width's name (`alhpa`, `alpha-x`) is most likely it.
            let near: Vec<String> = f
                .table
                .keys()
                .filter(|k| {
                    !["alpha", "alpha_x", "alpha_y"].contains(&k.as_str())
                        && ["alpha", "alpha_x", "alpha_y"]
                            .iter()
                            .any(|w| edit_distance(k, w) <= 2)
                })
                .map(|k| format!("`{k}`"))
                .collect();
            let hint = if near.is_empty() {
                String::new()
            } else {
                format!(
                    " ({} is not a key here: a misspelt width?)",
                    near.join(", ")
                )
            };
            err(format!(
                "{}: give either `alpha` or both `alpha_x` and `alpha_y`{hint}",
                f.name
            ))
        }
    }
}

/// The edit distance (insertions, deletions, substitutions, and swaps of two neighbours) of
/// two short keys.
fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, v) in d[0].iter_mut().enumerate() {
        *v = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut v = (d[i - 1][j] + 1)
                .min(d[i][j - 1] + 1)
                .min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                v = v.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = v;
        }
    }
    d[a.len()][b.len()]
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
                    if e.iter()
                        .chain(&k)
                        .any(|x| !(0.0..=MAX_CONDUCTOR).contains(x))
                    {
                        return err(format!(
                            "{}: conductor eta and k must be >= 0 and at most {}, got eta = \
                             [{}, {}, {}], k = [{}, {}, {}]",
                            f.name,
                            Num(MAX_CONDUCTOR),
                            Num(e[0]),
                            Num(e[1]),
                            Num(e[2]),
                            Num(k[0]),
                            Num(k[1]),
                            Num(k[2])
                        ));
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
                "{} fresnel: unknown \"{other}\" (known: {})",
                f.name,
                FRESNEL_KINDS.join(", ")
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
                "student-t" => student_t(&mut f, "[transfer]")?,
                other => {
                    return err(format!(
                        "[transfer] distribution: unknown \"{other}\" (known: beckmann, ggx, \
                         student-t)"
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
                "[transfer] kind: unknown \"{other}\" (known: {})",
                TRANSFER_KINDS.join(", ")
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
        MaterialSpec::from_table(&doc, dir)
    }

    /// [`MaterialSpec::parse`] of a document already read as a TOML table (e.g. built from
    /// another language's values): the same validation, the same messages.
    ///
    /// # Errors
    /// A [`MaterialError`] naming the table, the key and the problem.
    pub fn from_table(doc: &toml::Table, dir: &Path) -> Result<MaterialSpec, MaterialError> {
        let mut top = Fields::new("material", doc);
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
}
