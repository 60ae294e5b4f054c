//! Textures opened in the editor: a height map, a normal map or a map file (`meso extract`)
//! uploaded by the browser, decoded and extracted into its NDF pyramid by `meso_maps` (the same
//! loader and extraction as `meso extract`), and kept in memory for the texel inspector and the
//! textured preview.
//!
//! The server never reads a path it is given: the texture's bytes come in the request body
//! (`POST /api/texture`), its name only chooses the image format and names it in messages.
//!
//! * **Limits.** The body is at most [`MAX_TEXTURE_BYTES`]; an image at most
//!   [`MAX_TEXTURE_SIDE`] samples a side and [`MAX_TEXTURE_SAMPLES`] in all (read from its
//!   header, before anything is decoded), and the estimated memory of loading and extracting it
//!   within the memory budget (`meso_core::budget`); a map file's finest level at most
//!   [`MAX_TEXTURE_SAMPLES`] texels. Above them: 413 with a message saying which limit.
//! * **Store.** At most [`MAX_TEXTURES`] textures are kept, the least recently used dropped
//!   first. A texture's id is a hash of its bytes and parameters, so uploading the same file with
//!   the same parameters again answers from memory without extracting.
//! * **Materials.** A material whose NDF is `{"kind": "map", "texture": "<id>", "level": k |
//!   "top", "texel": [row, col]}` has the NDF of that texel, resolved as `[ndf] kind = "map"`
//!   resolves a map file's texel ([`meso_maps::resolver::texel_ndf`]); its TOML names the map
//!   file ([`Texture::map_file_name`]).

use crate::error::ApiError;
use meso_core::material::{MaterialError, NdfResolver, ResolvedNdf};
use meso_maps::input::{load_bytes, InputKind};
use meso_maps::{
    extract, extract_bytes, Border, ExtractParams, MapError, NormalConvention, NormalMode, Pyramid,
};
use serde::Deserialize;
use serde_json::{json, Value};
use sha2::{Digest, Sha256};
use std::collections::VecDeque;
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Largest upload body (32 MiB); larger uploads are answered 413.
pub const MAX_TEXTURE_BYTES: usize = 32 << 20;
/// Largest width or height of an uploaded image, in samples.
pub const MAX_TEXTURE_SIDE: u64 = 2048;
/// Most samples of an uploaded image (1024², about 1 GB to extract), and most level-0 texels of
/// an uploaded map file.
pub const MAX_TEXTURE_SAMPLES: u64 = 1 << 20;
/// Textures kept in memory; opening one more drops the least recently used.
pub const MAX_TEXTURES: usize = 4;
/// Longest texture name kept (characters); longer names are cut.
const MAX_NAME_CHARS: usize = 120;

/// What an upload holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TextureKind {
    /// A grey height map (PNG, JPEG, TGA, TIFF, EXR).
    Height,
    /// A tangent-space RGB normal map.
    Normal,
    /// A map file written by `meso extract` (docs/map-format.md).
    Map,
}

impl TextureKind {
    fn as_str(self) -> &'static str {
        match self {
            TextureKind::Height => "height",
            TextureKind::Normal => "normal",
            TextureKind::Map => "map",
        }
    }
}

/// The query parameters of `POST /api/texture`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UploadParams {
    /// What the body holds (required).
    pub kind: Option<TextureKind>,
    /// The file's name (its extension chooses the image format when the content does not say).
    pub name: Option<String>,
    /// Height maps: distance between samples (> 0, length units).
    pub texel_size: Option<f64>,
    /// Height maps: height of the full code range (> 0, same unit).
    pub height_scale: Option<f64>,
    /// Normal maps: `gl` (default; green up in the image) or `dx`.
    pub convention: Option<String>,
    /// Lobes per texel, 1–8 (default 4); images only.
    pub max_lobes: Option<usize>,
    /// Height maps: `wrap` (default) or `clamp`.
    pub border: Option<String>,
    /// Height maps: `triangles` (default) or `central`.
    pub normals: Option<String>,
}

/// An open texture: its pyramid and what the inspector shows about it.
#[derive(Debug)]
pub struct Texture {
    /// The id (hash of the bytes and parameters, 16 hex digits).
    pub id: String,
    /// The uploaded file's name.
    pub name: String,
    /// What was uploaded.
    pub kind: TextureKind,
    /// The NDF pyramid.
    pub pyramid: Arc<Pyramid>,
    /// The loader's warnings (quantised heights, texels at the horizon, …).
    pub warnings: Vec<String>,
    /// Milliseconds spent decoding and extracting.
    pub extract_ms: f64,
}

impl Texture {
    /// The name of the map file that holds this pyramid: the upload's own name for a map file,
    /// else the image's name with the extension `.map` (what `meso extract` writes from it with
    /// the same parameters). Materials naming a texel of this texture write it as their `file`.
    #[must_use]
    pub fn map_file_name(&self) -> String {
        if self.kind == TextureKind::Map {
            return self.name.clone();
        }
        let stem = Path::new(&self.name)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("texture");
        format!("{stem}.map")
    }

    /// The texture's summary (`POST /api/texture`, `GET /api/texture/{id}`): sizes, parameters,
    /// warnings and per level the texel grid, lobe count and fit residuals (the NDF residual and
    /// the shading error as a fraction of the peak, `null` when the map file did not record it).
    #[must_use]
    pub fn info_json(&self, cached: bool) -> Value {
        let p = &self.pyramid;
        let levels: Vec<Value> = p
            .info()
            .levels
            .iter()
            .enumerate()
            .map(|(k, l)| {
                json!({
                    "level": k,
                    "cols": l.cols,
                    "rows": l.rows,
                    "span": l.span,
                    "lobes": l.lobes,
                    "lobes_per_texel": l.lobes as f64 / (l.cols * l.rows).max(1) as f64,
                    "residual": {
                        "mean": finite(l.residual.mean),
                        "max": finite(l.residual.max),
                        "texels": l.residual.texels,
                        "shading_mean": l.residual.shading_mean.map(finite),
                        "shading_max": l.residual.shading_max.map(finite),
                    },
                })
            })
            .collect();
        json!({
            "id": self.id,
            "name": self.name,
            "kind": self.kind.as_str(),
            "map_file": self.map_file_name(),
            "width": p.width,
            "height": p.height,
            "texel_size": p.texel_size,
            "max_lobes": p.max_lobes,
            "border": match p.border { Border::Wrap => "wrap", Border::Clamp => "clamp" },
            "normals": match p.normal_mode {
                NormalMode::Triangles => "triangles",
                NormalMode::CentralDifferences => "central",
            },
            "horizon": p.levels.iter().all(|l| l.horizon.is_some()),
            "warnings": self.warnings,
            "extract_ms": (self.extract_ms * 10.0).round() / 10.0,
            "cached": cached,
            "levels": levels,
        })
    }

    /// The lobes of texel `(row, col)` of level `level` (`GET /api/texture/{id}/texel`): each
    /// lobe's axis as `[θ, φ]` in degrees (φ in [0, 360), rounded to 1e-6°), its weight and its
    /// Phong exponent η, in the JSON form of a `phong-peaks` lobe, plus what it stands for
    /// ([`meso_maps::texel_lobe_stats`]): `share`, its share of the texel's projected area, and
    /// for height maps `horizon`, the horizon angles of the cells whose normals it stands for
    /// along the eight stored azimuths as `{"azimuths": [8], "median": [8], "quartiles": [[8],
    /// [8]]}` in degrees (`null` for normal maps), the distribution from which the renderer
    /// takes the lobe's visibility of the light; the level's size and
    /// the texel's footprint in level-0 cells. Cost: one visit of each level-0 cell of the
    /// footprint (the whole map for the top level).
    ///
    /// # Errors
    /// 400 naming a level, row or column out of range.
    pub fn texel_json(&self, level: usize, row: usize, col: usize) -> Result<Value, ApiError> {
        let p = &self.pyramid;
        let lv = p
            .level(level)
            .map_err(|e| ApiError::bad_request(format!("level: {e} in texture {:?}", self.name)))?;
        let lobes = lv.texel_lobes(row, col).map_err(|e| {
            ApiError::bad_request(format!(
                "texel [{row}, {col}]: {e} in level {level} ({} × {} texels)",
                lv.rows, lv.cols
            ))
        })?;
        let stats = meso_maps::texel_lobe_stats(p, level, row, col)
            .map_err(|e| ApiError::bad_request(format!("texel [{row}, {col}]: {e}")))?;
        let c0 = p.levels[0].cols;
        let r0 = p.levels[0].rows;
        let out: Vec<Value> = lobes
            .iter()
            .zip(&stats)
            .map(|(l, st)| {
                let (t, ph) = meso_core::frame::spherical_angles(l.axis);
                let r = |x: f64| (x * 1e6).round() / 1e6;
                let mut ph = r(ph.to_degrees());
                if ph < 0.0 {
                    ph += 360.0;
                }
                // Per direction of `HORIZON_AZIMUTHS_DEG`, the median horizon angle and the
                // quartiles of the cells the lobe stands for (degrees).
                let horizon = st.horizon.map(|h| {
                    let q = |p: f64| -> Vec<f64> {
                        (0..meso_maps::HORIZON_DIRECTIONS)
                            .map(|d| r(h.quantile(d, p).to_degrees()))
                            .collect()
                    };
                    json!({
                        "azimuths": meso_maps::HORIZON_AZIMUTHS_DEG,
                        "median": q(0.5),
                        "quartiles": [q(0.25), q(0.75)],
                    })
                });
                json!({
                    "axis": [r(t.to_degrees()), ph],
                    "weight": l.weight,
                    "exponent": l.exponent,
                    "share": st.share,
                    "horizon": horizon,
                })
            })
            .collect();
        Ok(json!({
            "texture": self.id,
            "level": level,
            "row": row,
            "col": col,
            "rows": lv.rows,
            "cols": lv.cols,
            "span": lv.span,
            "cells": {
                "rows": [row * lv.span, ((row + 1) * lv.span).min(r0)],
                "cols": [col * lv.span, ((col + 1) * lv.span).min(c0)],
            },
            "lobes": out,
        }))
    }

    /// The NDF of a texel, as `[ndf] kind = "map"` resolves it (module docs).
    ///
    /// # Errors
    /// Level or texel out of range, as a [`MaterialError`].
    pub fn texel_ndf(
        &self,
        level: usize,
        row: usize,
        col: usize,
    ) -> Result<ResolvedNdf, MaterialError> {
        meso_maps::resolver::texel_ndf(
            &self.pyramid,
            level,
            row,
            col,
            &format!("texture {:?}", self.name),
        )
    }
}

fn finite(x: f64) -> Value {
    serde_json::Number::from_f64(x).map_or(Value::Null, Value::Number)
}

/// The open textures, least recently used first (at most [`MAX_TEXTURES`]), and the shader of
/// the last textured preview.
#[derive(Debug, Default)]
pub struct TextureStore {
    open: Mutex<VecDeque<Arc<Texture>>>,
    shader: Mutex<Option<CachedShader>>,
}

/// The NDF-mapped shader of the last textured preview: building it converts the whole pyramid
/// (0.8 s for a 256² map, 3.6 s for 1024², measured), rendering with it takes a fraction of that.
#[derive(Debug)]
struct CachedShader {
    /// The texture's id.
    id: String,
    /// What else the shader depends on: the facet material, texels per uv, shadowing.
    key: String,
    shader: Arc<meso_render::NdfMapped>,
}

impl TextureStore {
    /// An empty store.
    #[must_use]
    pub fn new() -> TextureStore {
        TextureStore::default()
    }

    /// The texture `id`, now the most recently used.
    #[must_use]
    pub fn get(&self, id: &str) -> Option<Arc<Texture>> {
        let mut open = self.open.lock().unwrap_or_else(|e| e.into_inner());
        let k = open.iter().position(|t| t.id == id)?;
        let t = open.remove(k)?;
        open.push_back(t.clone());
        Some(t)
    }

    /// [`TextureStore::get`], or 404 saying that the texture is not open.
    ///
    /// # Errors
    /// 404 when no texture `id` is open.
    pub fn require(&self, id: &str) -> Result<Arc<Texture>, ApiError> {
        self.get(id).ok_or_else(|| {
            ApiError::not_found(format!(
                "texture {id:?} is not open (the server keeps the {MAX_TEXTURES} most recently \
                 used textures): open it again with POST /api/texture"
            ))
        })
    }

    /// Keep `t` as the most recently used texture, dropping the least recently used beyond
    /// [`MAX_TEXTURES`].
    pub fn insert(&self, t: Arc<Texture>) {
        let mut open = self.open.lock().unwrap_or_else(|e| e.into_inner());
        open.retain(|x| x.id != t.id);
        open.push_back(t);
        while open.len() > MAX_TEXTURES {
            if let Some(gone) = open.pop_front() {
                let mut cached = self.shader.lock().unwrap_or_else(|e| e.into_inner());
                if cached.as_ref().is_some_and(|c| c.id == gone.id) {
                    *cached = None;
                }
            }
        }
    }

    /// The NDF-mapped shader of `texture` with the facet transfer, diffuse term and form of
    /// `surface`, `texels_per_uv` cells per unit of texture coordinate and horizon shadowing when
    /// `shadowing` (`meso_render::NdfMapped::new`): the one of the last call when it asked for
    /// the same, else built (blocking) and kept instead. Returns the shader and whether it came
    /// from the cache.
    ///
    /// # Errors
    /// `NdfMapped::new`'s message (a bad scale, shadowing without horizon statistics).
    pub fn shader(
        &self,
        texture: &Texture,
        surface: &meso_core::material::Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<(Arc<meso_render::NdfMapped>, bool), String> {
        let key = format!(
            "{:?}|{:?}|{:?}|{}|{shadowing}",
            surface.transfer,
            surface.diffuse,
            surface.form,
            texels_per_uv.to_bits()
        );
        if let Some(c) = self
            .shader
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            .filter(|c| c.id == texture.id && c.key == key)
        {
            return Ok((c.shader.clone(), true));
        }
        let shader = Arc::new(meso_render::NdfMapped::new(
            &texture.pyramid,
            surface,
            texels_per_uv,
            shadowing,
        )?);
        *self.shader.lock().unwrap_or_else(|e| e.into_inner()) = Some(CachedShader {
            id: texture.id.clone(),
            key,
            shader: shader.clone(),
        });
        Ok((shader, false))
    }

    /// The ids of the open textures, least recently used first.
    #[must_use]
    pub fn ids(&self) -> Vec<String> {
        let open = self.open.lock().unwrap_or_else(|e| e.into_inner());
        open.iter().map(|t| t.id.clone()).collect()
    }
}

/// The checked parameters of an upload.
#[derive(Clone, Debug)]
pub struct Checked {
    kind: TextureKind,
    name: String,
    input: Option<InputKind>,
    params: ExtractParams,
}

impl Checked {
    /// The id of these bytes under these parameters (module docs).
    #[must_use]
    pub fn id(&self, bytes: &[u8]) -> String {
        let mut h = Sha256::new();
        h.update(format!("{:?}|{:?}|{:?}|", self.kind, self.input, self.params).as_bytes());
        h.update(bytes);
        let d = h.finalize();
        d.iter().take(8).map(|b| format!("{b:02x}")).collect()
    }
}

/// A file name without folders or odd characters, at most [`MAX_NAME_CHARS`] long.
fn clean_name(name: Option<&str>, kind: TextureKind) -> String {
    let base = name
        .and_then(|n| n.rsplit(['/', '\\']).next())
        .unwrap_or("")
        .chars()
        .filter(|c| !c.is_control())
        .take(MAX_NAME_CHARS)
        .collect::<String>();
    let base = base.trim();
    if base.is_empty() || base == "." || base == ".." {
        match kind {
            TextureKind::Map => "texture.map".into(),
            _ => "texture.png".into(),
        }
    } else {
        base.to_owned()
    }
}

fn choice<'a>(
    key: &str,
    v: Option<&'a str>,
    known: &[&'a str],
) -> Result<Option<&'a str>, ApiError> {
    match v {
        None => Ok(None),
        Some(s) if known.contains(&s) => Ok(Some(s)),
        Some(s) => Err(ApiError::bad_request(format!(
            "{key}: unknown {s:?} (known: {})",
            known.join(", ")
        ))),
    }
}

/// Check the parameters of an upload (query of `POST /api/texture`).
///
/// # Errors
/// 400 naming a missing, unknown or out-of-range parameter, or one that does not apply to the
/// kind.
pub fn check_params(p: &UploadParams) -> Result<Checked, ApiError> {
    let kind = p.kind.ok_or_else(|| {
        ApiError::bad_request("kind: missing (height, normal or map) in the query string")
    })?;
    let name = clean_name(p.name.as_deref(), kind);
    let not_for = |key: &str, given: bool, what: &str| -> Result<(), ApiError> {
        if given {
            Err(ApiError::bad_request(format!(
                "{key}: does not apply to {what}"
            )))
        } else {
            Ok(())
        }
    };
    let mut params = ExtractParams::default();
    if let Some(k) = p.max_lobes {
        if !(1..=meso_maps::limits::MAX_LOBES).contains(&k) {
            return Err(ApiError::bad_request(format!(
                "max_lobes: must be between 1 and {}, got {k}",
                meso_maps::limits::MAX_LOBES
            )));
        }
        params = params.with_max_lobes(k);
    }
    let positive = |key: &str, v: Option<f64>| -> Result<f64, ApiError> {
        match v {
            None => Err(ApiError::bad_request(format!(
                "{key}: a height map needs texel_size and height_scale (numbers > 0, one \
                 length unit)"
            ))),
            Some(x) if x.is_finite() && x > 0.0 && x < 1e12 => Ok(x),
            Some(x) => Err(ApiError::bad_request(format!(
                "{key}: must be a finite number > 0, got {x}"
            ))),
        }
    };
    let input = match kind {
        TextureKind::Height => {
            not_for("convention", p.convention.is_some(), "a height map")?;
            let texel_size = positive("texel_size", p.texel_size)?;
            let height_scale = positive("height_scale", p.height_scale)?;
            let border = match choice("border", p.border.as_deref(), &["wrap", "clamp"])? {
                Some("clamp") => Border::Clamp,
                _ => Border::Wrap,
            };
            if choice("normals", p.normals.as_deref(), &["triangles", "central"])?
                == Some("central")
            {
                params.normal_mode = NormalMode::CentralDifferences;
            }
            Some(InputKind::Heights {
                texel_size,
                height_scale,
                border,
            })
        }
        TextureKind::Normal => {
            for (k, given) in [
                ("texel_size", p.texel_size.is_some()),
                ("height_scale", p.height_scale.is_some()),
                ("border", p.border.is_some()),
                ("normals", p.normals.is_some()),
            ] {
                not_for(k, given, "a normal map (it has no heights)")?;
            }
            let conv = match choice("convention", p.convention.as_deref(), &["gl", "dx"])? {
                Some("dx") => NormalConvention::Dx,
                _ => NormalConvention::Gl,
            };
            Some(InputKind::Normals(conv))
        }
        TextureKind::Map => {
            for (k, given) in [
                ("texel_size", p.texel_size.is_some()),
                ("height_scale", p.height_scale.is_some()),
                ("convention", p.convention.is_some()),
                ("max_lobes", p.max_lobes.is_some()),
                ("border", p.border.is_some()),
                ("normals", p.normals.is_some()),
            ] {
                not_for(
                    k,
                    given,
                    "a map file (it stores the parameters it was extracted with)",
                )?;
            }
            None
        }
    };
    Ok(Checked {
        kind,
        name,
        input,
        params,
    })
}

/// A meso-maps error as an API error: 413 for what is too large (size limits, memory budget),
/// 400 otherwise.
fn map_err(e: MapError) -> ApiError {
    match e {
        MapError::TooLarge { .. } | MapError::Budget(_) | MapError::OutOfMemory { .. } => {
            ApiError::too_large(e.to_string())
        }
        other => ApiError::bad_request(other.to_string()),
    }
}

/// Decode an upload and extract its pyramid (blocking: seconds for a 1024² map; call from
/// `spawn_blocking`). `id` is [`Checked::id`] of the same bytes.
///
/// # Errors
/// 400 for an empty, corrupt or invalid file; 413 for one above the limits (module docs).
pub fn open(bytes: &[u8], c: &Checked, id: String) -> Result<Texture, ApiError> {
    let t0 = std::time::Instant::now();
    let name = Path::new(&c.name);
    if bytes.is_empty() {
        return Err(ApiError::bad_request(format!(
            "{}: the upload is empty (0 bytes): send the file's bytes as the request body",
            c.name
        )));
    }
    let too_large = |what: String| {
        ApiError::too_large(format!(
            "{}: {what}; the editor opens textures up to {MAX_TEXTURE_SIDE} samples a side and \
             {MAX_TEXTURE_SAMPLES} samples in all (1024 × 1024): extract larger maps with \
             `meso extract` and render them with `meso render`",
            c.name
        ))
    };
    let (pyramid, warnings) = match c.input {
        None => {
            meso_core::budget::check_named(
                &c.name,
                "reading the map file",
                meso_maps::format::read_bytes(bytes.len() as u64),
            )
            .map_err(|e| ApiError::too_large(e.to_string()))?;
            let p = Pyramid::from_bytes(name, bytes).map_err(map_err)?;
            let (cols, rows) = (p.levels[0].cols as u64, p.levels[0].rows as u64);
            if cols.saturating_mul(rows) > MAX_TEXTURE_SAMPLES {
                return Err(too_large(format!(
                    "the map file's finest level has {cols} × {rows} texels"
                )));
            }
            (p, Vec::new())
        }
        Some(kind) => {
            let h = meso_maps::heightmap::probe_bytes(name, bytes).map_err(map_err)?;
            if h.width > MAX_TEXTURE_SIDE
                || h.height > MAX_TEXTURE_SIDE
                || h.pixels() > MAX_TEXTURE_SAMPLES
            {
                return Err(too_large(format!(
                    "the image is {} × {}",
                    h.width, h.height
                )));
            }
            let (w, hh) = (h.width as usize, h.height as usize);
            let estimate = match kind {
                InputKind::Normals(_) => h.normal_map_bytes() + extract_bytes(w, hh, 1, 0),
                InputKind::Heights { border, .. } => {
                    let (cols, rows) = if border == Border::Clamp {
                        (w.saturating_sub(1), hh.saturating_sub(1))
                    } else {
                        (w, hh)
                    };
                    let per_cell = match c.params.normal_mode {
                        NormalMode::Triangles => 2,
                        NormalMode::CentralDifferences => 1,
                    };
                    h.height_map_then(extract_bytes(cols, rows, per_cell, w * hh))
                }
            };
            meso_core::budget::check_named(&c.name, "extracting the NDF pyramid", estimate)
                .map_err(|e| ApiError::too_large(e.to_string()))?;
            let (input, warnings) = load_bytes(name, bytes, kind).map_err(map_err)?;
            let p = extract(input.source(), &c.params, &mut |_| {})
                .map_err(|e| map_err(e).with_prefix(&c.name))?;
            (p, warnings)
        }
    };
    Ok(Texture {
        id,
        name: c.name.clone(),
        kind: c.kind,
        pyramid: Arc::new(pyramid),
        warnings,
        extract_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

impl ApiError {
    /// The same error with `prefix: ` before its message.
    #[must_use]
    fn with_prefix(mut self, prefix: &str) -> ApiError {
        self.message = format!("{prefix}: {}", self.message);
        self
    }
}

/// Resolves the `kind = "map"` NDF of a material naming an open texture (module docs): the
/// level (`"top"` or a number, default the top) and texel (`[row, col]`, default `[0, 0]` at the
/// top, required at a numbered level) of the `[ndf]` table, as for a map file.
pub struct TexelResolver<'a> {
    /// The texture.
    pub texture: &'a Texture,
}

fn index(v: &toml::Value, what: &str) -> Result<usize, MaterialError> {
    match v {
        toml::Value::Integer(i) if *i >= 0 => Ok(*i as usize),
        _ => Err(MaterialError(format!(
            "[ndf] {what}: expected an integer ≥ 0, got {v}"
        ))),
    }
}

impl NdfResolver for TexelResolver<'_> {
    fn resolve(
        &self,
        kind: &str,
        table: &toml::Table,
        _file: &Path,
    ) -> Result<ResolvedNdf, MaterialError> {
        if kind != "map" {
            return Err(MaterialError(format!(
                "[ndf] kind = \"{kind}\": an open texture is named by kind = \"map\""
            )));
        }
        let top = self.texture.pyramid.levels.len() - 1;
        let (level, numbered) = match table.get("level") {
            None => (top, false),
            Some(toml::Value::String(s)) if s == "top" => (top, false),
            Some(v @ toml::Value::Integer(_)) => (index(v, "level")?, true),
            Some(v) => {
                return Err(MaterialError(format!(
                    "[ndf] level: expected \"top\" or a level number, got {v}"
                )))
            }
        };
        let (row, col) = match table.get("texel") {
            None if numbered => {
                return Err(MaterialError(format!(
                    "[ndf]: level = {level} needs `texel = [row, col]`"
                )))
            }
            None => (0, 0),
            Some(v) => {
                let a = v.as_array().filter(|a| a.len() == 2).ok_or_else(|| {
                    MaterialError(format!("[ndf] texel: expected [row, col], got {v}"))
                })?;
                (index(&a[0], "texel row")?, index(&a[1], "texel column")?)
            }
        };
        self.texture.texel_ndf(level, row, col)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn height_params() -> UploadParams {
        UploadParams {
            kind: Some(TextureKind::Height),
            name: Some("../../etc/rock.png".into()),
            texel_size: Some(1.0),
            height_scale: Some(0.5),
            ..UploadParams::default()
        }
    }

    #[test]
    fn names_lose_their_folders() {
        let c = check_params(&height_params()).unwrap();
        assert_eq!(c.name, "rock.png");
        assert_eq!(clean_name(Some(".."), TextureKind::Map), "texture.map");
    }

    #[test]
    fn parameters_that_do_not_apply_are_refused() {
        let mut p = height_params();
        p.convention = Some("gl".into());
        let e = check_params(&p).unwrap_err();
        assert!(e.message.contains("convention"), "{}", e.message);
        let p = UploadParams {
            kind: Some(TextureKind::Map),
            max_lobes: Some(2),
            ..UploadParams::default()
        };
        let e = check_params(&p).unwrap_err();
        assert!(e.message.contains("max_lobes"), "{}", e.message);
        let mut p = height_params();
        p.height_scale = None;
        assert!(check_params(&p)
            .unwrap_err()
            .message
            .contains("height_scale"));
        let mut p = height_params();
        p.max_lobes = Some(9);
        assert!(check_params(&p).unwrap_err().message.contains("max_lobes"));
        assert!(check_params(&UploadParams::default())
            .unwrap_err()
            .message
            .contains("kind"));
    }

    #[test]
    fn ids_depend_on_bytes_and_parameters() {
        let a = check_params(&height_params()).unwrap();
        let mut p = height_params();
        p.max_lobes = Some(2);
        let b = check_params(&p).unwrap();
        assert_ne!(a.id(b"abc"), b.id(b"abc"));
        assert_ne!(a.id(b"abc"), a.id(b"abd"));
        assert_eq!(a.id(b"abc"), a.id(b"abc"));
        assert_eq!(a.id(b"abc").len(), 16);
    }

    #[test]
    fn the_store_drops_the_least_recently_used() {
        let map = meso_maps::fixtures::v_grooves(4, 2, 0.1, 0.05).unwrap();
        let pyr = Arc::new(
            extract(
                meso_maps::Source::Heights(&map),
                &ExtractParams::default(),
                &mut |_| {},
            )
            .unwrap(),
        );
        let s = TextureStore::new();
        let tex = |id: &str| {
            Arc::new(Texture {
                id: id.into(),
                name: "x.png".into(),
                kind: TextureKind::Height,
                pyramid: pyr.clone(),
                warnings: Vec::new(),
                extract_ms: 0.0,
            })
        };
        for k in 0..MAX_TEXTURES {
            s.insert(tex(&format!("t{k}")));
        }
        assert!(s.get("t0").is_some()); // t0 is now the most recent; t1 the least
        s.insert(tex("new"));
        assert!(s.get("t1").is_none());
        assert!(s.get("t0").is_some());
        assert_eq!(s.ids().len(), MAX_TEXTURES);
        assert_eq!(s.require("t1").unwrap_err().status.as_u16(), 404);
        assert_eq!(tex("a").map_file_name(), "x.map");
    }
}
