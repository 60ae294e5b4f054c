//! Writing the material format: [`MaterialSpec::to_toml`] and [`Material::to_spec`].
//!
//! The text reads back to the same value exactly: `MaterialSpec::parse(&s.to_toml(), dir) ==
//! Ok(s)` (tests/material_write.rs). Numbers are written in Rust's shortest round-trip form
//! (`{:?}`). Where the parser transforms what it reads — weights rescaled to sum to 1, densities
//! rescaled to Eq. 1, axes normalised, node angles converted from degrees — the writer writes
//! numbers the parser turns into exactly the stored values, found by a short search checked
//! against the parser's own arithmetic:
//! * an axis as `[theta_deg, phi_deg]` when a pair of degrees reads back to it (the shortest
//!   such pair, so an axis read from `[30, 90]` is written `[30.0, 90.0]`), otherwise as the
//!   vector `[x, y, z]`;
//! * weights and densities scaled by a factor within a few ulps of 1 such that the parser's
//!   rescaling gives back the stored numbers (usually the factor 1: the stored numbers
//!   themselves);
//! * radial node angles as the shortest degrees that convert back to the stored radians.
//!
//! Where no such numbers exist the writer writes the nearest ones and the value reads back
//! within the last digits. The parser and the NDF constructors both rescale, so this happens:
//! * for weights whose floating-point sum is not exactly 1 and densities whose computed
//!   normalisation is not exactly 1 (in tests/material_write.rs, of 200 random NDFs each, exact:
//!   phong-peaks and deltas 99 %, mixtures 96 %, tabulated 92 %, harmonics 100 %, radial 5 % —
//!   its mass is computed to about 1e-14 — the rest within 1e-15 relative, radial 1e-9);
//! * for an axis given as a vector whose computed length is not exactly 1 (about 1 in 5 random
//!   unit vectors; within an ulp), and a radial node at radians no f64 number of degrees
//!   gives (values not read from a file).
//!
//! An NDF that its constructor leaves as it is (weights summing to exactly 1, axes from degrees
//! or of length exactly 1, …) reads back exactly, and so does every other part of a material.
//! Making the NDF constructors' rescaling idempotent (keep numbers already normalised to within
//! rounding) would make every NDF exact.

use super::parse::axis_value;
use super::{Material, MaterialError, MaterialSpec, NdfSpec, ShadowingKind};
use crate::convolution::{Accuracy, Form};
use crate::frame::deg_to_rad;
use crate::ndf::{
    Cylinder, Distribution, Microfacet, Ndf, PhongLobe, PhongPeaks, Radial, Tabulated,
    VonMisesFisher,
};
use crate::transfer::{Fresnel, PhongVariant, Transfer};
use glam::DVec3;
use std::fmt::Write;

/// Arrays longer than this are written over several lines, this many numbers a line.
const NUMBERS_PER_LINE: usize = 8;

impl MaterialSpec {
    /// The material file of this spec (docs/material-format.md): the top keys (`name`, `form`),
    /// then `[ndf]` (lobes one inline table per line), `[transfer]`, `[shadowing]`, `[diffuse]`
    /// (when not black) and `[quadrature]` (when not the default). Reading it back with
    /// [`MaterialSpec::parse`] gives this spec exactly (module docs of `material::write` for the
    /// one last-digit limit). An external NDF (`heightmap`, `map`) is written as its table, `file`
    /// as it was written (relative to the folder the spec was read from).
    #[must_use]
    pub fn to_toml(&self) -> String {
        self.to_toml_with_comment("")
    }

    /// [`MaterialSpec::to_toml`] with `comment`'s lines first, each as a `# ` comment line (e.g.
    /// the command line that re-runs a fit).
    #[must_use]
    pub fn to_toml_with_comment(&self, comment: &str) -> String {
        let mut s = String::new();
        for l in comment.lines() {
            let _ = writeln!(s, "# {l}");
        }
        let mut top = false;
        if let Some(n) = &self.name {
            let _ = writeln!(s, "name = {}", basic_string(n));
            top = true;
        }
        if let Some(f) = self.form {
            let _ = writeln!(s, "form = \"{}\"", form_name(f));
            top = true;
        }
        if top {
            s.push('\n');
        }
        s.push_str("[ndf]\n");
        match &self.ndf {
            NdfSpec::Inline(n) => write_ndf(&mut s, n),
            NdfSpec::External { table, .. } => {
                // `kind` first, then the other keys as the table holds them.
                let first = table.iter().filter(|(k, _)| *k == "kind");
                for (k, v) in first.chain(table.iter().filter(|(k, _)| *k != "kind")) {
                    let _ = writeln!(s, "{} = {v}", toml_key(k));
                }
            }
        }
        s.push_str("\n[transfer]\n");
        write_transfer(&mut s, &self.transfer);
        if let Some(k) = self.shadowing {
            let (kind, inter) = match k {
                ShadowingKind::None => ("none", false),
                ShadowingKind::Smith => ("smith", false),
                ShadowingKind::Horizon => ("horizon", false),
                ShadowingKind::Visibility => ("visibility", false),
                ShadowingKind::VisibilityInterreflected => ("visibility", true),
            };
            let _ = writeln!(s, "\n[shadowing]\nkind = \"{kind}\"");
            if inter {
                s.push_str("interreflection = true\n");
            }
        }
        if self.diffuse != [0.0; 3] {
            let _ = writeln!(s, "\n[diffuse]\nalbedo = {}", list(&self.diffuse));
        }
        if self.accuracy != Accuracy::default() {
            let _ = writeln!(
                s,
                "\n[quadrature]\nradial = {}\nazimuth = {}",
                self.accuracy.radial, self.accuracy.azimuth
            );
        }
        s
    }
}

impl Material {
    /// The spec of this material, with its NDF inline and its form and masking choice explicit,
    /// so that [`MaterialSpec::to_toml`] writes a file that builds this material again.
    ///
    /// # Errors
    /// Masking that needs the height map itself (`horizon`, `visibility`): the resolved NDF of a
    /// height map can be written inline, its visibility model cannot.
    pub fn to_spec(&self) -> Result<MaterialSpec, MaterialError> {
        if matches!(
            self.shadowing,
            ShadowingKind::Horizon
                | ShadowingKind::Visibility
                | ShadowingKind::VisibilityInterreflected
        ) {
            return Err(MaterialError(format!(
                "the material's masking ({:?}) needs its height map; write the [ndf] table \
                 that refers to the height map instead",
                self.shadowing
            )));
        }
        Ok(MaterialSpec {
            name: self.name.clone(),
            ndf: NdfSpec::Inline(self.ndf.clone()),
            transfer: self.transfer,
            diffuse: self.diffuse,
            form: Some(self.form),
            shadowing: Some(self.shadowing),
            accuracy: self.accuracy,
        })
    }
}

fn form_name(f: Form) -> &'static str {
    match f {
        Form::MultipleSurface => "multiple-surface",
        Form::Microfacet => "microfacet",
    }
}

/// A TOML basic string (double quotes, escapes) of `text`.
fn basic_string(text: &str) -> String {
    let mut out = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04X}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A bare key when TOML allows one, else a quoted key.
fn toml_key(k: &str) -> String {
    if !k.is_empty()
        && k.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        k.to_owned()
    } else {
        basic_string(k)
    }
}

/// A number in its shortest round-trip form (`30.0`, `0.1`, `1e-5`): valid TOML, read back to
/// the same f64.
fn num(x: f64) -> String {
    format!("{x:?}")
}

/// `[a, b, c]` on one line.
fn list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| num(*x)).collect();
    format!("[{}]", items.join(", "))
}

/// `key = [...]`, over several lines when long.
fn write_array(s: &mut String, key: &str, v: &[f64]) {
    if v.len() <= NUMBERS_PER_LINE {
        let _ = writeln!(s, "{key} = {}", list(v));
        return;
    }
    let _ = writeln!(s, "{key} = [");
    for chunk in v.chunks(NUMBERS_PER_LINE) {
        let items: Vec<String> = chunk.iter().map(|x| num(*x)).collect();
        let _ = writeln!(s, "  {},", items.join(", "));
    }
    s.push_str("]\n");
}

/// `alpha = a` or `alpha_x = a, alpha_y = b` (without the separator before), preceded by
/// `gamma = g` and the separator for a Student t.
fn alphas(m: &Microfacet, sep: &str) -> String {
    let gamma = match m.distribution {
        Distribution::StudentT { gamma } => format!("gamma = {}{sep}", num(gamma)),
        _ => String::new(),
    };
    if m.alpha_x == m.alpha_y {
        format!("{gamma}alpha = {}", num(m.alpha_x))
    } else {
        format!(
            "{gamma}alpha_x = {}{sep}alpha_y = {}",
            num(m.alpha_x),
            num(m.alpha_y)
        )
    }
}

fn distribution_name(d: Distribution) -> &'static str {
    d.name()
}

fn write_ndf(s: &mut String, ndf: &Ndf) {
    let _ = writeln!(s, "kind = \"{}\"", ndf.kind());
    match ndf {
        Ndf::PhongPeaks(p) => {
            let lobes = p.lobes();
            let w = weights(&lobes.iter().map(|l| l.weight).collect::<Vec<_>>());
            // What the parser does with an axis: PhongPeaks::new(PhongLobe::new(axis, …)).
            let stored = |v: DVec3| {
                PhongPeaks::new(vec![PhongLobe::new(v, 1.0, 0.0)])
                    .ok()
                    .map(|p| p.lobes()[0].axis)
            };
            s.push_str("lobes = [\n");
            for (l, w) in lobes.iter().zip(w) {
                let _ = writeln!(
                    s,
                    "  {{ axis = {}, weight = {}, exponent = {} }},",
                    list(&axis_numbers(l.axis, &stored)),
                    num(w),
                    num(l.exponent)
                );
            }
            s.push_str("]\n");
        }
        Ndf::Deltas(d) => {
            let normals = d.normals();
            let w = weights(&normals.iter().map(|n| n.weight).collect::<Vec<_>>());
            // DeltaSum::new divides each normal by its length (its own constructor per axis
            // would build a cap index each time: 100k normals would take a minute).
            let stored = |v: DVec3| Some(v / v.length());
            s.push_str("lobes = [\n");
            for (n, w) in normals.iter().zip(w) {
                let _ = writeln!(
                    s,
                    "  {{ axis = {}, weight = {} }},",
                    list(&axis_numbers(n.normal, &stored)),
                    num(w)
                );
            }
            s.push_str("]\n");
        }
        Ndf::Sphere(_) => {}
        Ndf::Cylinder(c) => {
            let stored = |v: DVec3| Cylinder::new(v, c.half).ok().map(|c| c.axis);
            let _ = writeln!(s, "axis = {}", list(&axis_numbers(c.axis, &stored)));
            if c.half {
                s.push_str("half = true\n");
            }
        }
        Ndf::VonMisesFisher(v) => {
            let stored = |a: DVec3| VonMisesFisher::new(a, v.kappa).ok().map(|v| v.mu);
            let _ = writeln!(s, "axis = {}", list(&axis_numbers(v.mu, &stored)));
            let _ = writeln!(s, "kappa = {}", num(v.kappa));
        }
        Ndf::Microfacet(m) => {
            let _ = writeln!(s, "{}", alphas(m, "\n"));
        }
        Ndf::Mixture(m) => {
            let lobes = m.lobes();
            let w = weights(&lobes.iter().map(|l| l.weight).collect::<Vec<_>>());
            s.push_str("lobes = [\n");
            for (l, w) in lobes.iter().zip(w) {
                let _ = writeln!(
                    s,
                    "  {{ kind = \"{}\", {}, weight = {} }},",
                    distribution_name(l.microfacet.distribution),
                    alphas(&l.microfacet, ", "),
                    num(w)
                );
            }
            s.push_str("]\n");
        }
        Ndf::Harmonics(h) => {
            let c = h.coeffs();
            // Harmonics::from_coeffs multiplies every coefficient by 1/(2√π c₀₀).
            let back = |v: &[f64]| {
                let scale = 1.0 / (2.0 * std::f64::consts::PI.sqrt() * v[0]);
                v.iter().zip(c).all(|(x, y)| x * scale == *y)
            };
            let _ = writeln!(s, "band = {}", h.lmax());
            let v = prescaled(c, Scaling::Multiply, TRIES, back);
            write_array(s, "coefficients", &v);
        }
        Ndf::Tabulated(t) => {
            let g = t.grid();
            let back = |v: &[f64]| {
                Tabulated::from_values(g, v.to_vec()).is_ok_and(|b| b.values() == t.values())
            };
            let _ = writeln!(s, "n_z = {}\nn_phi = {}", g.n_z, g.n_phi);
            let v = prescaled(t.values(), Scaling::Multiply, TRIES, back);
            write_array(s, "values", &v);
        }
        Ndf::Radial(r) => {
            let deg: Vec<f64> = r.theta().iter().map(|t| degrees_of(*t)).collect();
            let theta: Vec<f64> = deg.iter().map(|d| d.to_radians()).collect();
            let back = |v: &[f64]| {
                Radial::new(theta.clone(), v.to_vec()).is_ok_and(|b| b.values() == r.values())
            };
            write_array(s, "theta", &deg);
            let v = prescaled(r.values(), Scaling::Divide, TRIES, back);
            write_array(s, "density", &v);
        }
    }
}

fn write_transfer(s: &mut String, t: &Transfer) {
    match t {
        Transfer::Phong {
            exponent,
            specular,
            variant,
        } => {
            let _ = writeln!(
                s,
                "kind = \"phong\"\nexponent = {}\nspecular = {}",
                num(*exponent),
                list(specular)
            );
            if *variant == PhongVariant::Reflect {
                s.push_str("variant = \"reflect\"\n");
            }
        }
        Transfer::Lambert { albedo } => {
            let _ = writeln!(s, "kind = \"lambert\"\nalbedo = {}", list(albedo));
        }
        Transfer::Mirror { fresnel, specular } => {
            s.push_str("kind = \"mirror\"\n");
            write_fresnel(s, fresnel);
            let _ = writeln!(s, "specular = {}", list(specular));
        }
        Transfer::Microfacet {
            distribution,
            fresnel,
        } => {
            let _ = writeln!(
                s,
                "kind = \"microfacet\"\ndistribution = \"{}\"\n{}",
                distribution_name(distribution.distribution),
                alphas(distribution, "\n")
            );
            write_fresnel(s, fresnel);
        }
    }
}

fn write_fresnel(s: &mut String, f: &Fresnel) {
    match f {
        Fresnel::None => {}
        Fresnel::Dielectric { eta } => {
            let _ = writeln!(s, "fresnel = \"dielectric\"\neta = {}", num(*eta));
        }
        Fresnel::Conductor { eta, k } => {
            let _ = writeln!(
                s,
                "fresnel = \"conductor\"\neta = {}\nk = {}",
                list(eta),
                list(k)
            );
        }
        Fresnel::Schlick { f0 } => {
            let _ = writeln!(s, "fresnel = \"schlick\"\nf0 = {}", list(f0));
        }
    }
}

/// How the parser rescales a list of numbers by a factor `c` computed from them.
#[derive(Clone, Copy)]
enum Scaling {
    /// `x / c` (lobe weights, radial densities).
    Divide,
    /// `x · c` (tabulated values, harmonics coefficients).
    Multiply,
}

/// The lobe weights to write so that the NDF constructors' rescaling (sum, then divide by the
/// sum) gives `w` exactly.
fn weights(w: &[f64]) -> Vec<f64> {
    prescaled(w, Scaling::Divide, TRIES, |v| {
        let total: f64 = v.iter().sum();
        v.iter().zip(w).all(|(x, y)| x / total == *y)
    })
}

/// Factors tried by [`prescaled`] on each side of 1 (a radial NDF's mass is computed with a
/// relative error near 1e-14, about 50 ulps, hence the range) …
const TRIES: u32 = 400;
/// … but at most this many numbers rescaled in all, so that long lists (100k delta weights,
/// where a hit is rare anyway) stay quick to write.
const MAX_WORK: usize = 400_000;

/// Numbers `v` that read back as `w` (`reads_back(v)`: the parser's rescaling of a list by a
/// factor it computes from the list, `scaling`, gives `w`), `w` being already rescaled (its
/// factor is close to 1). Tries `w` itself, then `w` scaled by `tries` factors (fewer for long
/// lists, [`MAX_WORK`]) on each side of 1, an ulp apart, each number nudged to the neighbour
/// that the rescaling maps back onto its target. Returns `w` itself when no candidate reads back exactly (then the rescaled list
/// differs from `w` in the last digits).
fn prescaled(
    w: &[f64],
    scaling: Scaling,
    tries: u32,
    reads_back: impl Fn(&[f64]) -> bool,
) -> Vec<f64> {
    if reads_back(w) {
        return w.to_vec();
    }
    let eps = f64::EPSILON;
    let tries = tries.min(u32::try_from(MAX_WORK / w.len().max(1)).unwrap_or(u32::MAX));
    for k in 1..=tries {
        for c in [1.0 + f64::from(k) * eps, 1.0 - f64::from(k) * eps / 2.0] {
            let v: Vec<f64> = w.iter().map(|&x| preimage(x, c, scaling)).collect();
            if reads_back(&v) {
                return v;
            }
        }
    }
    w.to_vec()
}

/// The float nearest `x` (scaled by `c`) that the rescaling by `c` maps exactly to `x`, or the
/// plain scaled value when none of its close neighbours does.
fn preimage(x: f64, c: f64, scaling: Scaling) -> f64 {
    let (guess, forward): (f64, fn(f64, f64) -> f64) = match scaling {
        Scaling::Divide => (x * c, |y, c| y / c),
        Scaling::Multiply => (x / c, |y, c| y * c),
    };
    let mut cands = [guess; 5];
    cands[1] = guess.next_up();
    cands[2] = guess.next_down();
    cands[3] = cands[1].next_up();
    cands[4] = cands[2].next_down();
    cands
        .into_iter()
        .find(|&y| forward(y, c) == x)
        .unwrap_or(guess)
}

/// `x` and its four neighbours on each side.
fn neighbours(x: f64) -> Vec<f64> {
    let (mut up, mut down) = (x, x);
    let mut c = vec![x];
    for _ in 0..4 {
        (up, down) = (up.next_up(), down.next_down());
        c.extend([up, down]);
    }
    c
}

/// `x` rounded to 1, 2, … 17 significant digits, shortest first, duplicates removed.
fn roundings(x: f64) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(17);
    for d in 0..17 {
        if let Ok(v) = format!("{x:.d$e}").parse::<f64>() {
            if v.is_finite() && !out.contains(&v) {
                out.push(v);
            }
        }
    }
    out
}

/// The degrees to write for a radial node at `theta` radians: the shortest number whose
/// `to_radians` (what the parser does) is `theta`, else the nearest.
fn degrees_of(theta: f64) -> f64 {
    let d = theta.to_degrees();
    let mut c = roundings(d);
    c.extend(neighbours(d));
    c.into_iter().find(|c| c.to_radians() == theta).unwrap_or(d)
}

/// The numbers to write for an axis stored as `a == stored(axis_value(numbers))`:
/// `[theta_deg, phi_deg]` when a pair reads back exactly (the shortest such pair), else the
/// vector `[x, y, z]`. The pairs tried first are the full-precision angles of `a` and their close
/// neighbours (φ also a turn either way, as a file may say −30 or 330); only when one of them
/// reads back are shorter roundings tried, so an axis that no degrees give costs little.
fn axis_numbers(a: DVec3, stored: &dyn Fn(DVec3) -> Option<DVec3>) -> Vec<f64> {
    let reads_back = |n: &[f64]| axis_value(n).ok().and_then(stored) == Some(a);
    // θ and φ from atan2 (well conditioned everywhere, unlike acos), φ in (-180, 180].
    let td = a.x.hypot(a.y).atan2(a.z).to_degrees();
    let pd = a.y.atan2(a.x).to_degrees();
    // φ in [0, 360) first, the way files usually give it.
    let turns = if pd < 0.0 {
        [360.0, 0.0, 720.0, -360.0]
    } else {
        [0.0, 360.0, -360.0, 720.0]
    };
    // The sines and cosines `spherical_direction_deg` takes, to skip at little cost the pairs
    // whose direction is not within a few ulps of `a` (normalising moves it by about one).
    let trig = |d: f64| {
        let (s, c) = deg_to_rad(d).sin_cos();
        (d, s, c)
    };
    let close = |x: f64, y: f64| (x - y).abs() <= 4.0 * f64::EPSILON;
    let thetas = |c: Vec<f64>| -> Vec<(f64, f64, f64)> {
        c.into_iter()
            .filter(|t| (0.0..=180.0).contains(t))
            .map(trig)
            .filter(|t| close(t.2, a.z))
            .collect()
    };
    let phis = |c: &dyn Fn(f64) -> Vec<f64>| -> Vec<(f64, f64, f64)> {
        let mut v = vec![trig(0.0)];
        v.extend(turns.iter().flat_map(|t| c(pd + t)).map(trig));
        v
    };
    let pairs = |ts: &[(f64, f64, f64)], ps: &[(f64, f64, f64)]| -> Vec<[f64; 2]> {
        let mut out = Vec::new();
        for &(th, st, _) in ts {
            for &(ph, sp, cp) in ps {
                if close(st * cp, a.x) && close(st * sp, a.y) {
                    out.push([th, ph]);
                }
            }
        }
        out
    };
    let found = pairs(&thetas(neighbours(td)), &phis(&neighbours))
        .into_iter()
        .find(|p| reads_back(p));
    let Some(mut best) = found else {
        return a.to_array().to_vec();
    };
    let len = |p: &[f64; 2]| num(p[0]).len() + num(p[1]).len();
    if len(&best) <= 10 {
        return best.to_vec(); // already short, e.g. [0.0, 0.0] or [30.0, 90.0]
    }
    for pair in pairs(&thetas(roundings(td)), &phis(&roundings)) {
        if len(&pair) < len(&best) && reads_back(&pair) {
            best = pair;
        }
    }
    best.to_vec()
}
