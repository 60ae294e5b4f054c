//! The checks and loaders shared by `meso export` and the Python package's `meso.export`, run
//! before the (slow) fit: the input is an image and not a map file, the output a folder, a lobe
//! pyramid (`--lobes`) lines up with the export's mip chain, a normal map is one (not a grey
//! height map), and a material file's export takes no map option.

use crate::export::{self, ExtraBytes, Inputs};
use crate::mips;
use crate::ExportError;
use meso_maps::{NormalConvention, NormalMap};
use std::path::Path;

/// Files of an export in memory: `(file name, bytes)`, as [`export::Export::files`].
pub type Files = Vec<(String, Vec<u8>)>;

/// Refuse a map file (`meso extract`'s output) given where an image is expected, saying what to
/// do instead.
///
/// # Errors
/// [`ExportError::Invalid`] when `path` is a meso map file.
pub fn refuse_map_file(path: &Path) -> Result<(), ExportError> {
    if meso_maps::format::is_map_file(path) {
        let p = path.display();
        return Err(ExportError::Invalid(format!(
            "{p} is a meso map file (written by `meso extract`), not an image: export the image \
             it was extracted from (`meso export IMAGE …`), and pass the map as `--lobes {p}`"
        )));
    }
    Ok(())
}

/// Refuse an output path that exists and is not a folder (the export writes a folder of files).
///
/// # Errors
/// [`ExportError::Invalid`] naming the path.
pub fn check_out_dir(dir: &Path) -> Result<(), ExportError> {
    if dir.exists() && !dir.is_dir() {
        return Err(ExportError::Invalid(format!(
            "{}: an existing file; the export's output (--out) must be a folder (it writes \
             several files into it)",
            dir.display()
        )));
    }
    Ok(())
}

/// What a height map passed as a normal map needs, for the messages of [`load_normal_map`].
const HEIGHT_HINT: &str = "it looks like a height map: give --texel-size and --height-scale \
                           (Python: texel_size=, height_scale=) to export it from its heights";

/// Load a tangent-space normal map as `meso export` does ([`NormalMap::load`]), saying when the
/// image looks like a height map instead: a single-channel grey image (no normal map is one,
/// [`meso_maps::heightmap::GREY_NOT_NORMALS`]), or a texel that decodes to no direction (the
/// mid-grey of a height map reads as the "no data" grey of a normal map).
///
/// # Errors
/// [`ExportError::Invalid`] for a grey image or a texel that is no direction (with the hint);
/// the loader's other errors.
pub fn load_normal_map(
    path: &Path,
    convention: NormalConvention,
) -> Result<NormalMap, ExportError> {
    NormalMap::load(path, convention).map_err(|e| match e {
        meso_maps::MapError::Decode { path, message }
            if message == meso_maps::heightmap::GREY_NOT_NORMALS =>
        {
            ExportError::Invalid(format!(
                "{}: a single-channel grey image, read as a normal map; {HEIGHT_HINT}",
                path.display()
            ))
        }
        meso_maps::MapError::Decode { path, message }
            if message.contains("is not a normal") || message.contains("usable direction") =>
        {
            ExportError::Invalid(format!(
                "{}: read as a normal map, {message}; {HEIGHT_HINT}",
                path.display()
            ))
        }
        e => e.into(),
    })
}

/// The grid of a lobe pyramid's map file, from its header alone
/// ([`meso_maps::format::peek_sizes`]: magic, version, then the source's `width`, `height` in
/// samples and level 0's `cols`, `rows` in cells): `(width, height, cols, rows)`. The rest of
/// the file is validated when it is read ([`meso_maps::Pyramid::read_compact`]).
///
/// # Errors
/// [`ExportError::Invalid`] for a file that is not a map file or whose header is bad (too
/// short, an unknown version, sizes out of range); [`ExportError::Io`] when it cannot be read.
pub fn lobe_grid(path: &Path) -> Result<(usize, usize, usize, usize), ExportError> {
    if path.is_file() && !meso_maps::format::is_map_file(path) {
        return Err(ExportError::Invalid(format!(
            "{}: not a meso map file (--lobes takes the map file `meso extract` wrote)",
            path.display()
        )));
    }
    meso_maps::format::peek_sizes(path).map_err(|e| match e {
        meso_maps::MapError::Io { path, source } => ExportError::Io { path, source },
        e => ExportError::Invalid(format!(
            "{e} (--lobes takes the map file `meso extract` wrote)"
        )),
    })
}

/// Sizes `(cols, rows)` of a lobe pyramid's levels from level 0's `cols × rows`: halved rounding
/// up, down to 1 × 1 (the pyramid's own rule, [`meso_maps::pyramid::level_sizes`]).
#[must_use]
pub fn lobe_level_sizes(cols: usize, rows: usize) -> Vec<(usize, usize)> {
    meso_maps::pyramid::level_sizes(cols, rows).collect()
}

/// Sizes `(width, height)` of the export's mip levels ([`mips::level_size`]: halved rounding
/// down, the KTX2 rule).
#[must_use]
pub fn mip_level_sizes(width: usize, height: usize) -> Vec<(usize, usize)> {
    (0..mips::level_count(width, height))
        .map(|k| mips::level_size(width, height, k))
        .collect()
}

/// Check that a lobe pyramid of a `width × height` map, level 0 `cols × rows` cells, has
/// exactly the export's mip levels (same count, same size at every level), so that
/// `lobes<k>_mip<l>.png` is mip level `l`.
///
/// # Errors
/// [`ExportError::Invalid`] naming `path`, the sizes that differ and what to do.
pub fn check_lobe_grid(
    path: &Path,
    (pw, ph, cols, rows): (usize, usize, usize, usize),
    width: usize,
    height: usize,
) -> Result<(), ExportError> {
    let p = path.display();
    if (pw, ph) != (width, height) {
        return Err(ExportError::Invalid(format!(
            "{p}: the lobe pyramid is of a {pw} × {ph} map, the export's map is \
             {width} × {height}; pass the pyramid `meso extract` wrote for this map"
        )));
    }
    if (cols, rows) != (width, height) {
        return Err(ExportError::Invalid(format!(
            "{p}: the lobe pyramid's level 0 is {cols} × {rows} cells, the export's level 0 \
             {width} × {height} texels (the pyramid was extracted with --clamp, one cell between \
             each pair of samples); extract it with the export's wrapped border (`meso extract` \
             without --clamp) for --lobes"
        )));
    }
    let lobes = lobe_level_sizes(cols, rows);
    let mips = mip_level_sizes(width, height);
    if lobes != mips {
        let l = lobes
            .iter()
            .zip(&mips)
            .position(|(a, b)| a != b)
            .unwrap_or(lobes.len().min(mips.len()));
        let at = |v: &[(usize, usize)]| {
            v.get(l)
                .map_or("none".to_string(), |(c, r)| format!("{c} × {r}"))
        };
        return Err(ExportError::Invalid(format!(
            "{p}: the lobe pyramid's levels do not match the export's mip chain: level {l} is {} \
             in the pyramid ({} levels; its sizes halve rounding up) and {} in the mip chain ({} \
             levels; KTX2 halves rounding down), so lobes<k>_mip<l>.png would not be mip level \
             l; a {width} × {height} map cannot be exported with --lobes (sizes that halve \
             evenly down to 1, such as powers of two, can)",
            at(&lobes),
            lobes.len(),
            at(&mips),
            mips.len()
        )));
    }
    Ok(())
}

/// Estimated memory of the lobe textures of the pyramid at `path` for an export of
/// `width × height` texels ([`lobe_files`]): `before` the fit, reading the pyramid compactly
/// ([`meso_maps::Pyramid::read_compact_bytes`]: from a format-4 file's chunk headers; 4 × the
/// file for older versions) with its packed textures and their files alongside; `during` it,
/// the files alone (held until written). The packed textures are `max_lobes` slots of 8 bytes a
/// texel over the mip chain; their PNG files are counted as large again (16-bit data deflated).
///
/// # Errors
/// [`ExportError::Io`] when the file cannot be read; the reader's error for a file that is not
/// a map file.
pub fn lobe_bytes(path: &Path, width: u64, height: u64) -> Result<ExtraBytes, ExportError> {
    let need = meso_maps::Pyramid::read_compact_bytes(path)?;
    let texels: u64 = lobe_level_sizes(width.max(1) as usize, height.max(1) as usize)
        .iter()
        .map(|&(c, r)| (c * r) as u64)
        .sum();
    let packed = texels.saturating_mul(8 * need.max_lobes.max(1) as u64);
    Ok(ExtraBytes {
        before: need.bytes.saturating_add(packed.saturating_mul(2)),
        during: packed,
    })
}

/// Everything [`export::check_budget_for`] checks, and a lobe pyramid's (`lobes`): its grid
/// against the export's mip chain ([`check_lobe_grid`], from the image's header and the map
/// file's first bytes), and its memory ([`lobe_bytes`]: read and packed before the fit, its files
/// held during it) beside the export's, which holds every
/// file while the pyramid is read. The one up-front check of `meso export` and `meso.export`,
/// before anything is decoded or fitted.
///
/// # Errors
/// As [`export::check_budget_for`] and [`check_lobe_grid`].
pub fn check_export(
    map: &Path,
    heights: bool,
    roughness_map: Option<&Path>,
    base_color: Option<&Path>,
    anisotropic: bool,
    lobes: Option<&Path>,
) -> Result<(), ExportError> {
    refuse_map_file(map)?;
    let mut extra = ExtraBytes::default();
    if let Some(l) = lobes {
        let grid = lobe_grid(l)?;
        if let Some(h) = export::header(map)? {
            check_lobe_grid(l, grid, h.width as usize, h.height as usize)?;
            extra = lobe_bytes(l, h.width, h.height)?;
        }
    }
    export::check_budget_extra(map, heights, roughness_map, base_color, anisotropic, extra)
}

/// The lobe textures of the pyramid at `path` for an export of `width × height` texels: the
/// pyramid read, its levels checked against the mip chain ([`check_lobe_grid`]), packed and
/// encoded ([`crate::lobes::pack`], [`crate::lobes::files`]). Returns the files and a line for
/// the user (slots × levels).
///
/// # Errors
/// The reader's errors, a pyramid whose levels are not the mip chain's, encoding errors.
pub fn lobe_files(
    path: &Path,
    width: usize,
    height: usize,
) -> Result<(Files, String), ExportError> {
    // Held as compactly as the memory budget asks (`meso render`'s read): the same values.
    let pyr = meso_maps::Pyramid::read_compact(path)?;
    let l0 = &pyr.levels[0];
    check_lobe_grid(
        path,
        (pyr.width, pyr.height, l0.cols, l0.rows),
        width,
        height,
    )?;
    let tex = crate::lobes::pack(&pyr);
    // Level 0 held by band and changed in place while packed: not the file's lobes.
    pyr.check_mapped()?;
    let files = crate::lobes::files(&tex)?;
    let line = format!(
        "{}: {} lobe slots × {} levels",
        path.display(),
        tex.k,
        tex.levels.len()
    );
    Ok((files, line))
}

/// Whether `path` names a material file (`.toml`), exported by [`material_inputs`].
#[must_use]
pub fn is_material_file(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

/// Refuse map options (`given`: their names as the caller spells them) for a material file,
/// which gives its own roughness, metallic and base colour.
///
/// # Errors
/// [`ExportError::Invalid`] naming the file and every given option.
pub fn refuse_material_options(path: &Path, given: &[&str]) -> Result<(), ExportError> {
    if given.is_empty() {
        return Ok(());
    }
    Err(ExportError::Invalid(format!(
        "{}: a material file gives its own roughness, metallic and base colour; {} {} not apply \
         (map options only)",
        path.display(),
        given.join(", "),
        if given.len() == 1 { "does" } else { "do" }
    )))
}

/// The inputs of a material file's export (`meso export MATERIAL.toml`): its engine parameters
/// (`meso_measured::engine::of_material`: GGX α clamped to `[0.001, 1]`, metallic, linear base
/// colour) as a uniform material on a flat map ([`Inputs::uniform`]), and the parameters
/// described in a line for the user. Only materials whose NDF is in the file: a height map's
/// material exports through the map itself (its BRDF at every MERL cell would take hours).
///
/// # Errors
/// [`ExportError::Invalid`] naming the file: unreadable or invalid material files, an NDF from
/// a map file or image, a material without engine parameters.
pub fn material_inputs(path: &Path) -> Result<(Inputs, String), ExportError> {
    material_inputs_with(path, &|_, _| {})
}

/// [`material_inputs`] reporting the progress of the engine fit's BRDF evaluations,
/// `progress(done, total)` (`meso_measured::engine::of_material_with`).
///
/// # Errors
/// As [`material_inputs`].
pub fn material_inputs_with(
    path: &Path,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Inputs, String), ExportError> {
    use meso_core::material::{read_limited, MaterialSpec, NdfSpec, NoExternalNdfs};
    let p = path.display();
    let bad = |e: &dyn std::fmt::Display| ExportError::Invalid(format!("{p}: {e}"));
    let dir = path.parent().unwrap_or(Path::new("."));
    let text = read_limited(path).map_err(|e| bad(&e))?;
    let spec = MaterialSpec::parse(&text, dir).map_err(|e| bad(&e))?;
    if let NdfSpec::External { kind, file, table } = &spec.ndf {
        let f = file.display();
        let advice = if kind == "map" {
            // `meso export` takes images; a map file goes with one as `--lobes`.
            format!(
                "{f} is a map file, which `meso export` does not take alone: export the height \
                 or normal map image it was extracted from, with the map's lobes \
                 (meso export IMAGE --texel-size S --height-scale H --lobes {f} --out DIR)"
            )
        } else {
            // The material's scales where it gives them, else placeholders.
            let num = |key: &str, placeholder: &str| {
                table
                    .get(key)
                    .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
                    .map_or_else(|| placeholder.to_owned(), |x| x.to_string())
            };
            format!(
                "export that height map instead (meso export {f} --texel-size {} --height-scale \
                 {} --out DIR)",
                num("texel_size", "S"),
                num("height_scale", "H")
            )
        };
        return Err(ExportError::Invalid(format!(
            "{p}: its NDF comes from {f} ([ndf] kind = \"{kind}\"); {advice}"
        )));
    }
    let m = spec.build(&NoExternalNdfs).map_err(|e| bad(&e))?;
    let e = meso_measured::engine::of_material_with(&m, progress)
        .map_err(|e| ExportError::Invalid(format!("{p}: engine parameters: {e}")))?;
    Ok((
        Inputs::uniform(e.alpha.clamp(1e-3, 1.0), e.metallic, e.base_color),
        format!("{p}: {}", e.describe()),
    ))
}
