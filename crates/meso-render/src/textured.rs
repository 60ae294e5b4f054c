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
//!                          # normal_map = "n.png" (tangent space, convention = "gl" | "dx");
//!                          # or map = "bumps.map" (written by `meso extract`, ndf-mapped only)
//! texel_size = 0.01        # distance between height samples (length units)
//! height_scale = 0.02      # height of the full code range (same unit)
//! texels_per_uv = 64       # height-map cells per unit of u and v (default: the map's width)
//! filter = "trilinear"     # ndf-mapped: or "box" (NdfMapped::with_box_filter)
//! box_detail = 2           # ndf-mapped, box filter: levels finer than the footprint, 0–3
//!                          # (default: from the facet's sharpness, NdfMapped::with_box_detail)
//! view_weighting = true    # facets counted by the area the viewer sees (default: true with
//!                          # shadowing, i.e. for height maps and map files with horizons;
//!                          # false for normal maps; NdfMapped::with_view_weighting,
//!                          # BumpMapped::with_view_weighting)
//! [transfer]
//! kind = "phong"
//! exponent = 20
//! ```

use crate::mapped::{BumpMapped, NdfMapped, MAX_BOX_DETAIL};
use crate::shader::Shader;
use meso_core::material::{read_limited, MaterialSpec};
use meso_maps::limits::MAX_LOBES;
use meso_maps::resolver::HEIGHTMAP_KEYS;
use meso_maps::{
    extract, Border, ExtractParams, MapsResolver, NormalConvention, NormalMap, NormalMode, Pyramid,
    Source,
};
use std::path::Path;
use std::sync::Arc;

/// The shader of the material file at `path` if it has a `[texture]` table (module docs);
/// `Ok(None)` for an ordinary material file. Pyramids of height maps come through `maps` (its
/// memory, the disk cache `meso_maps::pyramid_cache`, or extracted); `map = "…"` reads a map
/// file as it is.
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
    check_texture_keys(tex).map_err(named)?;
    let kind = texture_kind(tex).map_err(named)?;
    let box_filter = box_filter(tex, kind).map_err(named)?;
    let box_detail = box_detail(tex, kind, box_filter).map_err(named)?;
    let view_weighting = view_weighting(tex).map_err(named)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let t = Texture {
        kind,
        tex,
        doc: &doc,
        dir,
        box_filter,
        box_detail,
        view_weighting,
        maps,
    };
    let string = |key: &str| tex_string(tex, key).map_err(named);
    if let Some(m) = string("map")? {
        if tex.contains_key("file") || tex.contains_key("normal_map") {
            return Err(named(
                "[texture]: `map` (a map file), `file` (a height map) and `normal_map` exclude \
                 each other"
                    .into(),
            ));
        }
        return map_mapped(&t, &dir.join(m)).map(Some).map_err(named);
    }
    let shader = match (string("file")?, string("normal_map")?) {
        (Some(f), None) => height_textured(&t, &dir.join(f)),
        (None, Some(n)) => normal_textured(&t, &dir.join(n)),
        (Some(_), Some(_)) => {
            Err("[texture]: `file` (a height map) and `normal_map` exclude each other".into())
        }
        (None, None) => Err(
            "[texture]: missing `file = \"…\"` (a height map), `normal_map = \"…\"` or \
             `map = \"…\"` (a map file)"
                .into(),
        ),
    };
    shader.map(Some).map_err(named)
}

/// Refuse keys a `[texture]` table does not know.
fn check_texture_keys(tex: &toml::Table) -> Result<(), String> {
    for k in tex.keys() {
        if !(HEIGHTMAP_KEYS.contains(&k.as_str())
            || [
                "kind",
                "texels_per_uv",
                "shadowing",
                "normal_map",
                "map",
                "convention",
                "filter",
                "box_detail",
                "view_weighting",
            ]
            .contains(&k.as_str()))
        {
            return Err(format!(
                "[texture]: unknown key `{k}` (known: kind, file, normal_map, map, convention, \
                 texel_size, height_scale, texels_per_uv, shadowing, filter, box_detail, \
                 view_weighting, max_lobes, border, normals)"
            ));
        }
    }
    Ok(())
}

/// The `[texture]` table's `kind`: `"ndf-mapped"` or `"bump-mapped"`.
fn texture_kind(tex: &toml::Table) -> Result<&str, String> {
    match tex.get("kind").map(|k| k.as_str()) {
        Some(Some(k @ ("ndf-mapped" | "bump-mapped"))) => Ok(k),
        Some(Some(k)) => Err(format!(
            "[texture] kind: unknown \"{k}\" (known: ndf-mapped, bump-mapped)"
        )),
        Some(None) => Err("[texture] kind: expected a string".into()),
        None => Err("[texture]: missing `kind`".into()),
    }
}

/// The string value of `key` in the `[texture]` table, if present.
fn tex_string<'a>(tex: &'a toml::Table, key: &str) -> Result<Option<&'a str>, String> {
    match tex.get(key).map(|f| f.as_str()) {
        Some(Some(f)) => Ok(Some(f)),
        Some(None) => Err(format!("[texture] {key}: expected a string")),
        None => Ok(None),
    }
}

/// A `[texture]` table as read by [`load_textured`], with what every kind of texture needs: its
/// `kind` and `filter` (checked), the rest of the material file (the facet material) and the
/// material file's folder.
struct Texture<'a> {
    kind: &'a str,
    tex: &'a toml::Table,
    /// The material file without its `[texture]` table.
    doc: &'a toml::Table,
    /// The folder of the material file (relative paths).
    dir: &'a Path,
    box_filter: bool,
    /// `box_detail`, if given (checked: a number in `[0, MAX_BOX_DETAIL]`).
    box_detail: Option<f64>,
    /// `view_weighting`, if given (else the material's default: on with shadowing).
    view_weighting: Option<bool>,
    maps: &'a MapsResolver,
}

impl Texture<'_> {
    /// `m` with the table's filter (`filter` and, if given, `box_detail`) and, if given,
    /// `view_weighting`.
    fn filtered(&self, m: NdfMapped) -> NdfMapped {
        let m = m.with_box_filter(self.box_filter);
        let m = match self.view_weighting {
            Some(on) => m.with_view_weighting(on),
            None => m,
        };
        match self.box_detail {
            Some(d) => m.with_box_detail(d),
            None => m,
        }
    }

    /// `b` with the table's `view_weighting`, if given.
    fn bump(&self, b: BumpMapped) -> Arc<dyn Shader> {
        Arc::new(match self.view_weighting {
            Some(on) => b.with_view_weighting(on),
            None => b,
        })
    }

    /// The facet material: the file without its `[texture]` table.
    fn surface(&self) -> Result<meso_core::material::Material, String> {
        let rest = toml::to_string(self.doc).map_err(|e| format!("cannot re-read: {e}"))?;
        MaterialSpec::parse(&rest, self.dir)
            .and_then(|s| s.build(self.maps))
            .map_err(|e| e.0)
    }

    /// `max_lobes` of the table, if given: an integer in `1..=MAX_LOBES`.
    fn max_lobes(&self) -> Result<Option<usize>, String> {
        let Some(v) = self.tex.get("max_lobes") else {
            return Ok(None);
        };
        let k = v
            .as_integer()
            .filter(|k| (1..=MAX_LOBES as i64).contains(k))
            .ok_or_else(|| {
                format!("[texture] max_lobes: must be an integer 1–{MAX_LOBES}, got {v}")
            })?;
        Ok(Some(k as usize))
    }
}

/// A `[texture]` with `normal_map = FILE`: its checks (no height-map keys, no shadowing, the
/// convention), then [`normal_mapped`].
fn normal_textured(t: &Texture<'_>, file: &Path) -> Result<Arc<dyn Shader>, String> {
    let tex = t.tex;
    for k in ["texel_size", "height_scale", "border", "normals"] {
        if tex.contains_key(k) {
            return Err(format!(
                "[texture] {k}: applies to height maps (`file`), not to `normal_map`"
            ));
        }
    }
    if tex.get("shadowing").and_then(toml::Value::as_bool) == Some(true) {
        return Err("[texture] shadowing: a normal map has no heights to shadow with".into());
    }
    let convention = match tex_string(tex, "convention")? {
        None | Some("gl") => NormalConvention::Gl,
        Some("dx") => NormalConvention::Dx,
        Some(o) => {
            return Err(format!(
                "[texture] convention: unknown \"{o}\" (known: gl, dx)"
            ))
        }
    };
    normal_mapped(t, file, convention)
}

/// A `[texture]` with `file = HEIGHTS`: bump-mapped from the heights, or NDF-mapped through the
/// pyramid (from the resolver's memory, the disk cache, or extracted).
fn height_textured(t: &Texture<'_>, file: &Path) -> Result<Arc<dyn Shader>, String> {
    let tex = t.tex;
    if meso_maps::format::is_map_file(file) {
        return Err(format!(
            "[texture] file: {} is a meso map file (`meso extract`), not a height map: give it \
             as `map = \"…\"` (without `height_scale`)",
            file.display()
        ));
    }
    if tex.contains_key("convention") {
        return Err("[texture] convention: applies to `normal_map`, not to a height map".into());
    }
    let shadowing = match tex.get("shadowing") {
        None => true,
        Some(v) => v
            .as_bool()
            .ok_or_else(|| "[texture] shadowing: expected true or false".to_string())?,
    };
    // The height-map keys as a `kind = "heightmap"` table, for meso-maps' loader.
    let mut map_table: toml::Table = tex
        .iter()
        .filter(|(k, _)| HEIGHTMAP_KEYS.contains(&k.as_str()))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    map_table.insert("kind".into(), toml::Value::String("heightmap".into()));
    let texture_err = |e: meso_core::material::MaterialError| e.0.replace("[ndf]", "[texture]");
    let surface = t.surface()?;
    Ok(match t.kind {
        "bump-mapped" => {
            let map = t
                .maps
                .load_heightmap(&map_table, file)
                .map_err(texture_err)?;
            let texels_per_uv = texels_per_uv(tex, map.cells_x())?;
            meso_core::budget::check(
                file,
                "bump-mapping the height map (its facet normals and shadow rays' tracer)",
                BumpMapped::bytes(map.cells_x(), map.cells_y(), shadowing),
            )
            .map_err(|e| format!("[texture] file: {e}"))?;
            t.bump(BumpMapped::new(&map, &surface, texels_per_uv, shadowing)?)
        }
        _ => {
            // From the resolver's memory, the disk cache or extracted (`MapsResolver`): the
            // height map itself is only decoded to extract.
            let pyramid = t
                .maps
                .heightmap_pyramid(&map_table, file)
                .map_err(texture_err)?;
            let texels_per_uv = texels_per_uv(tex, pyramid.levels[0].cols)?;
            // The tables' sums take seconds on a big map: reported as the resolver's
            // progress, under the height map's name.
            let report = |p: meso_maps::Progress| t.maps.report(file, p);
            Arc::new(
                t.filtered(NdfMapped::new_reporting(
                    &pyramid,
                    &surface,
                    texels_per_uv,
                    shadowing,
                    t.maps
                        .reports_progress()
                        .then_some(&report as &(dyn Fn(meso_maps::Progress) + Sync)),
                )?),
            )
        }
    })
}

/// A `[texture]` over a map file written by `meso extract` (`map = "…"`): NDF-mapped through
/// its pyramid as stored. The keys that describe the extraction (`texel_size`, `max_lobes`,
/// `border`, `normals`) may be given only to agree with the file; `height_scale` is refused
/// (the file's slopes are already scaled), and so is `kind = "bump-mapped"` (no heights).
fn map_mapped(t: &Texture<'_>, file: &Path) -> Result<Arc<dyn Shader>, String> {
    let tex = t.tex;
    let shown = file.display();
    if t.kind == "bump-mapped" {
        return Err(format!(
            "[texture] map: {shown} is a map file of fitted NDFs, without the heights that \
             kind = \"bump-mapped\" shades: give the height map as `file = \"…\"`, or use \
             kind = \"ndf-mapped\""
        ));
    }
    for k in ["height_scale", "convention"] {
        if tex.contains_key(k) {
            return Err(format!(
                "[texture] {k}: does not apply to a map file (`map`): {shown} stores slopes \
                 already scaled by the height map's parameters it was extracted with"
            ));
        }
    }
    // Kept as the file codes it (half the memory of `f32` levels, the same values read); when
    // that would take more than half the budget, level 0 (¾ of it) by band in the mapped file,
    // decoded where read (slower where a view reads much of it).
    let pyramid = t
        .maps
        .read_map_file(file)
        .map_err(|e| format!("[texture] map: {e}"))?;
    let conflict = |key: &str, given: &dyn std::fmt::Display, stored: &dyn std::fmt::Display| {
        format!(
            "[texture] {key} = {given} conflicts with the map file {shown}, extracted with \
             {key} = {stored} (remove `{key}` or re-extract)"
        )
    };
    if let Some(v) = tex.get("texel_size") {
        let t = v
            .as_float()
            .or_else(|| v.as_integer().map(|i| i as f64))
            .ok_or_else(|| format!("[texture] texel_size: expected a number, got {v}"))?;
        if (t - pyramid.texel_size).abs() > 1e-12 * pyramid.texel_size.abs().max(t.abs()) {
            return Err(conflict("texel_size", &t, &pyramid.texel_size));
        }
    }
    if let Some(k) = t.max_lobes()? {
        if k != pyramid.max_lobes {
            return Err(conflict("max_lobes", &k, &pyramid.max_lobes));
        }
    }
    let stored_border = match pyramid.border {
        Border::Wrap => "wrap",
        Border::Clamp => "clamp",
    };
    let stored_normals = match pyramid.normal_mode {
        NormalMode::Triangles => "triangles",
        NormalMode::CentralDifferences => "central",
    };
    for (key, stored, known) in [
        ("border", stored_border, ["wrap", "clamp"]),
        ("normals", stored_normals, ["triangles", "central"]),
    ] {
        if let Some(v) = tex.get(key) {
            match v.as_str() {
                Some(s) if s == stored => {}
                Some(s) if known.contains(&s) => {
                    return Err(conflict(key, &format!("\"{s}\""), &format!("\"{stored}\"")))
                }
                _ => {
                    return Err(format!(
                        "[texture] {key}: expected \"{}\" or \"{}\", got {v}",
                        known[0], known[1]
                    ))
                }
            }
        }
    }
    let has_horizon = pyramid.levels.iter().all(|l| l.horizon.is_some());
    let shadowing = match tex.get("shadowing") {
        None => has_horizon,
        Some(v) => {
            let s = v
                .as_bool()
                .ok_or_else(|| "[texture] shadowing: expected true or false".to_string())?;
            if s && !has_horizon {
                return Err(format!(
                    "[texture] shadowing: the map file {shown} has no horizon statistics \
                     (extracted from a normal map): nothing to shadow with"
                ));
            }
            s
        }
    };
    let texels_per_uv = texels_per_uv(tex, pyramid.levels[0].cols)?;
    let surface = t.surface()?;
    // The pyramid is read for this material alone: hand it over; its tables are built tile by
    // tile as the render reads them (a 4096² map's peak, docs/benchmarks.md), under a cap
    // from the memory budget (docs/limits.md).
    let cap = table_cap(file, &pyramid, &surface, shadowing)?;
    Ok(Arc::new(
        t.filtered(NdfMapped::from_pyramid(
            pyramid,
            &surface,
            texels_per_uv,
            shadowing,
        )?)
        .with_table_cap(cap),
    ))
}

/// The least memory for an NDF-mapped material's tables built on demand (a few hundred
/// level-0 tiles of a height map, ≈ 0.5 MB each).
pub const MIN_TABLE_CACHE: u64 = 64 << 20;

/// The cap on the tables `meso render` builds on demand for the map file `file` (its
/// `pyramid` held besides): half of what the memory budget leaves beside the pyramid, at
/// least [`MIN_TABLE_CACHE`], at most every tile's tables
/// ([`NdfMapped::tables_bytes_bound`]). The material's estimate, the pyramid and the least
/// cache, is checked against the budget first.
///
/// # Errors
/// The budget's message naming `file` when the pyramid and the least cache do not fit.
fn table_cap(
    file: &Path,
    pyramid: &Pyramid,
    surface: &meso_core::material::Material,
    shadowing: bool,
) -> Result<usize, String> {
    let held = NdfMapped::pyramid_bytes(pyramid);
    let bound = NdfMapped::tables_bytes_bound(pyramid, surface, shadowing);
    let least = MIN_TABLE_CACHE.min(bound);
    meso_core::budget::check(
        file,
        "rendering the map file (its pyramid and the least cache of tables)",
        held + least,
    )
    .map_err(|e| format!("[texture] map: {e}"))?;
    let left = meso_core::budget::budget().bytes.saturating_sub(held);
    let cap = (left / 2).max(least).min(bound);
    Ok(usize::try_from(cap).unwrap_or(usize::MAX))
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

/// `box_detail` of a `[texture]` table, if given: a number in `[0, MAX_BOX_DETAIL]`, for the box
/// filter of an NDF-mapped texture only (`NdfMapped::with_box_detail`).
fn box_detail(tex: &toml::Table, kind: &str, box_filter: bool) -> Result<Option<f64>, String> {
    let Some(v) = tex.get("box_detail") else {
        return Ok(None);
    };
    if kind != "ndf-mapped" || !box_filter {
        return Err(
            "[texture] box_detail: applies to kind = \"ndf-mapped\" with filter = \"box\""
                .to_string(),
        );
    }
    v.as_float()
        .or_else(|| v.as_integer().map(|i| i as f64))
        .filter(|d| (0.0..=MAX_BOX_DETAIL).contains(d))
        .map(Some)
        .ok_or_else(|| {
            format!("[texture] box_detail: must be a number 0–{MAX_BOX_DETAIL}, got {v}")
        })
}

/// `view_weighting` of a `[texture]` table, if given: `true` or `false`
/// ([`NdfMapped::with_view_weighting`], [`BumpMapped::with_view_weighting`]; without it the
/// material's default, on with shadowing).
fn view_weighting(tex: &toml::Table) -> Result<Option<bool>, String> {
    let Some(v) = tex.get("view_weighting") else {
        return Ok(None);
    };
    v.as_bool()
        .map(Some)
        .ok_or_else(|| format!("[texture] view_weighting: expected true or false, got {v}"))
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
            crate::mapped::check_scale(t).map_err(|e| format!("[texture] {e}"))?;
            Ok(t)
        }
    }
}

/// A `[texture]` over a tangent-space normal map: texel by texel, or through the pyramid of
/// its normals (no heights: no shadowing).
fn normal_mapped(
    t: &Texture<'_>,
    file: &Path,
    convention: NormalConvention,
) -> Result<Arc<dyn Shader>, String> {
    // The load's warnings: said by the caller, kept in the pyramid cache's entry.
    let load = || {
        let map = NormalMap::load(file, convention).map_err(|e| format!("[texture]: {e}"))?;
        let warnings = map.warnings();
        Ok::<_, String>((map, warnings))
    };
    let surface = t.surface()?;
    if t.kind == "bump-mapped" {
        let (map, warnings) = load()?;
        for w in &warnings {
            t.maps.warn(file, w);
        }
        let texels_per_uv = texels_per_uv(t.tex, map.width())?;
        meso_core::budget::check(
            file,
            "bump-mapping the normal map (its normals)",
            BumpMapped::bytes(map.width(), map.height(), false),
        )
        .map_err(|e| format!("[texture] normal_map: {e}"))?;
        return Ok(t.bump(BumpMapped::from_normal_map(&map, &surface, texels_per_uv)?));
    }
    let mut params = ExtractParams::default();
    if let Some(k) = t.max_lobes()? {
        params = params.with_max_lobes(k);
    }
    // From the disk cache (keyed by the file's bytes, convention and parameters) or extracted
    // and stored there: the normal map is only decoded to extract.
    let got = meso_maps::pyramid_cache::normal_pyramid_cached(file, convention, &params, || {
        let (map, warnings) = load()?;
        let pyramid = extract(Source::Normals(&map), &params, &mut |_| {})
            .map_err(|e| format!("[texture] {}: {e}", file.display()))?;
        Ok::<_, String>((pyramid, warnings))
    })?;
    for w in &got.warnings {
        t.maps.warn(file, w);
    }
    let pyramid = got.value;
    let texels_per_uv = texels_per_uv(t.tex, pyramid.width)?;
    Ok(Arc::new(t.filtered(NdfMapped::new(
        &pyramid,
        &surface,
        texels_per_uv,
        false,
    )?)))
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
            .map(|m| {
                maps.warn_estimated_interreflection(path, &m, true);
                Arc::new(crate::MaterialShader::new(&m)) as Arc<dyn Shader>
            })
            .map_err(|e| -> crate::ResolveError { format!("{e:#}").into() }),
    }
}
