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
//! file = "bumps.png"       # height map (PNG, TIFF, EXR), relative to this file
//! texel_size = 0.01        # distance between height samples (length units)
//! height_scale = 0.02      # height of the full code range (same unit)
//! texels_per_uv = 64       # height-map cells per unit of u and v (default: the map's width)
//! [transfer]
//! kind = "phong"
//! exponent = 20
//! ```

use crate::mapped::{BumpMapped, NdfMapped};
use crate::shader::Shader;
use meso_core::material::{read_limited, MaterialSpec};
use meso_maps::MapsResolver;
use std::path::Path;
use std::sync::Arc;

/// Keys of the `[texture]` table passed on to the height-map loader (`kind = "heightmap"` of
/// `meso_maps::resolver`).
const MAP_KEYS: [&str; 6] = [
    "file",
    "texel_size",
    "height_scale",
    "max_lobes",
    "border",
    "normals",
];

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
        if !(MAP_KEYS.contains(&k.as_str())
            || ["kind", "texels_per_uv", "shadowing"].contains(&k.as_str()))
        {
            return Err(named(format!(
                "[texture]: unknown key `{k}` (known: kind, file, texel_size, height_scale, \
                 texels_per_uv, shadowing, max_lobes, border, normals)"
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
    let file = match tex.get("file").map(|f| f.as_str()) {
        Some(Some(f)) => path.parent().unwrap_or(Path::new(".")).join(f),
        Some(None) => return Err(named("[texture] file: expected a string".into())),
        None => return Err(named("[texture]: missing `file = \"…\"`".into())),
    };
    let shadowing = match tex.get("shadowing") {
        None => true,
        Some(v) => v
            .as_bool()
            .ok_or_else(|| named("[texture] shadowing: expected true or false".into()))?,
    };
    // The height-map keys as a `kind = "heightmap"` table, for meso-maps' loader.
    let mut map_table: toml::Table = tex
        .iter()
        .filter(|(k, _)| MAP_KEYS.contains(&k.as_str()))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    map_table.insert("kind".into(), toml::Value::String("heightmap".into()));
    let texture_err =
        |e: meso_core::material::MaterialError| named(e.0.replace("[ndf]", "[texture]"));
    let map = MapsResolver::heightmap(&map_table, &file).map_err(texture_err)?;
    let texels_per_uv = match tex.get("texels_per_uv") {
        None => map.cells_x() as f64,
        Some(v) => {
            let t = v
                .as_float()
                .or_else(|| v.as_integer().map(|i| i as f64))
                .ok_or_else(|| named("[texture] texels_per_uv: expected a number".into()))?;
            if !(t.is_finite() && t > 0.0) {
                return Err(named(format!(
                    "[texture] texels_per_uv: must be a finite number > 0, got {t}"
                )));
            }
            t
        }
    };
    // The facet material: the file without its `[texture]` table.
    let rest = toml::to_string(&doc).map_err(|e| named(format!("cannot re-read: {e}")))?;
    let surface = MaterialSpec::parse(&rest, path.parent().unwrap_or(Path::new(".")))
        .and_then(|s| s.build(maps))
        .map_err(|e| named(e.0))?;
    let shader: Arc<dyn Shader> = match kind {
        "bump-mapped" => {
            Arc::new(BumpMapped::new(&map, &surface, texels_per_uv, shadowing).map_err(named)?)
        }
        _ => {
            let pyramid = maps
                .heightmap_pyramid(&map_table, &file)
                .map_err(texture_err)?;
            Arc::new(NdfMapped::new(&pyramid, &surface, texels_per_uv, shadowing).map_err(named)?)
        }
    };
    Ok(Some(shader))
}
