//! # meso-figures
//!
//! The pictures of Fournier 1992 (§4) rendered with `meso-render` from data generated in code
//! (no input files), for `meso figures [--out DIR]`; `docs/figures.md` describes each one.
//!
//! * **Figure 2** — a sphere with an anisotropic surface (normals along the great circle ⊥
//!   the bitangent: the NDF of a cylinder bump), and multiple surfaces of 2, 3 and 7 normals;
//!   the 7 are the lobe axes of the top level of the NDF pyramid of a half-cylinder bump map
//!   ([`cylinder_map`]; tests/catalogue.rs extracts it again and requires the catalogue's
//!   numbers).
//! * **Figures 3 and 4** — the same sphere as velvet (normals near the horizon: grazing sheen)
//!   and as silk (normals spread across the thread direction), under the same light, from
//!   near the viewer ([`cloth_light`]), which shows the velvet's bright rim.
//! * **Zoom** — a bump-mapped plane, NDF-mapped through the pyramid, zooming out from visible
//!   bumps to the averaged surface, with the mean luminance of every frame in a CSV.
//! * **Blend** — a strip of spheres whose NDF goes from one lobe set to another, weights
//!   `(1 − t)` and `t`.
//! * **Contact sheet** — every picture, labelled (`meso_plot::Sheet`).
//!
//! The materials of Figures 2–4 are those of [`meso_core::catalogue`] (the one definition the
//! editor's presets, the tests and the benchmarks use too), as [`MaterialDef`]s.
//!
//! Every material is written as a TOML file next to its PNG, with a scene file that `meso
//! render` accepts, so each picture can be re-rendered and edited. All files are written with
//! `meso_core::io::write_atomic`.
//!
//! Conventions: spheres have their pole on world `+y`, so their tangent (local `+x`) runs
//! along the parallels (horizontally in the pictures) and their bitangent (local `+y`) along
//! the meridians towards the pole; lobe axes in the material files are `[θ, φ]` in degrees in
//! that frame.
#![warn(missing_docs)]

mod material_def;

use glam::DVec3;
use meso_core::catalogue;
use meso_core::material::{MaterialSpec, NdfSpec};
use meso_maps::{extract, fixtures, ExtractParams, HeightMap, Pyramid, Source};
use meso_plot::{Canvas, Sheet};
use meso_render::{
    render, Camera, Image, ImageSettings, Light, MaterialShader, NdfMapped, Projection,
    RenderOptions, Scene, SceneBuilder, Shader,
};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// An error while making the figures: what failed, naming the file when there is one.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct FigureError(pub String);

fn ferr(msg: impl Into<String>) -> FigureError {
    FigureError(msg.into())
}

pub use material_def::{Lobe, MaterialDef};

/// The half-cylinder bump map of Figure 2: 64×64 samples, texel 1/64, cylinders of period 16
/// texels along the map's y (rows), so their normals spread in the x–z plane.
///
/// # Errors
/// Never for these constants; the height-map constructor's message otherwise.
pub fn cylinder_map() -> Result<HeightMap, FigureError> {
    fixtures::half_cylinders(64, 16, 1.0 / 64.0, 1.0).map_err(|e| ferr(e.to_string()))
}

/// Extract the NDF pyramid of `map` with up to `max_lobes` lobes per texel.
///
/// # Errors
/// The extractor's message.
pub fn pyramid(map: &HeightMap, max_lobes: usize) -> Result<Pyramid, FigureError> {
    let mut p = ExtractParams::default();
    p = p.with_max_lobes(max_lobes);
    // Fit every normal of a footprint (the default strided subset of 512 aliases with periodic
    // bump maps and biases the top-level lobes); the maps here are small.
    p.fit.max_em_points = 1 << 14;
    extract(Source::Heights(map), &p, &mut |_| {}).map_err(|e| ferr(e.to_string()))
}

/// The key light of the sphere figures: directional, from the upper left front, irradiance
/// 2.5 (perpendicular to the light's direction).
#[must_use]
pub fn key_light() -> Light {
    Light::Directional {
        direction: DVec3::new(-0.5, 0.55, 0.67).normalize(),
        irradiance: DVec3::splat(2.5),
    }
}

/// The light of Figures 3 and 4 ("under the same light"): directional, from just above
/// and left of the viewer, irradiance 2.5. Lit from near the view direction, the velvet's
/// fibres, seen and lit at grazing angles, shine at the limb all the way round (its
/// characteristic bright rim) while the centre stays dark, and the light's terminator lies
/// within a few pixels of the silhouette. (With the key light from the upper left, the
/// multiple-surface form's sheen ends in a sharp arc at the terminator: each facet keeps its
/// own cosine up to the macro horizon, where the renderer drops the light.)
#[must_use]
pub fn cloth_light() -> Light {
    Light::Directional {
        direction: DVec3::new(-0.2, 0.25, 0.947).normalize(),
        irradiance: DVec3::splat(2.5),
    }
}

/// Background radiance of the figures (dark blue-grey).
pub const BACKGROUND: [f32; 3] = [0.012, 0.013, 0.018];

fn sphere_camera(width: f64) -> Result<Camera, FigureError> {
    Camera::new(
        Projection::Orthographic { width },
        DVec3::new(0.0, 0.0, 5.0),
        DVec3::ZERO,
        DVec3::Y,
    )
    .map_err(|e| ferr(e.to_string()))
}

/// A unit sphere (pole `+y`) with `shader` under `lights` (e.g. `&[key_light()]` or
/// `&[cloth_light()]`), seen head-on through an orthographic camera 2.4 units wide,
/// `size × size` pixels at `spp` samples per pixel.
///
/// # Errors
/// Invalid sizes or lights.
pub fn sphere_scene(
    shader: Arc<dyn Shader>,
    size: u32,
    spp: u32,
    lights: &[Light],
) -> Result<Scene, FigureError> {
    let mut b = SceneBuilder::new(
        sphere_camera(2.4)?,
        ImageSettings {
            width: size,
            height: size,
            spp,
            background: BACKGROUND,
        },
    );
    let m = b.material(shader);
    b.sphere(DVec3::ZERO, 1.0, DVec3::Y, m)
        .map_err(|e| ferr(e.to_string()))?;
    for &l in lights {
        b.light(l).map_err(|e| ferr(e.to_string()))?;
    }
    b.build().map_err(|e| ferr(e.to_string()))
}

/// The scene file of [`sphere_scene`] for `meso render`, with `material` as the material path
/// and the directional `lights` (others are left out).
#[must_use]
pub fn sphere_scene_toml(material: &str, size: u32, spp: u32, lights: &[Light]) -> String {
    let mut s = format!(
        "[camera]\nkind = \"orthographic\"\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n\
         up = [0.0, 1.0, 0.0]\nwidth = 2.4\n[image]\nwidth = {size}\nheight = {size}\nspp = {spp}\n\
         background = [{}, {}, {}]\n[[object]]\nkind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\n\
         radius = 1.0\npole = [0.0, 1.0, 0.0]\nmaterial = \"{material}\"\n",
        BACKGROUND[0], BACKGROUND[1], BACKGROUND[2],
    );
    for light in lights {
        let Light::Directional {
            direction,
            irradiance,
        } = *light
        else {
            continue;
        };
        let _ = write!(
            s,
            "[[light]]\nkind = \"directional\"\ndirection = [{:.6}, {:.6}, {:.6}]\n\
             irradiance = [{}, {}, {}]\n",
            direction.x, direction.y, direction.z, irradiance.x, irradiance.y, irradiance.z
        );
    }
    s
}

/// The bump map of the zoom sequence: 64×64 samples of texel 1/64 (one tile per world unit),
/// a 4×4 egg-crate of bumps `h = 0.03·sin(2πx/P)·sin(2πy/P)`, `P = 1/4`, slopes up to 37°.
///
/// # Errors
/// Never for these constants.
pub fn bump_map() -> Result<HeightMap, FigureError> {
    let p = 0.25;
    let tau = std::f64::consts::TAU;
    HeightMap::from_fn(64, 64, 1.0 / 64.0, meso_maps::Border::Wrap, |x, y| {
        0.03 * (tau * x / p).sin() * (tau * y / p).sin()
    })
    .map_err(|e| ferr(e.to_string()))
}

/// The surface of the zoom sequence (its NDF is replaced by the bump map's): Phong facets
/// (η = 40) over a warm diffuse base.
#[must_use]
pub fn bump_surface() -> MaterialDef {
    MaterialDef {
        name: "bump-mapped plane".into(),
        lobes: vec![Lobe::delta(0.0, 0.0, 1.0)],
        exponent: 40.0,
        specular: [0.5, 0.5, 0.5],
        diffuse: [0.5, 0.36, 0.22],
    }
}

/// The light of the zoom sequence: directional, 55° from the plane's normal, from the left
/// (its direction and irradiance: [`plane_sun`]).
#[must_use]
pub fn plane_light() -> Light {
    let (direction, irradiance) = plane_sun();
    Light::Directional {
        direction,
        irradiance,
    }
}

/// [`plane_light`]'s unit direction towards the light (the plane's frame) and its irradiance
/// (W/m² per channel, perpendicular to that direction).
#[must_use]
pub fn plane_sun() -> (DVec3, DVec3) {
    (DVec3::new(-0.75, 0.35, 0.57).normalize(), DVec3::splat(2.0))
}

/// The direction towards the camera of [`plane_scene`] (unit, the plane's frame: 30° from the
/// normal, towards −y).
#[must_use]
pub fn plane_view() -> DVec3 {
    DVec3::new(0.0, -0.5, 0.866_025_403_784_438_6)
}

/// A plane `z = 0` (tangent `+x`, one texture unit per world unit) with `shader`, seen through
/// an orthographic camera tilted 30° from the normal, `width` world units across, under
/// [`plane_light`].
///
/// # Errors
/// Invalid sizes.
pub fn plane_scene(
    shader: Arc<dyn Shader>,
    width: f64,
    pixels: u32,
    spp: u32,
) -> Result<Scene, FigureError> {
    let dir = plane_view();
    let cam = Camera::new(
        Projection::Orthographic { width },
        dir * 10.0 * width.max(1.0),
        DVec3::ZERO,
        DVec3::Y,
    )
    .map_err(|e| ferr(e.to_string()))?;
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            width: pixels,
            height: pixels,
            spp,
            background: BACKGROUND,
        },
    );
    let m = b.material(shader);
    b.plane(DVec3::ZERO, DVec3::Z, DVec3::X, 1.0, m)
        .map_err(|e| ferr(e.to_string()))?;
    b.light(plane_light()).map_err(|e| ferr(e.to_string()))?;
    b.build().map_err(|e| ferr(e.to_string()))
}

/// The scene file of [`plane_scene`] for `meso render`, with `material` as the material path.
#[must_use]
pub fn plane_scene_toml(material: &str, width: f64, pixels: u32, spp: u32) -> String {
    let pos = plane_view() * 10.0 * width.max(1.0);
    let (l, e) = plane_sun();
    format!(
        "[camera]\nkind = \"orthographic\"\nposition = [{:?}, {:?}, {:?}]\n\
         look_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nwidth = {width:?}\n\
         [image]\nwidth = {pixels}\nheight = {pixels}\nspp = {spp}\nbackground = [{:?}, {:?}, {:?}]\n\
         [[object]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\
         tangent = [1.0, 0.0, 0.0]\nuv_scale = 1.0\nmaterial = \"{material}\"\n\
         [[light]]\nkind = \"directional\"\ndirection = [{:?}, {:?}, {:?}]\n\
         irradiance = [{:?}, {:?}, {:?}]\n",
        pos.x, pos.y, pos.z, BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], l.x, l.y, l.z, e.x, e.y, e.z
    )
}

/// Camera widths of the zoom sequence (world units, one map tile per unit): 0.9·2.2^k.
#[must_use]
pub fn zoom_widths(frames: usize) -> Vec<f64> {
    (0..frames).map(|k| 0.9 * 2.2f64.powi(k as i32)).collect()
}

/// Mean Rec. 709 luminance of an image.
#[must_use]
pub fn mean_luminance(img: &Image) -> f64 {
    let px = img.pixels();
    px.iter()
        .map(|p| 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]))
        .sum::<f64>()
        / px.len().max(1) as f64
}

/// Settings of [`run`].
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Edge of the sphere pictures in pixels (default 320).
    pub size: u32,
    /// Samples per pixel (default 4).
    pub spp: u32,
    /// Frames of the zoom sequence (default 8, at least 6).
    pub zoom_frames: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            out: PathBuf::from("out/figures"),
            size: 320,
            spp: 4,
            zoom_frames: 8,
        }
    }
}

/// One frame of the zoom sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZoomFrame {
    /// Camera width in world units (map tiles).
    pub width: f64,
    /// Pyramid level of detail at the frame's pixels.
    pub lod: f64,
    /// Mean luminance of the frame (linear).
    pub mean_luminance: f64,
}

/// What [`run`] produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Report {
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// The zoom sequence's frames.
    pub zoom: Vec<ZoomFrame>,
    /// Wall-clock seconds per step.
    pub timings: Vec<(String, f64)>,
}

struct Writer<'a> {
    dir: &'a Path,
    report: Report,
}

impl Writer<'_> {
    fn bytes(&mut self, name: &str, bytes: &[u8]) -> Result<(), FigureError> {
        let p = self.dir.join(name);
        meso_core::io::write_atomic(&p, bytes)
            .map_err(|e| ferr(format!("{}: cannot write: {e}", p.display())))?;
        self.report.files.push(p);
        Ok(())
    }
    fn png(&mut self, name: &str, img: &Image, exposure: f32) -> Result<(), FigureError> {
        let bytes = img
            .encode_png(exposure)
            .map_err(|e| ferr(format!("{name}: {e}")))?;
        self.bytes(name, &bytes)
    }
}

fn canvas(img: &Image, exposure: f32) -> Result<Canvas, FigureError> {
    Canvas::from_rgb8(img.width(), img.height(), &img.to_srgb8(exposure))
        .map_err(|e| ferr(e.to_string()))
}

/// A 16-bit grey PNG of a height map (`0` at its minimum, `65535` at its maximum) and the
/// height scale `H` that reads it back (`h = code/65535 · H + min`).
fn heightmap_png(map: &HeightMap) -> Result<(Vec<u8>, f64), FigureError> {
    map.encode_png16()
        .map_err(|e| ferr(format!("height map PNG: {e}")))
}

/// Render every figure into `opts.out` (see the crate docs); `log` receives one line per step.
///
/// # Errors
/// Unwritable output directory or files (the message names the path).
pub fn run(opts: &Options, log: &mut dyn FnMut(&str)) -> Result<Report, FigureError> {
    let dir = opts.out.as_path();
    std::fs::create_dir_all(dir)
        .map_err(|e| ferr(format!("{}: cannot create directory: {e}", dir.display())))?;
    let mut job = Job {
        w: Writer {
            dir,
            report: Report::default(),
        },
        sheet: Sheet::new("meso - Fournier 1992, multiple surfaces", 4, 256, 256),
        size: opts.size.clamp(32, 4096),
        spp: opts.spp.clamp(1, 4096),
        ropts: RenderOptions::default(),
    };
    job.spheres(log)?;
    job.zoom(opts.zoom_frames.max(6), log)?;
    job.blend_strip(log)?;
    let sheet_png = job
        .sheet
        .render()
        .and_then(|c| c.to_png_bytes())
        .map_err(|e| ferr(format!("contact sheet: {e}")))?;
    job.w.bytes("contact_sheet.png", &sheet_png)?;
    Ok(job.w.report)
}

/// The state [`run`]'s steps share: the files written, the contact sheet and the settings.
struct Job<'a> {
    w: Writer<'a>,
    sheet: Sheet,
    /// Edge of the sphere pictures in pixels.
    size: u32,
    /// Samples per pixel.
    spp: u32,
    ropts: RenderOptions,
}

impl Job<'_> {
    /// Figures 2–4: one sphere per material, with its material and scene files.
    fn spheres(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), FigureError> {
        let (size, spp) = (self.size, self.spp);
        let t0 = Instant::now();
        let spheres: Vec<(&str, String, MaterialDef)> = vec![
            (
                "fig2a_anisotropic",
                "Fig. 2a anisotropic".into(),
                catalogue::anisotropic(),
            ),
            (
                "fig2b_two_normals",
                "Fig. 2b 2 normals".into(),
                catalogue::two_normals(),
            ),
            (
                "fig2c_three_normals",
                "Fig. 2c 3 normals".into(),
                catalogue::three_normals(),
            ),
            (
                "fig2d_seven_normals",
                String::new(),
                catalogue::seven_normals(),
            ),
            ("fig3_velvet", "Fig. 3 velvet".into(), catalogue::velvet()),
            ("fig4_silk", "Fig. 4 silk".into(), catalogue::silk()),
        ]
        .into_iter()
        .map(|(stem, caption, m)| (stem, caption, MaterialDef::from(&m)))
        .collect();
        for (stem, caption, def) in &spheres {
            let t = Instant::now();
            let material = def.material()?;
            let shader: Arc<dyn Shader> = Arc::new(MaterialShader::new(&material));
            let lights: Vec<Light> = if stem.starts_with("fig2") {
                vec![key_light()]
            } else {
                vec![cloth_light()]
            };
            let scene = sphere_scene(shader, size, spp, &lights)?;
            let img = render(&scene, &self.ropts, None);
            self.w.png(&format!("{stem}.png"), &img, 0.0)?;
            self.w
                .bytes(&format!("{stem}.toml"), def.toml()?.as_bytes())?;
            self.w.bytes(
                &format!("{stem}.scene.toml"),
                sphere_scene_toml(&format!("{stem}.toml"), size, spp, &lights).as_bytes(),
            )?;
            let caption = if caption.is_empty() {
                format!("Fig. 2d {} normals", def.lobes.len())
            } else {
                caption.clone()
            };
            self.sheet.add(canvas(&img, 0.0)?, caption);
            log(&format!(
                "{stem}: {} lobes, {:.2} s",
                def.lobes.len(),
                t.elapsed().as_secs_f64()
            ));
        }
        self.w
            .report
            .timings
            .push(("spheres".into(), t0.elapsed().as_secs_f64()));
        Ok(())
    }

    /// The zoom sequence over the NDF-mapped bump map: `frames` pictures, their luminance
    /// table, and the files that reproduce them.
    fn zoom(&mut self, frames: usize, log: &mut dyn FnMut(&str)) -> Result<(), FigureError> {
        let spp = self.spp;
        let t0 = Instant::now();
        let map = bump_map()?;
        let pyr = pyramid(&map, 4)?;
        let surface_def = bump_surface();
        let surface = surface_def.material()?;
        let texels_per_uv = map.cells_x() as f64;
        let shader = Arc::new(
            NdfMapped::new(&pyr, &surface, texels_per_uv, true).map_err(|e| ferr(e.to_string()))?,
        );
        let zsize = (self.size * 3 / 5).max(32);
        let mut csv = String::from("frame,camera_width,lod,mean_luminance\n");
        for (k, &width) in zoom_widths(frames).iter().enumerate() {
            let scene = plane_scene(shader.clone(), width, zsize, spp)?;
            let img = render(&scene, &self.ropts, None);
            let lum = mean_luminance(&img);
            // The level at the image centre (the footprint is the same everywhere: orthographic).
            let lod = scene
                .intersect(&scene.camera.generate_ray(
                    f64::from(zsize) / 2.0,
                    f64::from(zsize) / 2.0,
                    zsize,
                    zsize,
                ))
                .map_or(f64::NAN, |sp| shader.lod(&sp));
            let _ = writeln!(csv, "{k},{width:.4},{lod:.4},{lum:.6}");
            self.w.report.zoom.push(ZoomFrame {
                width,
                lod,
                mean_luminance: lum,
            });
            self.w.png(&format!("zoom_{k:02}.png"), &img, 0.0)?;
            self.sheet.add(
                canvas(&img, 0.0)?,
                format!("zoom {k}: {width:.1} tiles, lod {lod:.1}"),
            );
        }
        self.w.bytes("zoom_luminance.csv", csv.as_bytes())?;
        self.zoom_files(&map, &surface_def, texels_per_uv, frames, zsize)?;
        log(&format!(
            "zoom: {frames} frames, {:.2} s",
            t0.elapsed().as_secs_f64()
        ));
        self.w
            .report
            .timings
            .push(("zoom".into(), t0.elapsed().as_secs_f64()));
        Ok(())
    }

    /// The zoom sequence's height map, its far-field and textured materials and each frame's
    /// scene file.
    fn zoom_files(
        &mut self,
        map: &HeightMap,
        surface_def: &MaterialDef,
        texels_per_uv: f64,
        frames: usize,
        zsize: u32,
    ) -> Result<(), FigureError> {
        let (png, hscale) = heightmap_png(map)?;
        self.w.bytes("zoom_heightmap.png", &png)?;
        // The bump map's far-field material: the height map's NDF under the surface's transfer.
        let surface = surface_def.to_spec()?;
        let mut mat = MaterialSpec {
            name: Some("zoom bump map, far-field (top-level) BRDF".into()),
            ndf: NdfSpec::External {
                kind: "heightmap".into(),
                table: Default::default(),
                file: "zoom_heightmap.png".into(),
            },
            ..surface.clone()
        };
        if let NdfSpec::External { table, .. } = &mut mat.ndf {
            table.insert("kind".into(), "heightmap".into());
            table.insert("file".into(), "zoom_heightmap.png".into());
            table.insert("texel_size".into(), map.texel_size().into());
            table.insert("height_scale".into(), hscale.into());
            table.insert("max_lobes".into(), 4i64.into());
        }
        let mat = mat.to_toml();
        let full = surface.to_toml();
        self.w.bytes("zoom_material.toml", mat.as_bytes())?;
        // The same bump map as a textured material for scene files, and each frame's scene, so
        // that `meso render zoom_KK.scene.toml` reproduces the frames (docs/scene-format.md).
        let mut textured = format!(
            "name = \"zoom bump map, NDF-mapped\"\n[texture]\nkind = \"ndf-mapped\"\n\
             file = \"zoom_heightmap.png\"\ntexel_size = {}\nheight_scale = {hscale}\nmax_lobes = 4\n\
             texels_per_uv = {texels_per_uv}\nshadowing = true\n",
            map.texel_size()
        );
        if let Some(pos) = full.find("[transfer]") {
            textured.push_str(&full[pos..]);
        }
        self.w.bytes("zoom_textured.toml", textured.as_bytes())?;
        for (k, &width) in zoom_widths(frames).iter().enumerate() {
            self.w.bytes(
                &format!("zoom_{k:02}.scene.toml"),
                plane_scene_toml("zoom_textured.toml", width, zsize, self.spp).as_bytes(),
            )?;
        }
        Ok(())
    }

    /// The NDF blend strip: seven spheres blending three normals into silk, with each step's
    /// material file.
    fn blend_strip(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), FigureError> {
        let (size, spp) = (self.size, self.spp);
        let t0 = Instant::now();
        let (a, b) = (
            MaterialDef::from(&catalogue::three_normals()),
            MaterialDef::from(&catalogue::silk()),
        );
        let steps = 7;
        let cam = sphere_camera(2.2 * steps as f64)?;
        let (sw, sh) = (size * 3, (size * 3 / steps as u32).max(16));
        let mut builder = SceneBuilder::new(
            cam,
            ImageSettings {
                width: sw,
                height: sh,
                spp,
                background: BACKGROUND,
            },
        );
        for k in 0..steps {
            let t = k as f64 / (steps - 1) as f64;
            let def = a.blend(&b, t);
            let m = builder.material(Arc::new(MaterialShader::new(&def.material()?)));
            let x = (k as f64 - (steps - 1) as f64 / 2.0) * 2.2;
            builder
                .sphere(DVec3::new(x, 0.0, 0.0), 1.0, DVec3::Y, m)
                .map_err(|e| ferr(e.to_string()))?;
            self.w
                .bytes(&format!("blend_t{t:.2}.toml"), def.toml()?.as_bytes())?;
        }
        builder
            .light(key_light())
            .map_err(|e| ferr(e.to_string()))?;
        let scene = builder.build().map_err(|e| ferr(e.to_string()))?;
        let img = render(&scene, &self.ropts, None);
        self.w.png("blend_strip.png", &img, 0.0)?;
        self.sheet
            .add(canvas(&img, 0.0)?, "NDF blend: 3 normals to silk");
        log(&format!("blend strip: {:.2} s", t0.elapsed().as_secs_f64()));
        self.w
            .report
            .timings
            .push(("blend".into(), t0.elapsed().as_secs_f64()));
        Ok(())
    }
}
