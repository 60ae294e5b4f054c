//! The JSON form of a material and its conversion to and from the TOML material format.
//!
//! The JSON schema mirrors the TOML format of `docs/material-format.md` key for key: a material
//! is an object with `name`, `form`, `ndf`, `transfer`, `diffuse`, `shadowing`, `quadrature`;
//! tables are objects, arrays are arrays. Every material that enters the server is converted to
//! TOML and validated by `meso_core` ([`Material::from_toml_str`]), so the server accepts exactly
//! what `meso brdf` and `meso render` accept from a file, minus NDFs that live in other files
//! (`heightmap`, `map`), which a server must not read.
//!
//! [`emit_toml`] writes a table the way a person would: top-level keys first, then one
//! `[section]` per table, lobes as one inline table per line.
//!
//! It transcribes the user's own document key for key (the reverse of [`parse_toml`]); it is
//! not a second material writer. meso-core's writer ([`MaterialSpec::to_toml`]) writes a
//! material *value* as the parser stores it: weights and densities normalised, every default
//! explicit (tried for Save, 2026-12-03: lobe weights 3 and 1 were saved as 0.75 and 0.25, a
//! radial density table rescaled, the mirror's default `specular` added, so the material came
//! back from Open… with other numbers than the user typed, which the browser test "the saved
//! TOML holds the new values" checks). The editor saves what the user typed, and every text it
//! saves is validated by that parser first.

use crate::error::ApiError;
use meso_core::material::{Material, MaterialSpec};
use serde_json::{Map, Number, Value};

/// Most lobes (or normals) a material may have through the API.
pub const MAX_LOBES: usize = 256;

/// JSON → TOML value. `null` has no TOML form and is refused, naming the key.
///
/// # Errors
/// A 400 [`ApiError`] naming the path of the offending value.
pub fn json_to_toml(v: &Value, path: &str) -> Result<toml::Value, ApiError> {
    Ok(match v {
        Value::Null => {
            return Err(ApiError::bad_request(format!(
                "{path}: null is not allowed (leave the key out instead)"
            )))
        }
        Value::Bool(b) => toml::Value::Boolean(*b),
        Value::Number(n) => {
            if let Some(i) = n.as_i64() {
                toml::Value::Integer(i)
            } else if let Some(f) = n.as_f64() {
                toml::Value::Float(f)
            } else {
                return Err(ApiError::bad_request(format!(
                    "{path}: {n} is not representable"
                )));
            }
        }
        Value::String(s) => toml::Value::String(s.clone()),
        Value::Array(a) => toml::Value::Array(
            a.iter()
                .enumerate()
                .map(|(k, x)| json_to_toml(x, &format!("{path}[{k}]")))
                .collect::<Result<_, _>>()?,
        ),
        Value::Object(o) => {
            let mut t = toml::Table::new();
            for (k, x) in o {
                t.insert(k.clone(), json_to_toml(x, &format!("{path}.{k}"))?);
            }
            toml::Value::Table(t)
        }
    })
}

/// TOML → JSON value (datetimes become strings; non-finite floats become `null`).
#[must_use]
pub fn toml_to_json(v: &toml::Value) -> Value {
    match v {
        toml::Value::String(s) => Value::String(s.clone()),
        toml::Value::Integer(i) => Value::Number((*i).into()),
        toml::Value::Float(f) => Number::from_f64(*f).map_or(Value::Null, Value::Number),
        toml::Value::Boolean(b) => Value::Bool(*b),
        toml::Value::Datetime(d) => Value::String(d.to_string()),
        toml::Value::Array(a) => Value::Array(a.iter().map(toml_to_json).collect()),
        toml::Value::Table(t) => Value::Object(
            t.iter()
                .map(|(k, x)| (k.clone(), toml_to_json(x)))
                .collect::<Map<_, _>>(),
        ),
    }
}

fn key(k: &str) -> String {
    if !k.is_empty()
        && k.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        k.to_owned()
    } else {
        toml::Value::String(k.to_owned()).to_string()
    }
}

/// The order in which keys are written: the order of `docs/material-format.md`, then the rest
/// alphabetically (`toml::Table` and `serde_json::Map` iterate alphabetically).
const KEY_ORDER: &[&str] = &[
    "name",
    "form",
    "kind",
    "axis",
    "weight",
    "exponent",
    "lobes",
    "distribution",
    "variant",
    "alpha",
    "alpha_x",
    "alpha_y",
    "kappa",
    "half",
    "band",
    "specular",
    "albedo",
    "fresnel",
    "eta",
    "k",
    "f0",
    "ndf",
    "transfer",
    "diffuse",
    "shadowing",
    "quadrature",
    "radial",
    "azimuth",
];

fn ordered(t: &toml::Table) -> Vec<(&String, &toml::Value)> {
    let rank = |k: &str| {
        KEY_ORDER
            .iter()
            .position(|x| *x == k)
            .unwrap_or(KEY_ORDER.len())
    };
    let mut v: Vec<_> = t.iter().collect();
    v.sort_by(|a, b| rank(a.0).cmp(&rank(b.0)).then_with(|| a.0.cmp(b.0)));
    v
}

/// A value on one line (tables inline).
fn inline(v: &toml::Value) -> String {
    match v {
        toml::Value::Float(f) if f.fract() == 0.0 && f.abs() < 1e15 => format!("{f:.1}"),
        toml::Value::Array(a) => {
            let items: Vec<String> = a.iter().map(inline).collect();
            format!("[{}]", items.join(", "))
        }
        toml::Value::Table(t) => {
            if t.is_empty() {
                return "{}".into();
            }
            let items: Vec<String> = ordered(t)
                .into_iter()
                .map(|(k, x)| format!("{} = {}", key(k), inline(x)))
                .collect();
            format!("{{ {} }}", items.join(", "))
        }
        other => other.to_string(),
    }
}

/// A `key = value` line; arrays of tables get one table per line.
fn entry(out: &mut String, k: &str, v: &toml::Value) {
    match v {
        toml::Value::Array(a) if !a.is_empty() && a.iter().all(toml::Value::is_table) => {
            out.push_str(&format!("{} = [\n", key(k)));
            for x in a {
                out.push_str(&format!("  {},\n", inline(x)));
            }
            out.push_str("]\n");
        }
        _ => out.push_str(&format!("{} = {}\n", key(k), inline(v))),
    }
}

/// Write a material table as readable TOML (see the module docs).
#[must_use]
pub fn emit_toml(t: &toml::Table) -> String {
    let mut out = String::new();
    for (k, v) in ordered(t) {
        if !v.is_table() {
            entry(&mut out, k, v);
        }
    }
    for (k, v) in ordered(t) {
        if let toml::Value::Table(sub) = v {
            if !out.is_empty() {
                out.push('\n');
            }
            out.push_str(&format!("[{}]\n", key(k)));
            for (sk, sv) in ordered(sub) {
                entry(&mut out, sk, sv);
            }
        }
    }
    out
}

/// A material validated from JSON: the meso-core material and its TOML text.
#[derive(Debug, Clone)]
pub struct Validated {
    /// The material, ready to evaluate.
    pub material: Material,
    /// The material as TOML (what `POST /api/toml` answers).
    pub toml: String,
}

/// Validate a JSON material (see the module docs) and convert it to TOML. NDFs that live in
/// files (`heightmap`, `map`) are refused: see [`validate_with`] for open textures.
///
/// # Errors
/// 400 with the message of meso-core's validation, or of the JSON shape.
pub fn validate(v: &Value) -> Result<Validated, ApiError> {
    validate_with(v, None)
}

/// The keys of a JSON NDF naming a texel of an open texture (`crate::textures`).
const TEXTURE_NDF_KEYS: [&str; 5] = ["kind", "texture", "level", "texel", "file"];

/// [`validate`], with the open `textures`: an NDF `{"kind": "map", "texture": "<id>", "level":
/// k | "top", "texel": [row, col]}` is the NDF of that texel (as `[ndf] kind = "map"` resolves a
/// map file's), and the TOML names the texture's map file (`crate::textures::Texture::
/// map_file_name`) instead of the id.
///
/// # Errors
/// 400 as for [`validate`]; 404 for a texture that is not open.
pub fn validate_with(
    v: &Value,
    textures: Option<&crate::textures::TextureStore>,
) -> Result<Validated, ApiError> {
    let Value::Object(_) = v else {
        return Err(ApiError::bad_request(
            "material: expected a JSON object mirroring the TOML material format",
        ));
    };
    let lobes = v
        .pointer("/ndf/lobes")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    if lobes > MAX_LOBES {
        return Err(ApiError::bad_request(format!(
            "material.ndf.lobes: {lobes} lobes is above the server's limit of {MAX_LOBES}"
        )));
    }
    let mut texture = None;
    if let Some(k) = v.pointer("/ndf/kind").and_then(Value::as_str) {
        if k == "heightmap" || k == "map" {
            let id = v.pointer("/ndf/texture");
            let (Some(store), Some(id)) = (textures, id) else {
                return Err(ApiError::bad_request(format!(
                    "material.ndf.kind: \"{k}\" NDFs live in files, which the server does not \
                     read: open the texture in the editor (POST /api/texture uploads it) and name \
                     a texel of it with {{\"kind\": \"map\", \"texture\": \"<id>\", \"level\": k, \
                     \"texel\": [row, col]}}, or use an inline NDF"
                )));
            };
            if k != "map" {
                return Err(ApiError::bad_request(
                    "material.ndf.kind: an open texture is named by kind = \"map\" (with \
                     `texture`, `level` and `texel`)",
                ));
            }
            if let Some(Value::Object(o)) = v.get("ndf") {
                if let Some(bad) = o.keys().find(|x| !TEXTURE_NDF_KEYS.contains(&x.as_str())) {
                    return Err(ApiError::bad_request(format!(
                        "material.ndf.{bad}: unknown key for a texture texel (known: {})",
                        TEXTURE_NDF_KEYS.join(", ")
                    )));
                }
            }
            let id = id
                .as_str()
                .ok_or_else(|| ApiError::bad_request("material.ndf.texture: expected an id"))?;
            texture = Some(store.require(id)?);
        }
    }
    let mut v = v.clone();
    if let (Some(t), Some(Value::Object(ndf))) = (&texture, v.get_mut("ndf")) {
        ndf.remove("texture");
        ndf.insert("file".into(), Value::from(t.map_file_name()));
    }
    let toml::Value::Table(t) = json_to_toml(&v, "material")? else {
        unreachable!("an object converts to a table")
    };
    let text = emit_toml(&t);
    let material = match &texture {
        None => Material::from_toml_str(&text),
        Some(t) => MaterialSpec::parse(&text, std::path::Path::new(""))
            .and_then(|s| s.build(&crate::textures::TexelResolver { texture: t })),
    }
    .map_err(|e| ApiError::bad_request(format!("material: {}", e.0)))?;
    Ok(Validated {
        material,
        toml: text,
    })
}

/// Parse and validate TOML material text into its JSON form. Lobe axes given as vectors are
/// rewritten as `[theta_deg, phi_deg]` (rounded to 1e-6 degrees) so that editors see one form.
///
/// # Errors
/// 400 with meso-core's message (syntax, unknown keys, out-of-range values, …).
pub fn parse_toml(text: &str) -> Result<Value, ApiError> {
    if text.len() as u64 > meso_core::material::MAX_MATERIAL_BYTES {
        return Err(ApiError::too_large("material TOML above 1 MiB"));
    }
    let spec = MaterialSpec::parse(text, std::path::Path::new(""))
        .map_err(|e| ApiError::bad_request(e.0))?;
    match &spec.ndf {
        // An NDF in another file: its table is checked here, the file itself is the browser's
        // to send (POST /api/texture); the editor asks for it.
        meso_core::material::NdfSpec::External { kind, table, .. } => {
            check_external(kind, table).map_err(|e| ApiError::bad_request(e.0))?;
        }
        meso_core::material::NdfSpec::Inline(_) => {
            spec.build(&meso_core::material::NoExternalNdfs)
                .map_err(|e| ApiError::bad_request(e.0))?;
        }
    }
    let table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| ApiError::bad_request(e.message().to_owned()))?;
    let mut json = toml_to_json(&toml::Value::Table(table));
    if let Some(Value::Array(lobes)) = json.pointer_mut("/ndf/lobes") {
        for l in lobes.iter_mut() {
            if let Some(Value::Array(a)) = l.get_mut("axis") {
                if a.len() == 3 {
                    let f: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
                    if f.len() == 3 {
                        let d = glam::DVec3::new(f[0], f[1], f[2]).normalize();
                        let (t, p) = meso_core::frame::spherical_angles(d);
                        let r = |x: f64| (x.to_degrees() * 1e6).round() / 1e6;
                        let mut p = r(p);
                        if p < 0.0 {
                            p += 360.0;
                        }
                        *a = vec![Value::from(r(t)), Value::from(p)];
                    }
                }
            }
        }
    }
    Ok(json)
}

/// Check the `[ndf]` table of a `heightmap` or `map` material as meso-maps reads it (keys and
/// values), without its file.
fn check_external(
    kind: &str,
    table: &toml::Table,
) -> Result<(), meso_core::material::MaterialError> {
    use meso_core::material::MaterialError;
    match kind {
        "heightmap" => meso_maps::resolver::MapsResolver::heightmap_params(table).map(|_| ()),
        _ => {
            if let Some(k) = table
                .keys()
                .find(|k| !["kind", "file", "level", "texel"].contains(&k.as_str()))
            {
                return Err(MaterialError(format!(
                    "[ndf]: unknown key `{k}` (known here: kind, file, level, texel)"
                )));
            }
            match table.get("level") {
                None | Some(toml::Value::Integer(0..)) => {}
                Some(toml::Value::String(s)) if s == "top" => {}
                Some(v) => {
                    return Err(MaterialError(format!(
                        "[ndf] level: expected \"top\" or a level number, got {v}"
                    )))
                }
            }
            match table.get("texel") {
                None => Ok(()),
                Some(toml::Value::Array(a))
                    if a.len() == 2 && a.iter().all(|x| matches!(x, toml::Value::Integer(0..))) =>
                {
                    Ok(())
                }
                Some(v) => Err(MaterialError(format!(
                    "[ndf] texel: expected [row, col], got {v}"
                ))),
            }
        }
    }
}

/// Blend two materials' NDFs: the lobes of `a` with weights scaled by `1 − t` and those of `b`
/// scaled by `t` (each set first normalised to sum 1), as one lobe list. Everything else comes
/// from `a` for `t < 0.5` and from `b` otherwise, except the diffuse albedo, which is mixed.
/// When one NDF is `phong-peaks` and the other `deltas`, the normals become Phong peaks of
/// exponent [`DELTA_AS_PEAK_EXPONENT`].
///
/// # Errors
/// 400 when a material has no `ndf.lobes` or `t ∉ [0, 1]`.
pub fn blend(a: &Value, b: &Value, t: f64) -> Result<Value, ApiError> {
    if !(0.0..=1.0).contains(&t) {
        return Err(ApiError::bad_request(format!(
            "t: must be in [0, 1], got {t}"
        )));
    }
    let kind = |m: &Value, which: &str| -> Result<String, ApiError> {
        m.pointer("/ndf/kind")
            .and_then(Value::as_str)
            .filter(|k| *k == "phong-peaks" || *k == "deltas")
            .map(str::to_owned)
            .ok_or_else(|| {
                ApiError::bad_request(format!(
                    "{which}.ndf.kind: blending needs phong-peaks or deltas NDFs"
                ))
            })
    };
    let (ka, kb) = (kind(a, "a")?, kind(b, "b")?);
    let out_kind = if ka == kb {
        ka.clone()
    } else {
        "phong-peaks".into()
    };
    let lobes = |m: &Value, k: &str, scale: f64, which: &str| -> Result<Vec<Value>, ApiError> {
        let arr = m
            .pointer("/ndf/lobes")
            .and_then(Value::as_array)
            .ok_or_else(|| ApiError::bad_request(format!("{which}.ndf.lobes: missing")))?;
        let total: f64 = arr
            .iter()
            .filter_map(|l| l.get("weight").and_then(Value::as_f64))
            .sum();
        if !(total > 0.0 && total.is_finite()) {
            return Err(ApiError::bad_request(format!(
                "{which}.ndf.lobes: the weights must sum to a positive number"
            )));
        }
        let mut out = Vec::with_capacity(arr.len());
        for l in arr {
            let mut l = l.clone();
            let w = l.get("weight").and_then(Value::as_f64).unwrap_or(0.0);
            if let Value::Object(o) = &mut l {
                o.insert("weight".into(), Value::from(w / total * scale));
                if k == "deltas" && out_kind == "phong-peaks" {
                    o.insert("exponent".into(), Value::from(DELTA_AS_PEAK_EXPONENT));
                }
            }
            if scale > 0.0 {
                out.push(l);
            }
        }
        Ok(out)
    };
    let mut all = lobes(a, &ka, 1.0 - t, "a")?;
    all.extend(lobes(b, &kb, t, "b")?);
    let mut out = if t < 0.5 { a.clone() } else { b.clone() };
    let albedo = |m: &Value| -> [f64; 3] {
        let mut c = [0.0; 3];
        if let Some(Value::Array(x)) = m.pointer("/diffuse/albedo") {
            for (ci, xi) in c.iter_mut().zip(x) {
                *ci = xi.as_f64().unwrap_or(0.0);
            }
        }
        c
    };
    let (da, db) = (albedo(a), albedo(b));
    let mix: Vec<Value> = (0..3)
        .map(|k| Value::from(da[k] * (1.0 - t) + db[k] * t))
        .collect();
    if let Value::Object(o) = &mut out {
        o.insert(
            "ndf".into(),
            serde_json::json!({ "kind": out_kind, "lobes": all }),
        );
        if da != [0.0; 3] || db != [0.0; 3] {
            o.insert("diffuse".into(), serde_json::json!({ "albedo": mix }));
        }
        let na = a.get("name").and_then(Value::as_str).unwrap_or("a");
        let nb = b.get("name").and_then(Value::as_str).unwrap_or("b");
        o.insert(
            "name".into(),
            Value::from(format!(
                "blend {:.0}% {na} / {:.0}% {nb}",
                (1.0 - t) * 100.0,
                t * 100.0
            )),
        );
    }
    Ok(out)
}

/// The exponent given to a delta normal blended with Phong peaks (a sharp peak, ~2° wide).
pub const DELTA_AS_PEAK_EXPONENT: f64 = 20_000.0;

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn json_toml_round_trip() {
        let m = json!({
            "name": "two \"quoted\" lobes",
            "ndf": { "kind": "phong-peaks", "lobes": [
                { "axis": [0, 0], "weight": 0.6, "exponent": 40 },
                { "axis": [30.5, 90], "weight": 0.4, "exponent": 100.0 } ] },
            "transfer": { "kind": "phong", "exponent": 50.0, "specular": [1.0, 0.8, 0.6] },
            "diffuse": { "albedo": [0.1, 0.2, 0.3] }
        });
        let v = validate(&m).unwrap();
        assert!(v.toml.contains("[ndf]"), "{}", v.toml);
        assert!(v
            .toml
            .contains("  { axis = [30.5, 90], weight = 0.4, exponent = 100.0 },"));
        let back = parse_toml(&v.toml).unwrap();
        assert_eq!(back["name"], m["name"]);
        assert_eq!(back["ndf"]["lobes"][1]["axis"][0], json!(30.5));
        assert_eq!(back["transfer"]["specular"], json!([1.0, 0.8, 0.6]));
    }

    #[test]
    fn vector_axes_become_angles() {
        let j = parse_toml(
            "[ndf]\nkind = \"deltas\"\nlobes = [{ axis = [0, 1, 1], weight = 1 }]\n\
             [transfer]\nkind = \"lambert\"\n",
        )
        .unwrap();
        assert_eq!(j["ndf"]["lobes"][0]["axis"], json!([45.0, 90.0]));
    }

    #[test]
    fn errors_name_the_key() {
        let e = validate(&json!({ "transfer": { "kind": "phong", "exponent": -1 } })).unwrap_err();
        assert!(e.message.contains("exponent"), "{}", e.message);
        let e = validate(&json!({ "transfer": null })).unwrap_err();
        assert!(e.message.contains("material.transfer"), "{}", e.message);
        let e = validate(&json!([1, 2])).unwrap_err();
        assert_eq!(e.status.as_u16(), 400);
        let e = parse_toml("[transfer]\nkind = \"phong\"\nexponent = 1\nbogus = 2\n").unwrap_err();
        assert!(e.message.contains("bogus"), "{}", e.message);
    }

    /// Height-map and map materials parse (their `[ndf]` table checked as meso-maps reads it,
    /// the file only named), and are refused where they would be evaluated without a texture.
    #[test]
    fn file_ndfs_parse_but_do_not_validate_without_a_texture() {
        let j = parse_toml(
            "[ndf]\nkind = \"map\"\nfile = \"rock.map\"\nlevel = 2\ntexel = [1, 3]\n\
             [transfer]\nkind = \"lambert\"\n",
        )
        .unwrap();
        assert_eq!(j["ndf"]["texel"], json!([1, 3]));
        let e = validate(&j).unwrap_err();
        assert!(e.message.contains("POST /api/texture"), "{}", e.message);
        for (text, key) in [
            ("kind = \"map\"\nfile = \"a.map\"\nbogus = 1\n", "bogus"),
            ("kind = \"map\"\nfile = \"a.map\"\ntexel = [1]\n", "texel"),
            ("kind = \"map\"\nfile = \"a.map\"\nlevel = -1\n", "level"),
            ("kind = \"heightmap\"\nfile = \"a.png\"\ntexel_size = 1\n", "height_scale"),
            ("kind = \"heightmap\"\nfile = \"a.png\"\ntexel_size = 1\nheight_scale = 1\nmax_lobes = 9\n", "max_lobes"),
        ] {
            let e = parse_toml(&format!("[ndf]\n{text}[transfer]\nkind = \"lambert\"\n"))
                .unwrap_err();
            assert!(e.message.contains(key), "{text}: {}", e.message);
        }
        // A texture texel without the server's textures is refused too.
        let m = json!({ "ndf": { "kind": "map", "texture": "0123456789abcdef", "level": 0,
                                 "texel": [0, 0] },
                        "transfer": { "kind": "lambert" } });
        assert_eq!(validate(&m).unwrap_err().status.as_u16(), 400);
        let store = crate::textures::TextureStore::new();
        assert_eq!(
            validate_with(&m, Some(&store)).unwrap_err().status.as_u16(),
            404
        );
    }

    #[test]
    fn blend_scales_weights() {
        let a = json!({ "ndf": { "kind": "deltas", "lobes": [ { "axis": [0, 0], "weight": 2 } ] },
                        "transfer": { "kind": "lambert" } });
        let b = json!({ "ndf": { "kind": "phong-peaks", "lobes": [
                          { "axis": [80, 0], "weight": 1, "exponent": 10 },
                          { "axis": [80, 180], "weight": 1, "exponent": 10 } ] },
                        "transfer": { "kind": "phong", "exponent": 20 } });
        let m = blend(&a, &b, 0.25).unwrap();
        assert_eq!(m["ndf"]["kind"], "phong-peaks");
        let l = m["ndf"]["lobes"].as_array().unwrap();
        assert_eq!(l.len(), 3);
        assert!((l[0]["weight"].as_f64().unwrap() - 0.75).abs() < 1e-12);
        assert_eq!(l[0]["exponent"], json!(DELTA_AS_PEAK_EXPONENT));
        assert!((l[2]["weight"].as_f64().unwrap() - 0.125).abs() < 1e-12);
        assert_eq!(m["transfer"]["kind"], "lambert");
        validate(&m).unwrap();
        assert!(blend(&a, &b, 1.5).is_err());
    }
}
