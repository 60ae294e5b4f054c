//! The picture of `meso ndf plot`: equal-area maps of both hemispheres on one colour scale, and
//! polar slices of the density through the mean normal. Singular NDFs (delta sums, cylinders) are
//! drawn as their normals: discs with area proportional to the weight, or the circle of normals.

use anyhow::{Context, Result};
use glam::DVec3;
use meso_core::frame::{spherical_angles, spherical_direction};
use meso_core::ndf::Ndf;
use meso_plot::{
    color, hemisphere_map_range, Canvas, ColorMap, PolarPlot, PolarSeries, Sheet, ValueScale,
};
use std::path::PathBuf;

/// Arguments of `meso ndf plot`.
#[derive(clap::Args, Debug)]
pub struct PlotArgs {
    /// Material file (TOML).
    pub material: PathBuf,
    /// Output PNG.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Colour scale of the maps.
    #[arg(long, value_enum, default_value_t = Scale::Log)]
    pub scale: Scale,
    /// Size of each hemisphere map in pixels (128–4096: below 115 the polar plot beside the
    /// maps has no room to draw).
    #[arg(long, default_value_t = 360, value_parser = clap::value_parser!(u32).range(MIN_SIZE..=4096))]
    pub size: u32,
}

/// Smallest `--size` of `meso ndf plot`: the polar plot beside the maps needs at least 115
/// pixels (its labels and a radius of 20 pixels), with a margin.
pub const MIN_SIZE: i64 = 128;

/// Estimated peak memory (bytes) of drawing the picture at `size` ([`ndf_sheet`]): its three
/// panels of `4/3·size × size` pixels, each held as values, colours and the sheet (26 bytes a
/// pixel), and 16 MiB for the rest. Measured: 35 MB at 512, 112 MB at 1024, 408 MB at 2048
/// (peak RSS; estimated 44, 126 and 453 MB).
#[must_use]
pub fn sheet_bytes(size: u32) -> u64 {
    let size = u64::from(size);
    4 * size * size * 26 + (16 << 20)
}

/// Value scale of the NDF maps.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    /// Linear in density.
    Linear,
    /// Logarithmic over four decades below the maximum.
    Log,
}

/// Render the NDF of a material to a PNG.
pub fn plot(a: &PlotArgs) -> Result<()> {
    crate::util::check_outputs(&[&a.out], &[&a.material])?;
    meso_core::budget::check(
        &a.material,
        &format!("plotting the NDF at --size {}", a.size),
        sheet_bytes(a.size),
    )?;
    let m = crate::load_material(&a.material)?;
    // Again, now that the files the material names (a height map, a map file) are read.
    crate::util::check_outputs(&[&a.out], &[])?;
    let title = format!(
        "NDF of {} ({})",
        m.name.clone().unwrap_or_else(|| a
            .material
            .file_name()
            .map_or_else(String::new, |f| f.to_string_lossy().into_owned())),
        m.ndf.kind()
    );
    let sheet = ndf_sheet(&m.ndf, &title, a.size, a.scale)?;
    sheet
        .write_png(&a.out)
        .with_context(|| format!("{}: cannot write", a.out.display()))?;
    Ok(())
}

/// The picture as a canvas (also used by `meso figures` and the editor).
pub fn ndf_sheet(ndf: &Ndf, title: &str, size: u32, scale: Scale) -> Result<Canvas> {
    let mut sheet = Sheet::new(title, 3, size + size / 3, size);
    if ndf.is_singular() {
        for upper in [true, false] {
            let mut c = hemisphere_map_range(
                |_| 0.93,
                size,
                ColorMap::Gray,
                ValueScale::Linear,
                upper,
                Some((0.0, 1.0)),
            )?;
            let g = c.geometry;
            match ndf {
                Ndf::Deltas(d) => {
                    for n in d.normals() {
                        if (n.normal.z >= 0.0) == upper {
                            if let Some(p) = g.pixel_of(n.normal) {
                                let r = (g.radius * 0.12 * n.weight.sqrt()).max(3.0);
                                c.canvas
                                    .disc_outlined(p, r, color::palette(0), 1.5, color::INK);
                            }
                        }
                    }
                }
                Ndf::Cylinder(cy) => {
                    let pts: Vec<[f64; 2]> = (0..=720)
                        .map(|k| {
                            cy.normal_at(
                                -std::f64::consts::PI
                                    + 2.0 * std::f64::consts::PI * k as f64 / 720.0,
                            )
                        })
                        .filter(|n| (n.z >= 0.0) == upper && (!cy.half || n.z >= 0.0))
                        .filter_map(|n| g.pixel_of(n))
                        .collect();
                    if pts.len() > 1 {
                        c.canvas.polyline(&pts, 3.0, color::palette(0));
                    }
                }
                _ => {}
            }
            sheet.add(
                c.canvas,
                if upper {
                    "upper hemisphere (z > 0)"
                } else {
                    "lower hemisphere (z < 0)"
                },
            );
        }
        let mut p = PolarPlot::new("weights by theta");
        p.r_label = "weight".into();
        if let Ndf::Deltas(d) = ndf {
            for (k, n) in d.normals().iter().enumerate() {
                let (t, ph) = spherical_angles(n.normal);
                let signed = if ph.cos() >= 0.0 { t } else { -t };
                p.add(
                    PolarSeries::new(
                        format!("N{}", k + 1),
                        vec![[signed, 0.0], [signed, n.weight]],
                    )
                    .with_color(color::palette(k)),
                );
            }
        }
        sheet.add(
            p.render(size + size / 3, size)?,
            "delta weights (radius) at their polar angle",
        );
        return Ok(sheet.render()?);
    }
    // Shared value range over the sphere.
    let grid = meso_core::grid::EqualAreaGrid::with_cells(40_000);
    let mut hi: f64 = 0.0;
    for c in 0..grid.len() {
        hi = hi.max(ndf.eval(grid.cell_center(c)));
    }
    hi = hi.max(1e-12);
    let (vs, range) = match scale {
        Scale::Linear => (ValueScale::Linear, (0.0, hi)),
        Scale::Log => (ValueScale::Log, (hi * 1e-4, hi)),
    };
    for upper in [true, false] {
        let map = hemisphere_map_range(
            |d| {
                let v = ndf.eval(d);
                if scale == Scale::Log {
                    v.max(range.0)
                } else {
                    v
                }
            },
            size,
            ColorMap::Viridis,
            vs,
            upper,
            Some(range),
        )?;
        sheet.add(
            map.with_colorbar("n (1/sr)"),
            if upper {
                "upper hemisphere (z > 0), equal-area"
            } else {
                "lower hemisphere (z < 0), equal-area"
            },
        );
    }
    // Polar slices through the mean normal: the plane of φ_mean and the plane across it.
    let st = ndf.stats();
    let phi0 = if st.mean_normal.truncate().length() > 1e-9 {
        spherical_angles(st.mean_normal).1
    } else {
        0.0
    };
    let mut p = PolarPlot::new("slices through the mean normal");
    p.r_label = "n (1/sr)".into();
    for (k, phi) in [phi0, phi0 + std::f64::consts::FRAC_PI_2]
        .into_iter()
        .enumerate()
    {
        let pts: Vec<[f64; 2]> = (0..=360)
            .map(|j| {
                let t = -90.0 + 0.5 * j as f64;
                let d: DVec3 = spherical_direction(
                    t.abs().to_radians(),
                    if t >= 0.0 {
                        phi
                    } else {
                        phi + std::f64::consts::PI
                    },
                );
                [t.to_radians(), ndf.eval(d)]
            })
            .collect();
        p.add(
            PolarSeries::new(
                format!("phi = {:.0} deg", phi.to_degrees().rem_euclid(360.0)),
                pts,
            )
            .with_color(color::palette(k)),
        );
    }
    sheet.add(
        p.render(size + size / 3, size)?,
        "polar slices (upper hemisphere)",
    );
    Ok(sheet.render()?)
}
