//! The whole export: inputs → mip chains → KTX2, PNG, glTF and an error table, written
//! all-or-nothing.

use crate::ggx::roughness_to_alpha;
use crate::mips::{build_chain, build_chain_aniso, BaseMaps, LevelStats, MipLevel};
use crate::{gltf, ktx2, texture, ExportError};
use glam::DVec3;
use meso_maps::{HeightMap, NormalMap};
use std::path::{Path, PathBuf};

/// File name of the normal map KTX2 (RGBA8 UNORM, full mip chain).
pub const NORMAL_KTX2: &str = "normal.ktx2";
/// File name of the metallicRoughness KTX2 (RGBA8 UNORM, G = roughness, B = metallic).
pub const ROUGHNESS_KTX2: &str = "metallic_roughness.ktx2";
/// File name of the KHR_materials_anisotropy KTX2 (RGBA8 UNORM, RG = direction, B =
/// strength; only with [`Inputs::anisotropic`]).
pub const ANISOTROPY_KTX2: &str = "anisotropy.ktx2";
/// File name of the glTF JSON.
pub const GLTF: &str = "scene.gltf";
/// File name of the glTF binary buffer.
pub const GLTF_BIN: &str = "scene.bin";
/// File name of the base colour PNG (when one is given).
pub const BASE_COLOR_PNG: &str = "base_color.png";
/// File name of the per-level fit errors (CSV).
pub const ERRORS_CSV: &str = "errors.csv";

/// File name of the inspection PNG of normal mip level `k` (RGB, OpenGL convention).
#[must_use]
pub fn normal_png(k: usize) -> String {
    format!("normal_mip{k}.png")
}
/// File name of the inspection PNG of metallicRoughness mip level `k` (RGB, G = roughness).
#[must_use]
pub fn roughness_png(k: usize) -> String {
    format!("metallic_roughness_mip{k}.png")
}

/// File name of the PNG of anisotropy mip level `k` (RGB: R, G = direction, B = strength;
/// only with [`Inputs::anisotropic`]).
#[must_use]
pub fn anisotropy_png(k: usize) -> String {
    format!("anisotropy_mip{k}.png")
}

/// File name of the grey inspection PNG of roughness level `k` (`round(255·√α)`, for viewing).
#[must_use]
pub fn roughness_grey_png(k: usize) -> String {
    format!("roughness_mip{k}.png")
}

/// Per-sample normals of a height map by central differences,
/// `n ∝ (−∂h/∂x, −∂h/∂y, 1)` with `∂h/∂x = (h(i, j+1) − h(i, j−1)) / 2S` (the border as the
/// map's own [`meso_maps::Border`]): one normal per sample, the texture's size.
#[must_use]
pub fn normals_from_heightmap(map: &HeightMap) -> Vec<DVec3> {
    let s = map.texel_size();
    let mut v = Vec::with_capacity(map.width() * map.height());
    for i in 0..map.height() as isize {
        for j in 0..map.width() as isize {
            let gx = (map.at(i, j + 1) - map.at(i, j - 1)) / (2.0 * s);
            let gy = (map.at(i + 1, j) - map.at(i - 1, j)) / (2.0 * s);
            v.push(DVec3::new(-gx, -gy, 1.0).normalize());
        }
    }
    v
}

/// Where level-0 roughness comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Roughness {
    /// One GGX width α everywhere (not glTF roughness; `r = √α`).
    Alpha(f64),
    /// Per-texel GGX widths α, map row order (e.g. from [`load_roughness`]).
    Map(Vec<f64>),
}

/// Load a roughness image holding glTF perceptual roughness `r` (α = r²): a grey image, or a
/// colour one in glTF's metallicRoughness layout (G is taken). Rows are reversed into map order.
/// Returns α per texel and warnings for the user.
///
/// # Errors
/// Unreadable or undecodable files, a size other than `width × height`, or an image whose
/// decoding needs more memory than the budget (`meso_core::budget`, checked from the header).
pub fn load_roughness(
    path: &Path,
    width: usize,
    height: usize,
) -> Result<(Vec<f64>, Vec<String>), ExportError> {
    // The size from the header first: a mismatch needs no decoding.
    if let Some(h) = header(path)? {
        if (h.width, h.height) != (width as u64, height as u64) {
            return Err(ExportError::Invalid(format!(
                "{}: the roughness map is {} × {}, the normals {width} × {height}",
                path.display(),
                h.width,
                h.height
            )));
        }
    }
    let img = open(path, "loading the roughness map", roughness_bytes)?;
    let mut warnings = Vec::new();
    if (img.width() as usize, img.height() as usize) != (width, height) {
        return Err(ExportError::Invalid(format!(
            "{}: the roughness map is {} × {}, the normals {width} × {height}",
            path.display(),
            img.width(),
            img.height()
        )));
    }
    let rgb = img.to_rgb32f();
    let grey = rgb.pixels().all(|p| p.0[0] == p.0[1] && p.0[1] == p.0[2]);
    if !grey {
        warnings.push(format!(
            "{}: a colour roughness map; taking its green channel (glTF metallicRoughness layout)",
            path.display()
        ));
    }
    let mut alphas = Vec::with_capacity(width * height);
    for r in (0..height as u32).rev() {
        for c in 0..width as u32 {
            alphas.push(roughness_to_alpha(rgb.get_pixel(c, r).0[1] as f64));
        }
    }
    Ok((alphas, warnings))
}

/// Bytes of memory an export of a `width × height` map needs besides loading the map
/// ([`EXPORT_BYTES_PER_TEXEL`] per level-0 texel): the inputs, the base maps, both mip chains
/// with their errors, and every file's bytes (PNG, KTX2), all held until they are written.
#[must_use]
pub fn export_bytes(width: u64, height: u64) -> u64 {
    width
        .saturating_mul(height)
        .saturating_mul(EXPORT_BYTES_PER_TEXEL)
}

/// Peak bytes per level-0 texel of [`build`] and [`write()`] (see [`export_bytes`]): normals (f64)
/// held by the inputs (24), normals and α of the base maps (32), level 0's normals, α and two
/// error arrays (48), the smaller levels (16) and the per-texel results while fitting them
/// (12), the RGBA8 levels, PNG and KTX2 files of the chain (31): 163 B counted; measured 160 B
/// (the peak RSS of `meso export` grows by 123 MB from a 512² to a 1024² normal map,
/// docs/limits.md), with a 10 % margin.
pub const EXPORT_BYTES_PER_TEXEL: u64 = 176;

/// Extra peak bytes per level-0 texel of an anisotropic export ([`Inputs::anisotropic`]):
/// level 0's α_t, directions and isotropic errors (24), the smaller levels' (8), the per-texel
/// results while fitting (8), the RGBA8 levels, PNG and KTX2 files of the anisotropy chain
/// (15): 55 B counted, 64 B with a margin (measured: the peak RSS of a 1024² export grows by
/// 16 MB with the option, docs/benchmarks.md).
pub const ANISO_EXTRA_BYTES_PER_TEXEL: u64 = 64;

/// Peak bytes of [`load_roughness`] for an image with this header: the file, the decoded
/// image, its float RGB conversion and the α values.
#[must_use]
pub fn roughness_bytes(h: &meso_maps::ImageHeader) -> u64 {
    h.file_bytes
        .saturating_add(h.pixels().saturating_mul(h.bytes_per_pixel + 12 + 8))
}

/// Peak bytes of [`load_base_color`] for an image with this header: the file, the decoded
/// image, its RGBA8 conversion and the PNG re-encoding (at most about the raw size).
#[must_use]
pub fn base_color_bytes(h: &meso_maps::ImageHeader) -> u64 {
    h.file_bytes
        .saturating_add(h.pixels().saturating_mul(h.bytes_per_pixel + 4 + 4))
}

/// Refuse, from the images' headers and before anything is decoded, an export whose estimated
/// memory is above the budget ([`meso_core::budget`]): the map's load (`heights`: a height map,
/// else a normal map) and the export (mip chains and files, held until written) named after the
/// map, then the roughness map's and the base colour's loads. The one check of `meso export` and
/// the Python package's `meso.export`.
///
/// # Errors
/// [`ExportError::Budget`] naming the file; unreadable headers as [`header`] reports them.
pub fn check_budget(
    map: &Path,
    heights: bool,
    roughness_map: Option<&Path>,
    base_color: Option<&Path>,
) -> Result<(), ExportError> {
    check_budget_for(map, heights, roughness_map, base_color, false)
}

/// [`check_budget`] for an export that is anisotropic or not ([`Inputs::anisotropic`]: adds
/// [`ANISO_EXTRA_BYTES_PER_TEXEL`] per texel).
///
/// # Errors
/// As [`check_budget`].
pub fn check_budget_for(
    map: &Path,
    heights: bool,
    roughness_map: Option<&Path>,
    base_color: Option<&Path>,
    anisotropic: bool,
) -> Result<(), ExportError> {
    check_budget_extra(
        map,
        heights,
        roughness_map,
        base_color,
        anisotropic,
        ExtraBytes::default(),
    )
}

/// Memory an export holds besides its own work (bytes): a lobe pyramid read and packed
/// `before` the fit, with the inputs loaded, and its files held `during` the fit and until
/// written (`crate::prepare::lobe_bytes`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExtraBytes {
    /// Held before the fit, beside the loaded inputs (the fit's memory is not yet taken).
    pub before: u64,
    /// Held during the fit, beside its memory.
    pub during: u64,
}

/// Bytes per level-0 texel of the [`Inputs`] held once loaded: the normals (`f64`, 24), a
/// roughness map's α (8) and a base colour texture (16).
pub const INPUT_BYTES_PER_TEXEL: u64 = 48;

/// [`check_budget_for`] with `extra` held besides the export's own work (a lobe pyramid read
/// before the fit and its files held during it, `crate::prepare::check_export`): the map's
/// estimate is its load plus the larger of the inputs ([`INPUT_BYTES_PER_TEXEL`]) with
/// `extra.before`, and the export's own bytes plus `extra.during` (its task then names the
/// pyramid).
///
/// # Errors
/// As [`check_budget`].
pub fn check_budget_extra(
    map: &Path,
    heights: bool,
    roughness_map: Option<&Path>,
    base_color: Option<&Path>,
    anisotropic: bool,
    extra: ExtraBytes,
) -> Result<(), ExportError> {
    use meso_core::budget::check;
    if let Some(h) = header(map)? {
        let load = if heights {
            h.height_map_bytes()
        } else {
            h.normal_map_bytes()
        };
        let texels = h.width.saturating_mul(h.height);
        let aniso = if anisotropic {
            texels.saturating_mul(ANISO_EXTRA_BYTES_PER_TEXEL)
        } else {
            0
        };
        let fit = export_bytes(h.width, h.height)
            .saturating_add(aniso)
            .saturating_add(extra.during);
        // Before the fit the inputs are held beside the lobe pyramid (without one, less than
        // the fit: INPUT_BYTES_PER_TEXEL < EXPORT_BYTES_PER_TEXEL).
        let before = texels
            .saturating_mul(INPUT_BYTES_PER_TEXEL)
            .saturating_add(extra.before);
        let estimate = load.saturating_add(fit.max(before));
        let task = if extra != ExtraBytes::default() {
            format!(
                "exporting {} × {} texels and reading the lobe pyramid",
                h.width, h.height
            )
        } else {
            format!("exporting {} × {} texels", h.width, h.height)
        };
        check(map, &task, estimate)?;
    }
    if let Some(r) = roughness_map {
        if let Some(h) = header(r)? {
            check(r, "loading the roughness map", roughness_bytes(&h))?;
        }
    }
    if let Some(c) = base_color {
        if let Some(h) = header(c)? {
            check(c, "loading the base colour image", base_color_bytes(&h))?;
        }
    }
    Ok(())
}

/// The header of a regular image file, read without decoding it; `None` for a file that is not
/// regular or whose header the probe cannot read (the decoder reports that, with more detail).
///
/// # Errors
/// An image larger than meso's size limits (`meso_maps::heightmap::MAX_DIMENSION`,
/// `MAX_TEXELS`).
pub fn header(path: &Path) -> Result<Option<meso_maps::ImageHeader>, ExportError> {
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return Ok(None);
    }
    match meso_maps::probe(path) {
        Ok(h) => Ok(Some(h)),
        Err(e @ meso_maps::MapError::TooLarge { .. }) => Err(e.into()),
        Err(_) => Ok(None),
    }
}

/// Read and decode an image after checking, from its header, that `task` (its estimated peak
/// memory, `estimate`) fits the memory budget (`meso_core::budget`).
fn open(
    path: &Path,
    task: &str,
    estimate: impl Fn(&meso_maps::ImageHeader) -> u64,
) -> Result<image::DynamicImage, ExportError> {
    let img = meso_maps::heightmap::decode_image(path, task, estimate)?;
    if img.width() == 0 || img.height() == 0 {
        return Err(ExportError::Invalid(format!(
            "{}: empty image",
            path.display()
        )));
    }
    Ok(img)
}

/// A base colour image (sRGB, as stored), re-encoded as an 8-bit RGBA PNG in image order.
#[derive(Clone, Debug, PartialEq)]
pub struct BaseColor {
    /// The PNG bytes.
    pub png: Vec<u8>,
}

/// Load a base colour image (PNG, JPEG, TGA, TIFF) for the glTF asset; 16-bit and float images
/// are converted to 8 bits, with a warning.
///
/// # Errors
/// Unreadable or undecodable files, or an image whose decoding needs more memory than the
/// budget (`meso_core::budget`, checked from the header).
pub fn load_base_color(path: &Path) -> Result<(BaseColor, Vec<String>), ExportError> {
    let img = open(path, "loading the base colour image", base_color_bytes)?;
    let mut warnings = Vec::new();
    if !matches!(
        img.color(),
        image::ColorType::Rgb8
            | image::ColorType::Rgba8
            | image::ColorType::L8
            | image::ColorType::La8
    ) {
        warnings.push(format!(
            "{}: {:?} base colour converted to 8-bit sRGB RGBA (glTF stores 8-bit colour)",
            path.display(),
            img.color()
        ));
    }
    let rgba = img.to_rgba8();
    let png = texture::encode_png(
        rgba.width() as usize,
        rgba.height() as usize,
        4,
        rgba.as_raw(),
    )?;
    Ok((BaseColor { png }, warnings))
}

/// Everything the exporter needs besides the output folder.
#[derive(Clone, Debug, PartialEq)]
pub struct Inputs {
    /// Texels along x.
    pub width: usize,
    /// Texels along y.
    pub height: usize,
    /// Level-0 unit normals, map row order.
    pub normals: Vec<DVec3>,
    /// Level-0 roughness.
    pub roughness: Roughness,
    /// Metallic value written to the B channel (`[0, 1]`).
    pub metallic: f64,
    /// Base colour texture, if any.
    pub base_color: Option<BaseColor>,
    /// Linear base colour factor (RGBA, `[0, 1]`) of a material without a base colour
    /// texture. With [`Inputs::base_color`] the glTF factor is `[1, 1, 1, 1]` whatever this
    /// holds: glTF multiplies the texture by the factor, and the texture is the colour.
    pub base_color_factor: [f64; 4],
    /// Fit anisotropic GGX lobes (`α_t`, `α_b`, direction; [`crate::ggx::fit_aniso`]) and
    /// write them the KHR_materials_anisotropy way: the metallicRoughness G channel carries
    /// `√α_b`, [`ANISOTROPY_KTX2`] and [`anisotropy_png`] the direction and strength, and the
    /// glTF material uses the extension. `false` (the default of the constructors): isotropic α.
    pub anisotropic: bool,
}

impl Inputs {
    /// Inputs from a tangent-space normal map with a constant α and no base colour texture.
    #[must_use]
    pub fn from_normal_map(map: &NormalMap, alpha: f64) -> Inputs {
        Inputs {
            width: map.width(),
            height: map.height(),
            normals: map.normals().to_vec(),
            roughness: Roughness::Alpha(alpha),
            metallic: 0.0,
            base_color: None,
            base_color_factor: [0.8, 0.8, 0.8, 1.0],
            anisotropic: false,
        }
    }
    /// Inputs of a uniform material with no normal map (a flat 4 × 4 map, +z everywhere): GGX
    /// width `alpha`, `metallic` and the linear base colour `base_color` as the glTF factor —
    /// the export of a material given by its parameters alone (`meso export MATERIAL.toml`,
    /// the engine parameters of a fitted material). Every level's α is `alpha` (a flat map loses
    /// no variance).
    #[must_use]
    pub fn uniform(alpha: f64, metallic: f64, base_color: [f64; 3]) -> Inputs {
        Inputs {
            width: 4,
            height: 4,
            normals: vec![DVec3::Z; 16],
            roughness: Roughness::Alpha(alpha),
            metallic,
            base_color: None,
            base_color_factor: [base_color[0], base_color[1], base_color[2], 1.0],
            anisotropic: false,
        }
    }

    /// Inputs from a height map (normals by [`normals_from_heightmap`]) with a constant α.
    #[must_use]
    pub fn from_heightmap(map: &HeightMap, alpha: f64) -> Inputs {
        Inputs {
            width: map.width(),
            height: map.height(),
            normals: normals_from_heightmap(map),
            roughness: Roughness::Alpha(alpha),
            metallic: 0.0,
            base_color: None,
            base_color_factor: [0.8, 0.8, 0.8, 1.0],
            anisotropic: false,
        }
    }
}

/// The export in memory: every file's name and bytes, and the per-level statistics.
#[derive(Clone, Debug)]
pub struct Export {
    /// `(file name, bytes)` in writing order.
    pub files: Vec<(String, Vec<u8>)>,
    /// Per-level fit statistics, level 0 first.
    pub stats: Vec<LevelStats>,
    /// The mip chains themselves.
    pub levels: Vec<MipLevel>,
}

/// Build every output in memory (nothing is written).
///
/// # Errors
/// [`ExportError::Invalid`] for inconsistent inputs (empty map, α or metallic outside `[0, 1]`,
/// bad normals, an anisotropic export of a 1 × 1 map, which has no coarser level to fit).
pub fn build(inputs: &Inputs) -> Result<Export, ExportError> {
    let (w, h) = (inputs.width, inputs.height);
    if inputs.anisotropic && w * h == 1 {
        return Err(ExportError::Invalid(
            "anisotropic export of a 1 × 1 map: a single texel has only level 0, whose \
             roughness is the isotropic input; there is no coarser level to fit"
                .to_string(),
        ));
    }
    if !(0.0..=1.0).contains(&inputs.metallic) {
        return Err(ExportError::Invalid(format!(
            "metallic {} is outside [0, 1]",
            inputs.metallic
        )));
    }
    let alphas = match &inputs.roughness {
        Roughness::Alpha(a) => {
            if !(a.is_finite() && *a > 0.0 && *a <= 1.0) {
                return Err(ExportError::Invalid(format!(
                    "α = {a}: the GGX width must be in (0, 1]"
                )));
            }
            vec![*a; w * h]
        }
        Roughness::Map(v) => v.clone(),
    };
    let base = BaseMaps::new(w, h, inputs.normals.clone(), alphas)?;
    let levels = if inputs.anisotropic {
        build_chain_aniso(&base)
    } else {
        build_chain(&base)
    };
    let stats: Vec<LevelStats> = levels.iter().enumerate().map(|(k, l)| l.stats(k)).collect();
    let orient = || {
        vec![
            ("KTXorientation".to_string(), "rd".to_string()),
            (
                "KTXwriter".to_string(),
                concat!("meso export ", env!("CARGO_PKG_VERSION")).to_string(),
            ),
        ]
    };
    let mut files = Vec::new();
    let mut nlev = Vec::new();
    let mut rlev = Vec::new();
    let mut alev = Vec::new();
    for (k, l) in levels.iter().enumerate() {
        if let Some(a) = &l.aniso {
            let t = texture::anisotropy_rgba8(l.width, l.height, &l.alphas, &a.alpha_t, &a.angles);
            files.push((
                anisotropy_png(k),
                texture::encode_png(l.width, l.height, 3, &texture::rgba_to_rgb(&t))?,
            ));
            alev.push(ktx2::Level {
                width: l.width as u32,
                height: l.height as u32,
                data: t,
            });
        }
        let n = texture::normals_rgba8(l.width, l.height, &l.normals);
        let r = texture::metallic_roughness_rgba8(l.width, l.height, &l.alphas, inputs.metallic);
        files.push((
            normal_png(k),
            texture::encode_png(l.width, l.height, 3, &texture::rgba_to_rgb(&n))?,
        ));
        files.push((
            roughness_png(k),
            texture::encode_png(l.width, l.height, 3, &texture::rgba_to_rgb(&r))?,
        ));
        let grey: Vec<u8> = r.chunks_exact(4).map(|p| p[1]).collect();
        files.push((
            roughness_grey_png(k),
            texture::encode_png(l.width, l.height, 1, &grey)?,
        ));
        nlev.push(ktx2::Level {
            width: l.width as u32,
            height: l.height as u32,
            data: n,
        });
        rlev.push(ktx2::Level {
            width: l.width as u32,
            height: l.height as u32,
            data: r,
        });
    }
    files.push((
        NORMAL_KTX2.to_string(),
        ktx2::write(&ktx2::Texture {
            format: ktx2::Format::Rgba8Unorm,
            levels: nlev,
            key_values: orient(),
        })?,
    ));
    files.push((
        ROUGHNESS_KTX2.to_string(),
        ktx2::write(&ktx2::Texture {
            format: ktx2::Format::Rgba8Unorm,
            levels: rlev,
            key_values: orient(),
        })?,
    ));
    if inputs.anisotropic {
        files.push((
            ANISOTROPY_KTX2.to_string(),
            ktx2::write(&ktx2::Texture {
                format: ktx2::Format::Rgba8Unorm,
                levels: alev,
                key_values: orient(),
            })?,
        ));
    }
    if let Some(bc) = &inputs.base_color {
        files.push((BASE_COLOR_PNG.to_string(), bc.png.clone()));
    }
    let tex = gltf::MaterialTextures {
        normal: normal_png(0),
        metallic_roughness: roughness_png(0),
        base_color: inputs
            .base_color
            .as_ref()
            .map(|_| BASE_COLOR_PNG.to_string()),
        anisotropy: inputs.anisotropic.then(|| anisotropy_png(0)),
    };
    let meshes = [
        ("sphere", gltf::uv_sphere(1.0, 64, 32, 2.0)),
        ("plane", gltf::plane(2.0, 1.0)),
    ];
    let (bin, doc) = gltf::asset(&meshes, &tex, GLTF_BIN, base_color_factor(inputs));
    files.push((GLTF_BIN.to_string(), bin));
    let json = serde_json::to_vec_pretty(&doc)
        .map_err(|e| ExportError::Invalid(format!("glTF JSON: {e}")))?;
    files.push((GLTF.to_string(), json));
    files.push((ERRORS_CSV.to_string(), errors_csv(&stats).into_bytes()));
    Ok(Export {
        files,
        stats,
        levels,
    })
}

/// The glTF `baseColorFactor` of an export: `[1, 1, 1, 1]` with a base colour texture (glTF
/// multiplies the texture by the factor, so anything else would darken or tint it), else
/// [`Inputs::base_color_factor`].
#[must_use]
pub fn base_color_factor(inputs: &Inputs) -> [f64; 4] {
    if inputs.base_color.is_some() {
        [1.0; 4]
    } else {
        inputs.base_color_factor
    }
}

/// The per-level statistics as CSV:
/// `level,width,height,mean_alpha,mean_error_pct,max_error_pct,plain_mip_error_pct`, and for
/// an anisotropic export also `mean_alpha_t,mean_strength,iso_fit_error_pct,iso_fit_max_error_pct`
/// (then `mean_alpha` is the mean `α_b` and the errors before them the anisotropic lobe's).
#[must_use]
pub fn errors_csv(stats: &[LevelStats]) -> String {
    let aniso = stats.iter().any(|l| l.aniso.is_some());
    let mut s = String::from(
        "level,width,height,mean_alpha,mean_error_pct,max_error_pct,plain_mip_error_pct",
    );
    if aniso {
        s += ",mean_alpha_t,mean_strength,iso_fit_error_pct,iso_fit_max_error_pct";
    }
    s += "\n";
    for l in stats {
        s += &format!(
            "{},{},{},{:.5},{:.3},{:.3},{:.3}",
            l.level,
            l.width,
            l.height,
            l.mean_alpha,
            l.mean_error_pct,
            l.max_error_pct,
            l.mean_plain_error_pct
        );
        if let Some(a) = &l.aniso {
            s += &format!(
                ",{:.5},{:.4},{:.3},{:.3}",
                a.mean_alpha_t, a.mean_strength, a.mean_iso_error_pct, a.max_iso_error_pct
            );
        }
        s += "\n";
    }
    s
}

/// Whether a file name is one an export writes: the fixed names ([`NORMAL_KTX2`], [`GLTF`], …,
/// the lobe shaders) or a level's PNG, `<stem>_mip<k>.png`.
fn is_export_file_name(name: &str) -> bool {
    const FIXED: [&str; 9] = [
        NORMAL_KTX2,
        ROUGHNESS_KTX2,
        ANISOTROPY_KTX2,
        GLTF,
        GLTF_BIN,
        BASE_COLOR_PNG,
        ERRORS_CSV,
        crate::lobes::WGSL_FILE,
        crate::lobes::GLSL_FILE,
    ];
    FIXED.contains(&name)
        || name
            .strip_suffix(".png")
            .and_then(|s| s.rsplit_once("_mip"))
            .is_some_and(|(stem, k)| {
                !stem.is_empty() && !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit())
            })
}

/// The files in `dir` named as an export's files ([`Export::files`]' names: the KTX2 and glTF
/// files, the CSV, the shaders and the per-level PNGs `<stem>_mip<k>.png`) that `export` does
/// not write: left there by an earlier export into the same folder (a larger map's extra mip
/// levels, an anisotropy chain, a base colour), which this export's glTF does not reference.
/// [`write()`] leaves them (nothing of the user's is removed); `meso export` warns of them.
/// Sorted; empty when `dir` cannot be read.
#[must_use]
pub fn stale_files(export: &Export, dir: &Path) -> Vec<PathBuf> {
    let ours: std::collections::HashSet<&str> =
        export.files.iter().map(|(n, _)| n.as_str()).collect();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .filter(|e| {
            e.file_name()
                .to_str()
                .is_some_and(|n| is_export_file_name(n) && !ours.contains(n) && e.path().is_file())
        })
        .map(|e| e.path())
        .collect();
    out.sort();
    out
}

/// The warning for [`stale_files`] in `dir`, when there are any: how many, and their names
/// (what `meso export` prints after the folder's name, and Python's `export` returns among its
/// warnings).
#[must_use]
pub fn stale_warning(export: &Export, dir: &Path) -> Option<String> {
    let names: Vec<String> = stale_files(export, dir)
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    (!names.is_empty()).then(|| {
        format!(
            "{} file{} of an earlier export left in the folder, not written by this one and not \
             used by its scene.gltf: {}",
            names.len(),
            if names.len() == 1 { "" } else { "s" },
            names.join(", ")
        )
    })
}

/// Write the export's files into `dir` (created if missing). All or nothing, and nothing of
/// the user's lost: every file is first written in full to a temporary file beside its target
/// (`meso_core::io::stage_with`); only when all are written are they renamed into place
/// (`meso_core::io::commit_all`). A file that cannot be written (a full disk, a directory in the
/// way) leaves `dir` as it was — the files of an earlier export there untouched — and removes
/// `dir` if this call created it.
///
/// No file is written over one of `inputs` (the files the export was made from), nor over a
/// file in `meso_core::io`'s input log when it records: such an export is refused before
/// anything is written.
///
/// # Errors
/// [`ExportError::Invalid`] when `dir` is an existing file or one of the files would replace
/// an input; [`ExportError::Io`] naming the path that failed.
pub fn write(export: &Export, dir: &Path, inputs: &[&Path]) -> Result<Vec<PathBuf>, ExportError> {
    crate::prepare::check_out_dir(dir)?;
    for (name, _) in &export.files {
        let path = dir.join(name);
        meso_core::io::check_not_input(&path, inputs)
            .and_then(|()| meso_core::io::check_not_recorded_input(&path))
            .map_err(|e| {
                ExportError::Invalid(format!(
                    "{e} (the export writes {name} into {})",
                    dir.display()
                ))
            })?;
    }
    let existed = dir.is_dir();
    std::fs::create_dir_all(dir).map_err(|e| ExportError::Io {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let undo = |path: PathBuf, source: std::io::Error| {
        if !existed {
            let _ = std::fs::remove_dir(dir);
        }
        ExportError::Io { path, source }
    };
    let mut staged = Vec::with_capacity(export.files.len());
    let mut written = Vec::with_capacity(export.files.len());
    for (name, bytes) in &export.files {
        let path = dir.join(name);
        match meso_core::io::stage_with(&path, |w| w.write_all(bytes)) {
            Ok(s) => staged.push(s),
            Err(e) => {
                // Dropping the staged files removes their temporary files.
                drop(staged);
                return Err(undo(path, e));
            }
        }
        written.push(path);
    }
    meso_core::io::commit_all(staged).map_err(|e| undo(e.path, e.source))?;
    Ok(written)
}
