//! Material integration: [`MapsResolver`] loads the `[ndf]` tables of material files whose NDF
//! comes from a height map or a map file (`meso_core::material::NdfResolver`).
//!
//! # `kind = "heightmap"`
//! | key | value |
//! | --- | --- |
//! | `file` | the height map (PNG, TIFF, EXR), relative to the material file |
//! | `texel_size` | distance between samples `S` (> 0, length units) |
//! | `height_scale` | height of the full code range `H` (> 0, same unit) |
//! | `max_lobes` | lobes per texel, 1–8 (default 4, 6 on a map of faces and walls: `ExtractParams::walls_max_lobes`) |
//! | `border` | `"wrap"` (default) or `"clamp"` |
//! | `normals` | `"triangles"` (default) or `"central"` (central differences) |
//! | `represent` | `"facets"` (default: every facet normal of the map, binned to ≈ 0.8°, as a delta sum with each bin's own visibility, `shadowing = "visibility"`: within 0.1–6% of the ray-traced BRDF where the lobes miss by 3–88%, docs/heightmaps.md; see [`MapsResolver::heightmap_facets`]) or `"lobes"` (the pyramid's top-level fitted Phong peaks, with Smith or horizon masking) |
//!
//! With `represent = "lobes"` the pyramid is extracted once per (file, modification time,
//! parameters) and cached in the resolver, and on disk per (file content, parameters)
//! ([`crate::pyramid_cache`]); the NDF is the top level's lobes (the whole map).
//!
//! # `kind = "map"`
//! | key | value |
//! | --- | --- |
//! | `file` | a map file written by `meso extract` (docs/map-format.md) |
//! | `level` | `"top"` (default) or a level number (0 = finest) |
//! | `texel` | `[row, col]` of the texel; required with a numbered level (default `[0, 0]` at the top) |
//!
//! Unknown keys are errors naming them. The resolved NDF is `Ndf::PhongPeaks` (the fitted lobes
//! are the Eq. 1 area density, see `crate::facets`), the horizon model is the texel's
//! [`HorizonStats`] (for the top level: the statistics merged over the whole map) as
//! `G(i, o) = V(i)·V(o)`, and the default form is the microfacet form.

use crate::facet_ndf::{facets_bytes, facets_with_visibility_progress};
use crate::facets::NormalMode;
use crate::heightmap::{Border, HeightMap};
use crate::horizon::{HorizonStats, HorizonVisibility};
use crate::pyramid::{extract, ExtractParams, Pyramid, Source};
use meso_core::convolution::Form;
use meso_core::material::{MaterialError, NdfResolver, ResolvedNdf, VisibilityModel};
use meso_core::ndf::{Ndf, PhongPeaks};
use meso_core::transfer::Transfer;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Check the memory of loading the height map `file` and of `task` (its estimate from the
/// image's header: `work(cols, rows, per_cell, samples)`) against the budget.
fn check_heightmap_budget(
    file: &Path,
    p: &HeightmapParams,
    task: &str,
    work: impl Fn(usize, usize, usize, usize) -> u64,
) -> Result<(), MaterialError> {
    if !std::fs::metadata(file).is_ok_and(|m| m.is_file()) {
        return Ok(());
    }
    let Ok(h) = crate::heightmap::probe(file) else {
        return Ok(());
    };
    let (w, hgt) = (h.width as usize, h.height as usize);
    let (cols, rows) = match p.border {
        Border::Wrap => (w, hgt),
        Border::Clamp => (w.saturating_sub(1), hgt.saturating_sub(1)),
    };
    let per_cell = match p.normal_mode {
        NormalMode::Triangles => 2,
        NormalMode::CentralDifferences => 1,
    };
    let estimate = h.height_map_then(work(cols, rows, per_cell, w * hgt));
    meso_core::budget::check(file, task, estimate).map_err(|e| MaterialError(format!("[ndf]: {e}")))
}

/// The keys that describe a height map and its pyramid in a `kind = "heightmap"` table (besides
/// `kind` and `represent`); `[texture]` tables of scene files take the same ones.
pub const HEIGHTMAP_KEYS: [&str; 6] = [
    "file",
    "texel_size",
    "height_scale",
    "max_lobes",
    "border",
    "normals",
];

/// The parameters of a `kind = "heightmap"` table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeightmapParams {
    /// Texel size `S` (length units).
    pub texel_size: f64,
    /// Height scale `H` (length units).
    pub height_scale: f64,
    /// Largest number of lobes per texel, when the table gives it (on every map); `None`: the
    /// extraction's default, 4, or [`crate::WALLS_MAX_LOBES`] on a map of faces and walls
    /// ([`ExtractParams::max_lobes_for`]).
    pub max_lobes: Option<usize>,
    /// Border mode.
    pub border: Border,
    /// How normals are derived.
    pub normal_mode: NormalMode,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct CacheKey {
    path: PathBuf,
    len: u64,
    modified: Option<std::time::SystemTime>,
    texel_size: u64,
    height_scale: u64,
    max_lobes: Option<usize>,
    clamp: bool,
    central: bool,
}

/// An `NdfResolver` for `[ndf] kind = "heightmap"` and `kind = "map"` (see the module docs).
/// Extracted pyramids are cached per resolver.
#[derive(Default)]
pub struct MapsResolver {
    cache: Mutex<HashMap<CacheKey, Arc<Pyramid>>>,
    disk_hits: std::sync::atomic::AtomicUsize,
    progress: Option<ExtractProgress>,
    warnings: Option<Warnings>,
    /// `(file, warning)` pairs already reported (each once per resolver).
    warned: Mutex<std::collections::HashSet<(PathBuf, String)>>,
}

/// A hook for what loading an input found and corrected (a colour image given as heights,
/// 8-bit terraces dequantised, normal-map texels tilted up to the horizon, …): the input's path
/// and one line. The CLI prints them on standard error; without a hook they are dropped.
pub type Warnings = Arc<dyn Fn(&Path, &str) + Send + Sync>;

/// A progress hook for pyramid extractions: the height map's path and the extraction's
/// [`crate::pyramid::Progress`] (called from the extracting thread). `represent = "facets"`
/// materials report their horizon march through it too (task `Facets`, `levels = 0`,
/// `work_done` counting rows of cells; called from rayon's worker threads), and
/// [`MapsResolver::read_map_file`] its reading of a map file (task `Read`, bytes).
pub type ExtractProgress = Arc<dyn Fn(&Path, crate::pyramid::Progress) + Send + Sync>;

fn merr<T>(msg: impl Into<String>) -> Result<T, MaterialError> {
    Err(MaterialError(msg.into()))
}

fn check_keys(table: &toml::Table, known: &[&str]) -> Result<(), MaterialError> {
    let unknown: Vec<&str> = table
        .keys()
        .map(String::as_str)
        .filter(|k| !known.contains(k))
        .collect();
    if unknown.is_empty() {
        Ok(())
    } else {
        merr(format!(
            "[ndf]: unknown key{} {} (known here: {})",
            if unknown.len() > 1 { "s" } else { "" },
            unknown
                .iter()
                .map(|k| format!("`{k}`"))
                .collect::<Vec<_>>()
                .join(", "),
            known.join(", ")
        ))
    }
}

fn positive_number(table: &toml::Table, key: &str) -> Result<f64, MaterialError> {
    let v = match table.get(key) {
        None => {
            return merr(format!(
                "[ndf]: kind = \"heightmap\" needs `{key}` (a number > 0)"
            ))
        }
        Some(toml::Value::Float(f)) => *f,
        Some(toml::Value::Integer(i)) => *i as f64,
        Some(v) => return merr(format!("[ndf] {key}: expected a number, got {v}")),
    };
    if !(v.is_finite() && v > 0.0) {
        return merr(format!("[ndf] {key}: must be a finite number > 0, got {v}"));
    }
    Ok(v)
}

fn integer(v: &toml::Value, what: &str) -> Result<usize, MaterialError> {
    match v {
        toml::Value::Integer(i) if *i >= 0 => Ok(*i as usize),
        _ => merr(format!("[ndf] {what}: expected an integer ≥ 0, got {v}")),
    }
}

fn choice<'a>(
    table: &'a toml::Table,
    key: &str,
    known: &[&'a str],
) -> Result<Option<&'a str>, MaterialError> {
    match table.get(key) {
        None => Ok(None),
        Some(toml::Value::String(s)) if known.contains(&s.as_str()) => Ok(Some(s.as_str())),
        Some(v) => merr(format!(
            "[ndf] {key}: expected one of {}, got {v}",
            known
                .iter()
                .map(|k| format!("\"{k}\""))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Turn a texel's lobes and horizon statistics into a [`ResolvedNdf`].
fn resolved(
    lobes: &[meso_core::ndf::PhongLobe],
    horizon: Option<HorizonStats>,
    what: &str,
) -> Result<ResolvedNdf, MaterialError> {
    if lobes.is_empty() {
        return merr(format!("{what}: the texel has no lobes"));
    }
    let ndf = Ndf::PhongPeaks(
        PhongPeaks::new(lobes.to_vec()).map_err(|e| MaterialError(format!("{what}: {e}")))?,
    );
    Ok(ResolvedNdf {
        ndf,
        horizon: horizon.map(|h| Arc::new(HorizonVisibility(h)) as Arc<dyn VisibilityModel>),
        default_form: Form::Microfacet,
    })
}

impl std::fmt::Debug for MapsResolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MapsResolver")
            .field("cached_pyramids", &self.cache.lock().map_or(0, |c| c.len()))
            .field("progress", &self.progress.is_some())
            .finish()
    }
}

impl MapsResolver {
    /// A resolver with an empty cache.
    #[must_use]
    pub fn new() -> MapsResolver {
        MapsResolver::default()
    }

    /// Report the progress of every pyramid extraction (a 1024² height map takes seconds), facet
    /// horizon march and map-file read ([`MapsResolver::read_map_file`]) to `progress`
    /// ([`crate::Progress::task`] says which).
    #[must_use]
    pub fn with_progress(mut self, progress: ExtractProgress) -> MapsResolver {
        self.progress = Some(progress);
        self
    }

    /// A map file written by `meso extract`, held as compactly as the memory budget asks
    /// ([`Pyramid::read_compact`]), its reading reported to this resolver's progress
    /// ([`crate::ProgressTask::Read`]).
    ///
    /// # Errors
    /// As [`Pyramid::read`].
    pub fn read_map_file(&self, path: &Path) -> Result<Pyramid, crate::MapError> {
        match &self.progress {
            Some(f) => Pyramid::read_compact_reporting(path, &mut |p| f(path, p)),
            None => Pyramid::read_compact(path),
        }
    }

    /// Report what loading inputs finds and corrects to `warnings` (each warning once per file
    /// and resolver). Inputs read from a cache (a pyramid or facet cache hit) are not decoded,
    /// so they report nothing.
    #[must_use]
    pub fn with_warnings(mut self, warnings: Warnings) -> MapsResolver {
        self.warnings = Some(warnings);
        self
    }

    /// Report ([`MapsResolver::warn`]) when `material`, loaded from `file` through this
    /// resolver, asks for the light between facets (`interreflection = true`) and will not get
    /// it traced from the geometry: its visibility model cannot (a clamped map, central
    /// normals, mirror facets:
    /// `VisibilityModel::interreflection_solved`), and then Lambert facets get the coarser
    /// sky-view estimate and others the single bounce only; or the caller evaluates
    /// `interactive`ly (the renderer: `meso_core::shading::Policy::Interactive`), which keeps
    /// the sky-view estimate for Lambert facets (said in docs/heightmaps.md) and leaves the
    /// light between glossy facets out (said here, since the picture would lack it silently).
    pub fn warn_estimated_interreflection(
        &self,
        file: &Path,
        material: &meso_core::material::Material,
        interactive: bool,
    ) {
        use meso_core::material::ShadowingKind;
        if material.shadowing != ShadowingKind::VisibilityInterreflected {
            return;
        }
        let lambert = matches!(material.transfer, Transfer::Lambert { .. });
        if let Some(Err(why)) = material
            .horizon
            .as_ref()
            .map(|h| h.interreflection_solved(&material.transfer))
        {
            let instead = if lambert {
                "it is estimated from the facets' sky views instead (coarser: docs/heightmaps.md)"
            } else {
                "it is left out: only the single bounce is computed (docs/heightmaps.md)"
            };
            self.warn(file, &format!("interreflection = true: {why}; {instead}"));
        } else if interactive && !lambert {
            self.warn(
                file,
                "interreflection = true: the renderer leaves out the light between glossy \
                 facets (it is path traced per direction pair, too slow per pixel); \
                 `meso brdf` includes it",
            );
        }
    }

    /// Report `progress` of work on the input `file` (e.g. a renderer's tables,
    /// [`crate::ProgressTask::Tables`]) to the hook of [`MapsResolver::with_progress`], if any.
    pub fn report(&self, file: &Path, progress: crate::pyramid::Progress) {
        if let Some(f) = &self.progress {
            f(file, progress);
        }
    }

    /// Whether a progress hook is set ([`MapsResolver::with_progress`]).
    #[must_use]
    pub fn reports_progress(&self) -> bool {
        self.progress.is_some()
    }

    /// Report `warning` about the input `file` to the hook of [`MapsResolver::with_warnings`],
    /// unless this resolver reported it before.
    pub fn warn(&self, file: &Path, warning: &str) {
        if let Some(hook) = &self.warnings {
            let fresh = self
                .warned
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .insert((file.to_path_buf(), warning.to_owned()));
            if fresh {
                hook(file, warning);
            }
        }
    }

    /// [`MapsResolver::heightmap`], its load warnings reported ([`MapsResolver::warn`]).
    ///
    /// # Errors
    /// As [`MapsResolver::heightmap`].
    pub fn load_heightmap(
        &self,
        table: &toml::Table,
        file: &Path,
    ) -> Result<HeightMap, MaterialError> {
        let map = Self::heightmap(table, file)?;
        for w in map.warnings() {
            self.warn(file, w);
        }
        Ok(map)
    }

    /// Parse and check a `kind = "heightmap"` table (module docs).
    ///
    /// # Errors
    /// Unknown keys and missing or bad values, as a message naming them.
    pub fn heightmap_params(table: &toml::Table) -> Result<HeightmapParams, MaterialError> {
        let known: Vec<&str> = std::iter::once("kind")
            .chain(HEIGHTMAP_KEYS)
            .chain(["represent"])
            .collect();
        check_keys(table, &known)?;
        choice(table, "represent", &["lobes", "facets"])?;
        let texel_size = positive_number(table, "texel_size")?;
        let height_scale = positive_number(table, "height_scale")?;
        let max_lobes = match table.get("max_lobes") {
            None => None,
            Some(v) => {
                let k = integer(v, "max_lobes")?;
                if !(1..=crate::fit::MAX_LOBES).contains(&k) {
                    return merr(format!(
                        "[ndf] max_lobes: must be between 1 and {}, got {k}",
                        crate::fit::MAX_LOBES
                    ));
                }
                Some(k)
            }
        };
        let border = match choice(table, "border", &["wrap", "clamp"])? {
            Some("clamp") => Border::Clamp,
            _ => Border::Wrap,
        };
        let normal_mode = match choice(table, "normals", &["triangles", "central"])? {
            Some("central") => NormalMode::CentralDifferences,
            _ => NormalMode::Triangles,
        };
        Ok(HeightmapParams {
            texel_size,
            height_scale,
            max_lobes,
            border,
            normal_mode,
        })
    }

    /// Load the height map of a `kind = "heightmap"` table.
    ///
    /// # Errors
    /// Bad keys or values, and every height-map error, as a message.
    pub fn heightmap(table: &toml::Table, file: &Path) -> Result<HeightMap, MaterialError> {
        let p = Self::heightmap_params(table)?;
        HeightMap::load(file, p.texel_size, p.height_scale, p.border)
            .map_err(|e| MaterialError(format!("[ndf]: {e}")))
    }

    /// The pyramid of a `kind = "heightmap"` table: from this resolver's memory, else from the
    /// disk cache ([`crate::pyramid_cache`]), else extracted (and stored there). Always the
    /// pyramid a map file would hold (`f32` lobes), whichever answered.
    ///
    /// # Errors
    /// Unknown keys, bad values, and every height-map or extraction error, as a message.
    pub fn heightmap_pyramid(
        &self,
        table: &toml::Table,
        file: &Path,
    ) -> Result<Arc<Pyramid>, MaterialError> {
        let HeightmapParams {
            texel_size,
            height_scale,
            max_lobes,
            border,
            normal_mode,
        } = Self::heightmap_params(table)?;
        let meta = std::fs::metadata(file)
            .map_err(|e| MaterialError(format!("[ndf] file {}: {e}", file.display())))?;
        let key = CacheKey {
            path: std::fs::canonicalize(file).unwrap_or_else(|_| file.to_path_buf()),
            len: meta.len(),
            modified: meta.modified().ok(),
            texel_size: texel_size.to_bits(),
            height_scale: height_scale.to_bits(),
            max_lobes,
            clamp: border == Border::Clamp,
            central: normal_mode == NormalMode::CentralDifferences,
        };
        if let Some(p) = self.cache_get(&key) {
            return Ok(p);
        }
        let mut params = ExtractParams {
            normal_mode,
            ..ExtractParams::default()
        };
        if let Some(k) = max_lobes {
            params = params.with_max_lobes(k);
        }
        // From the disk cache (`crate::pyramid_cache`) when it has this map and parameters.
        let got = crate::pyramid_cache::pyramid_cached(
            file,
            texel_size,
            height_scale,
            border,
            &params,
            || {
                check_heightmap_budget(
                    file,
                    &HeightmapParams {
                        texel_size,
                        height_scale,
                        max_lobes,
                        border,
                        normal_mode,
                    },
                    "extracting the NDF pyramid",
                    crate::pyramid::extract_bytes,
                )?;
                let map = HeightMap::load(file, texel_size, height_scale, border)
                    .map_err(|e| MaterialError(format!("[ndf]: {e}")))?;
                let pyramid = extract(Source::Heights(&map), &params, &mut |p| {
                    if let Some(f) = &self.progress {
                        f(file, p);
                    }
                })
                .map_err(|e| MaterialError(format!("[ndf] {}: {e}", file.display())))?;
                Ok((pyramid, map.warnings().to_vec()))
            },
        )?;
        // Said whether the cache answered or not: the entry keeps them.
        for w in &got.warnings {
            self.warn(file, w);
        }
        let (pyr, hit) = (got.value, got.hit);
        if hit {
            self.disk_hits
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        let pyr = Arc::new(pyr);
        if let Ok(mut c) = self.cache.lock() {
            c.insert(key, pyr.clone());
        }
        Ok(pyr)
    }

    /// How many pyramids this resolver read from the disk cache ([`crate::pyramid_cache`])
    /// instead of extracting them.
    #[must_use]
    pub fn disk_cache_hits(&self) -> usize {
        self.disk_hits.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// `represent = "facets"`: the whole map's facet normals as a delta sum (the multiple
    /// surface of Eq. 3, evaluated exactly by Eq. 4), merged per ≈ 0.8° bin of the fit's entry
    /// grid (each bin's area-weighted mean normal), with the map's horizon statistics as its
    /// masking model. Exact up to the binning where the fitted lobes are an approximation; the
    /// cost grows with the number of occupied bins (thousands for rough maps), and a mirror
    /// facet has no pointwise BRDF on a delta sum (use the lobes there).
    ///
    /// # Errors
    /// Bad keys or values, every height-map error.
    pub fn heightmap_facets(
        table: &toml::Table,
        file: &Path,
    ) -> Result<ResolvedNdf, MaterialError> {
        Self::heightmap_facets_with(table, file, None)
    }

    /// [`MapsResolver::heightmap_facets`], reporting the horizon march to `progress` as a
    /// [`crate::pyramid::Progress`] of task [`crate::pyramid::ProgressTask::Facets`] with
    /// `levels = 0` (no pyramid levels: `work_done` counts rows of cells marched, from 0 to
    /// `work_total`).
    fn heightmap_facets_with(
        table: &toml::Table,
        file: &Path,
        resolver: Option<&MapsResolver>,
    ) -> Result<ResolvedNdf, MaterialError> {
        let progress = resolver.and_then(|r| r.progress.as_ref());
        let p = Self::heightmap_params(table)?;
        check_heightmap_budget(
            file,
            &p,
            "building the facet NDF and its visibility",
            facets_bytes,
        )?;
        let what = format!("[ndf] {}", file.display());
        // Chunks finish on several threads: report only a count above every one reported.
        let highest = std::sync::atomic::AtomicUsize::new(0);
        let report = |done: usize, total: usize| {
            if done > 0 && highest.fetch_max(done, std::sync::atomic::Ordering::Relaxed) >= done {
                return;
            }
            if let Some(f) = progress {
                f(
                    file,
                    crate::pyramid::Progress {
                        task: crate::pyramid::ProgressTask::Facets,
                        levels_done: 0,
                        levels: 0,
                        texels_done: 0,
                        texels_total: 0,
                        work_done: done as u64,
                        work_total: total.max(1) as u64,
                    },
                );
            }
        };
        // Built once per map content and parameters, then read from the cache
        // (`crate::facet_cache`), which reports no progress: it takes a moment.
        let got = crate::facet_cache::facets_cached(
            file,
            p.texel_size,
            p.height_scale,
            p.border,
            p.normal_mode,
            || {
                HeightMap::load(file, p.texel_size, p.height_scale, p.border)
                    .map_err(|e| MaterialError(format!("[ndf]: {e}")))
            },
            |map| {
                facets_with_visibility_progress(map, p.normal_mode, &report)
                    .map_err(|e| MaterialError(format!("{what}: {e}")))
            },
        )?;
        // Said whether the cache answered or not: the entry keeps them.
        if let Some(r) = resolver {
            for w in &got.warnings {
                r.warn(file, w);
            }
        }
        let (ndf, mut vis) = got.value;
        if p.normal_mode == NormalMode::Triangles && p.border == Border::Wrap {
            // The light between facets (`interreflection = true`) traces the map again, once,
            // when a material first asks for it.
            let file = file.to_path_buf();
            vis.radiosity = Some(Arc::new(crate::radiosity::LazyRadiosity::new(move || {
                let map = HeightMap::load(&file, p.texel_size, p.height_scale, p.border)
                    .map_err(|e| e.to_string())?;
                // The ray tracer's own copy of the heights, budgeted before it is made (the
                // radiosity's patches are bounded by `MAX_PATCHES` on their own).
                meso_core::budget::check(
                    &file,
                    "tracing the light between the map's facets",
                    crate::gonio::Gonio::bytes(map.width(), map.height()),
                )
                .map_err(|e| e.to_string())?;
                Ok(map)
            })));
        }
        Ok(ResolvedNdf {
            ndf,
            horizon: Some(Arc::new(vis) as Arc<dyn VisibilityModel>),
            default_form: Form::Microfacet,
        })
    }

    fn cache_get(&self, key: &CacheKey) -> Option<Arc<Pyramid>> {
        self.cache.lock().ok()?.get(key).cloned()
    }

    fn resolve_map(&self, table: &toml::Table, file: &Path) -> Result<ResolvedNdf, MaterialError> {
        check_keys(table, &["kind", "file", "level", "texel"])?;
        // One texel's lobes are read: the pyramid held as compactly as the budget asks (the
        // same values as `Pyramid::read`, an 8192² map's level 0 by band).
        let pyr = self
            .read_map_file(file)
            .map_err(|e| MaterialError(format!("[ndf]: {e}")))?;
        let top = pyr.levels.len() - 1;
        let (level, numbered) = match table.get("level") {
            None => (top, false),
            Some(toml::Value::String(s)) if s == "top" => (top, false),
            Some(v @ toml::Value::Integer(_)) => (integer(v, "level")?, true),
            Some(v) => {
                return merr(format!(
                    "[ndf] level: expected \"top\" or a level number, got {v}"
                ))
            }
        };
        let (row, col) = match table.get("texel") {
            None if numbered => {
                return merr(format!("[ndf]: level = {level} needs `texel = [row, col]`"))
            }
            None => (0, 0),
            Some(v) => {
                let a = v.as_array().filter(|a| a.len() == 2).ok_or_else(|| {
                    MaterialError(format!("[ndf] texel: expected [row, col], got {v}"))
                })?;
                (
                    integer(&a[0], "texel row")?,
                    integer(&a[1], "texel column")?,
                )
            }
        };
        texel_ndf(&pyr, level, row, col, &file.display().to_string())
    }
}

/// The NDF of texel `(row, col)` of level `level` of a pyramid, as `[ndf] kind = "map"` resolves
/// it: the texel's fitted lobes as `Ndf::PhongPeaks`, its horizon statistics as the masking model
/// ([`HorizonVisibility`]), the microfacet form by default. `source` names the pyramid in errors
/// (a file, an uploaded texture).
///
/// # Errors
/// A level or texel out of range, or a texel without lobes, as a message naming them.
pub fn texel_ndf(
    pyr: &Pyramid,
    level: usize,
    row: usize,
    col: usize,
    source: &str,
) -> Result<ResolvedNdf, MaterialError> {
    let lv = pyr
        .level(level)
        .map_err(|e| MaterialError(format!("[ndf] level: {e} in {source}")))?;
    let what = format!("[ndf] {source} level {level} texel [{row}, {col}]");
    let lobes = lv
        .texel_lobes(row, col)
        .map_err(|e| MaterialError(format!("[ndf] texel: {e} in level {level}")))?;
    let horizon = lv
        .texel_horizon(row, col)
        .map_err(|e| MaterialError(format!("[ndf] texel: {e}")))?;
    resolved(&lobes, horizon, &what)
}

impl NdfResolver for MapsResolver {
    fn resolve(
        &self,
        kind: &str,
        table: &toml::Table,
        file: &Path,
    ) -> Result<ResolvedNdf, MaterialError> {
        match kind {
            "heightmap" if choice(table, "represent", &["lobes", "facets"])? != Some("lobes") => {
                Self::heightmap_facets_with(table, file, Some(self))
            }
            "heightmap" => {
                let pyr = self.heightmap_pyramid(table, file)?;
                let top = pyr.top();
                let lobes = top
                    .texel_lobes(0, 0)
                    .map_err(|e| MaterialError(format!("[ndf]: {e}")))?;
                let horizon = top
                    .texel_horizon(0, 0)
                    .map_err(|e| MaterialError(format!("[ndf]: {e}")))?;
                resolved(&lobes, horizon, &format!("[ndf] {}", file.display()))
            }
            "map" => self.resolve_map(table, file),
            other => merr(format!(
                "[ndf] kind = \"{other}\": not a height-map NDF (known: heightmap, map)"
            )),
        }
    }
}
