//! Spatially varying materials in scene files: a material file with a `[texture]` table is a
//! height map shaded either texel by texel ([`BumpMapped`], the ground truth) or through its
//! pyramid of fitted NDFs ([`NdfMapped`], filtered by the pixel footprint). The rest of the file
//! (`[transfer]`, `[diffuse]`, `form`, …) is an ordinary meso material whose facet transfer and
//! diffuse term every micro-facet uses; its `[ndf]`, if any, is ignored. Format:
//! `docs/scene-format.md`, "Textured materials".
//!
//! ```toml
//! [texture]
//! kind = "ndf-mapped"      # or "bump-mapped"
//! file = "bumps.png"       # height map (PNG, TIFF, EXR), relative to this file; or
//!                          # normal_map = "n.png" (tangent space, convention = "gl" | "dx")
//! texel_size = 0.01        # distance between height samples (length units)
//! height_scale = 0.02      # height of the full code range (same unit)
//! texels_per_uv = 64       # height-map cells per unit of u and v (default: the map's width)
//! filter = "trilinear"     # ndf-mapped: or "box" (NdfMapped::with_box_filter)
//! [transfer]
//! kind = "phong"
//! exponent = 20
//! ```

use crate::mapped::{BumpMapped, NdfMapped};
use crate::shader::Shader;
use meso_core::material::{read_limited, MaterialSpec};
use meso_maps::fit::MAX_LOBES;
use meso_maps::resolver::HEIGHTMAP_KEYS;
use meso_maps::{extract, ExtractParams, MapsResolver, NormalConvention, NormalMap, Source};
use std::path::Path;
use std::sync::Arc;

/// The shader of the material file at `path` if it has a `[texture]` table (module docs);
/// `Ok(None)` for an ordinary material file. Pyramids are extracted through `maps` (and cached
/// there).
///
/// # Errors
/// A message naming the file, the table and the problem: unreadable or oversized file, invalid
/// TOML, unknown or bad keys, a missing or broken height map, an invalid facet material.
pub fn load_textured(path: &Path, maps: &MapsResolver) -> Result<Option<Arc<dyn Shader>>, String> {
    let named = |e: String| format!("{}: {e}", path.display());
    let text = read_limited(path).map_err(|e| e.0)?;
    let mut doc: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| named(format!("not valid TOML: {}", e.message())))?;
    let Some(texture) = doc.remove("texture") else {
        return Ok(None);
    };
    let tex = texture
        .as_table()
        .ok_or_else(|| named("[texture]: expected a table".into()))?;
    for k in tex.keys() {
        if !(HEIGHTMAP_KEYS.contains(&k.as_str())
            || [
                "kind",
                "texels_per_uv",
                "shadowing",
                "normal_map",
                "convention",
                "filter",
            ]
            .contains(&k.as_str()))
        {
            return Err(named(format!(
                "[texture]: unknown key `{k}` (known: kind, file, normal_map, convention, \
                 texel_size, height_scale, texels_per_uv, shadowing, filter, max_lobes, border, \
                 normals)"
            )));
        }
    }
    let kind = match tex.get("kind").map(|k| k.as_str()) {
        Some(Some(k @ ("ndf-mapped" | "bump-mapped"))) => k,
        Some(Some(k)) => {
            return Err(named(format!(
                "[texture] kind: unknown \"{k}\" (known: ndf-mapped, bump-mapped)"
            )))
        }
        Some(None) => return Err(named("[texture] kind: expected a string".into())),
        None => return Err(named("[texture]: missing `kind`".into())),
    };
    let box_filter = box_filter(tex, kind).map_err(named)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let string = |key: &str| match tex.get(key).map(|f| f.as_str()) {
        Some(Some(f)) => Ok(Some(f)),
        Some(None) => Err(named(format!("[texture] {key}: expected a string"))),
        None => Ok(None),
    };
    let file = match (string("file")?, string("normal_map")?) {
        (Some(f), None) => dir.join(f),
        (None, Some(n)) => {
            for k in ["texel_size", "height_scale", "border", "normals"] {
                if tex.contains_key(k) {
                    return Err(named(format!(
                        "[texture] {k}: applies to height maps (`file`), not to `normal_map`"
                    )));
                }
            }
            if tex.get("shadowing").and_then(toml::Value::as_bool) == Some(true) {
                return Err(named(
                    "[texture] shadowing: a normal map has no heights to shadow with".into(),
                ));
            }
            let convention = match string("convention")? {
                None | Some("gl") => NormalConvention::Gl,
                Some("dx") => NormalConvention::Dx,
                Some(o) => {
                    return Err(named(format!(
                        "[texture] convention: unknown \"{o}\" (known: gl, dx)"
                    )))
                }
            };
            return normal_mapped(
                kind,
                tex,
                &doc,
                path,
                &dir.join(n),
                convention,
                box_filter,
                maps,
            )
            .map(Some)
            .map_err(named);
        }
        (Some(_), Some(_)) => {
            return Err(named(
                "[texture]: `file` (a height map) and `normal_map` exclude each other".into(),
            ))
        }
        (None, None) => {
            return Err(named(
                "[texture]: missing `file = \"…\"` (a height map) or `normal_map = \"…\"`".into(),
            ))
        }
    };
    if tex.contains_key("convention") {
        return Err(named(
            "[texture] convention: applies to `normal_map`, not to a height map".into(),
        ));
    }
    let shadowing = match tex.get("shadowing") {
        None => true,
        Some(v) => v
            .as_bool()
            .ok_or_else(|| named("[texture] shadowing: expected true or false".into()))?,
    };
    // The height-map keys as a `kind = "heightmap"` table, for meso-maps' loader.
    let mut map_table: toml::Table = tex
        .iter()
        .filter(|(k, _)| HEIGHTMAP_KEYS.contains(&k.as_str()))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    map_table.insert("kind".into(), toml::Value::String("heightmap".into()));
    let texture_err =
        |e: meso_core::material::MaterialError| named(e.0.replace("[ndf]", "[texture]"));
    let map = MapsResolver::heightmap(&map_table, &file).map_err(texture_err)?;
    let texels_per_uv = texels_per_uv(tex, map.cells_x()).map_err(named)?;
    let surface = facet_material(&doc, dir, maps).map_err(named)?;
    let shader: Arc<dyn Shader> = match kind {
        "bump-mapped" => {
            Arc::new(BumpMapped::new(&map, &surface, texels_per_uv, shadowing).map_err(named)?)
        }
        _ => {
            let pyramid = maps
                .heightmap_pyramid(&map_table, &file)
                .map_err(texture_err)?;
            Arc::new(
                NdfMapped::new(&pyramid, &surface, texels_per_uv, shadowing)
                    .map_err(named)?
                    .with_box_filter(box_filter),
            )
        }
    };
    Ok(Some(shader))
}

/// `filter` of a `[texture]` table: `"box"` (default: the closer to the supersampled bump map
/// on every map measured, docs/heightmaps.md "Steep maps") or `"trilinear"`, NDF-mapped only.
fn box_filter(tex: &toml::Table, kind: &str) -> Result<bool, String> {
    match tex.get("filter") {
        None => Ok(true),
        Some(_) if kind != "ndf-mapped" => {
            Err("[texture] filter: applies to kind = \"ndf-mapped\"".to_string())
        }
        Some(v) => match v.as_str() {
            Some("trilinear") => Ok(false),
            Some("box") => Ok(true),
            Some(o) => Err(format!(
                "[texture] filter: unknown \"{o}\" (known: trilinear, box)"
            )),
            None => Err("[texture] filter: expected a string".to_string()),
        },
    }
}

/// `texels_per_uv` of a `[texture]` table (default: the map's width, one copy per unit of uv).
fn texels_per_uv(tex: &toml::Table, width: usize) -> Result<f64, String> {
    match tex.get("texels_per_uv") {
        None => Ok(width as f64),
        Some(v) => {
            let t = v
                .as_float()
                .or_else(|| v.as_integer().map(|i| i as f64))
                .ok_or_else(|| "[texture] texels_per_uv: expected a number".to_string())?;
            if t.is_finite() && t > 0.0 {
                Ok(t)
            } else {
                Err(format!(
                    "[texture] texels_per_uv: must be a finite number > 0, got {t}"
                ))
            }
        }
    }
}

/// The facet material: the file without its `[texture]` table.
fn facet_material(
    doc: &toml::Table,
    dir: &Path,
    maps: &MapsResolver,
) -> Result<meso_core::material::Material, String> {
    let rest = toml::to_string(doc).map_err(|e| format!("cannot re-read: {e}"))?;
    MaterialSpec::parse(&rest, dir)
        .and_then(|s| s.build(maps))
        .map_err(|e| e.0)
}

/// A `[texture]` over a tangent-space normal map: texel by texel, or through the pyramid of
/// its normals (no heights: no shadowing).
#[allow(clippy::too_many_arguments)]
fn normal_mapped(
    kind: &str,
    tex: &toml::Table,
    doc: &toml::Table,
    path: &Path,
    file: &Path,
    convention: NormalConvention,
    box_filter: bool,
    maps: &MapsResolver,
) -> Result<Arc<dyn Shader>, String> {
    let map = NormalMap::load(file, convention).map_err(|e| format!("[texture]: {e}"))?;
    let texels_per_uv = texels_per_uv(tex, map.width())?;
    let surface = facet_material(doc, path.parent().unwrap_or(Path::new(".")), maps)?;
    if kind == "bump-mapped" {
        return Ok(Arc::new(BumpMapped::from_normal_map(
            &map,
            &surface,
            texels_per_uv,
        )?));
    }
    let mut params = ExtractParams::default();
    if let Some(v) = tex.get("max_lobes") {
        let k = v
            .as_integer()
            .filter(|k| (1..=MAX_LOBES as i64).contains(k))
            .ok_or_else(|| {
                format!("[texture] max_lobes: must be an integer 1–{MAX_LOBES}, got {v}")
            })?;
        params.fit.max_lobes = k as usize;
    }
    let pyramid = extract(Source::Normals(&map), &params, &mut |_| {})
        .map_err(|e| format!("[texture] {}: {e}", file.display()))?;
    Ok(Arc::new(
        NdfMapped::new(&pyramid, &surface, texels_per_uv, false)?.with_box_filter(box_filter),
    ))
}

/// The shader of a material file: a `[texture]` material (bump- or NDF-mapped, through
/// [`load_textured`]) or a plain meso-core material (height-map NDFs loaded by `maps`). The one
/// "material file → shader" resolver of the `meso` CLI and the Python package.
///
/// # Errors
/// A message naming the file and the problem.
pub fn resolve_material_file(
    path: &Path,
    maps: &MapsResolver,
) -> Result<Arc<dyn Shader>, crate::ResolveError> {
    match load_textured(path, maps) {
        Err(e) => Err(e.into()),
        Ok(Some(s)) => Ok(s),
        Ok(None) => meso_core::material::Material::from_file(path, maps)
            .map(|m| Arc::new(crate::MaterialShader::new(&m)) as Arc<dyn Shader>)
            .map_err(|e| -> crate::ResolveError { format!("{e:#}").into() }),
    }
}
