//! How well do a pyramid's fitted lobes give the view-weighted shading of a steep map, before
//! any shadowing? A diagnostic of the lobes' shape (docs/heightmaps.md, "The lobes' shape
//! under the viewer's weight").
//!
//! View weighting (`meso_render::NdfMapped::with_view_weighting`) weighs each normal `m` of a
//! footprint by the area the viewer `o` sees of it, `(m·o)⁺/m_z` per unit of projected area.
//! Lambert facets lit from `l` then read, per footprint, the seen-weighted mean of `(m·l)⁺`:
//!
//! `S = Σ share · E[(m·o)⁺ (m·l)⁺ / m_z] / Σ share · E[(m·o)⁺ / m_z]`,
//!
//! and GGX facets of roughness α (given as the last argument; Fresnel 1, no shadowing inside a
//! facet) the same with `(m·o)⁺ (m·l)⁺` replaced by `D_α(h·m)/4`, `h` the half vector of `l`
//! and `o` (the facet BRDF `D/(4 (m·l)(m·o))` times both cosines),
//!
//! each lobe's expectation over its projected area (`m_z`-weighted, its part below the horizon
//! dropped, as the renderer drops it) and `share` its part of the texel's projected area
//! ([`meso_maps::lobe_stats`]). Per level, the lobes' `S` summed over the map (each lobe
//! integrated finely: 400 angles to its axis out to 12 widths of the peak × 48 azimuths) is
//! printed as a ratio to the same sum over level 0's facets, the exact value. No horizon
//! statistics are read: a ratio away from 1 is the lobes' shape alone.
//!
//! ```text
//! cargo run --release -p meso-maps --example seen_weighted -- HEIGHTS HEIGHT_SCALE \
//!     [MAX_LOBES] [LIGHT_AZ LIGHT_ELEV VIEW_AZ VIEW_ELEV] [GGX_ALPHA]
//! ```
//!
//! Angles in degrees (azimuth from +x towards +y, elevation above the plane); defaults: 4
//! lobes, the light at azimuth 90° and elevation 21°, the viewer at 270° and 30° (the light
//! opposite a grazing viewer), Lambert facets (`GGX_ALPHA` 0). The map tiles
//! (`Border::Wrap`), texel size 1.
use glam::DVec3;
use meso_core::frame::Frame;
use meso_maps::{extract, lobe_stats, Border, ExtractParams, HeightMap, Source};
use std::path::Path;

/// A unit direction of azimuth `az` and elevation `el` (degrees).
fn dir(az: f64, el: f64) -> DVec3 {
    let (a, e) = (az.to_radians(), el.to_radians());
    DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!(
            "usage: seen_weighted HEIGHTS HEIGHT_SCALE [MAX_LOBES] \
             [LIGHT_AZ LIGHT_ELEV VIEW_AZ VIEW_ELEV] [GGX_ALPHA]"
        );
        std::process::exit(2);
    }
    let num = |i: usize, d: f64| -> f64 {
        args.get(i).map_or(d, |s| {
            s.parse()
                .unwrap_or_else(|_| panic!("argument {}: not a number: {s}", i + 1))
        })
    };
    let map = HeightMap::load(Path::new(&args[0]), 1.0, num(1, 1.0), Border::Wrap)
        .unwrap_or_else(|e| panic!("{}: {e}", args[0]));
    let params = ExtractParams::default().with_max_lobes(num(2, 4.0) as usize);
    let (l, o) = (
        dir(num(3, 90.0), num(4, 21.0)),
        dir(num(5, 270.0), num(6, 30.0)),
    );
    let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).expect("extraction");
    let stats = lobe_stats(&pyr, false);
    // The seen-weighted response and the seen weight of a normal, per unit of projected area.
    let alpha = num(7, 0.0);
    let ggx = (alpha > 0.0).then(|| {
        meso_core::ndf::microfacet::Microfacet::isotropic(
            meso_core::ndf::microfacet::Distribution::Ggx,
            alpha,
        )
        .unwrap_or_else(|e| panic!("GGX_ALPHA {alpha}: {e}"))
    });
    let h = (l + o).normalize();
    let lit_seen = |m: DVec3| {
        let (ml, mo) = (m.dot(l), m.dot(o));
        if ml <= 0.0 || mo <= 0.0 {
            return 0.0;
        }
        match &ggx {
            Some(g) => g.d_isotropic(h.dot(m)) / (4.0 * m.z),
            None => mo * ml / m.z,
        }
    };
    let seen = |m: DVec3| m.dot(o).max(0.0) / m.z;
    // Level 0: its facets (sharp lobes) by their share of their cell's projected area.
    let l0 = &pyr.levels[0];
    let (mut num0, mut den0) = (0.0, 0.0);
    for (p, &sh) in l0.lobes.range(0, l0.lobes.len()).zip(&stats.shares[0]) {
        if p.axis.z > 0.0 {
            num0 += sh * lit_seen(p.axis);
            den0 += sh * seen(p.axis);
        }
    }
    let exact = num0 / den0;
    println!(
        "{}: {}x{}, height scale {}, at most {} lobes; level 0 (the facets): S = {exact:.4}",
        args[0],
        map.width(),
        map.height(),
        num(1, 1.0),
        params.fit.max_lobes
    );
    // A fine rule for a Phong peak `cos^η(θ/2)` about its axis: angles to the axis.
    const ANGLES: usize = 400;
    const AZIMUTHS: usize = 48;
    for (k, lv) in pyr.levels.iter().enumerate().skip(1) {
        let (mut n, mut d) = (0.0, 0.0);
        for (p, &sh) in lv.lobes.range(0, lv.lobes.len()).zip(&stats.shares[k]) {
            if sh <= 0.0 {
                continue;
            }
            let f = Frame::from_normal_tangent(p.axis.normalize(), DVec3::X);
            let (mut wz, mut a, mut b) = (0.0, 0.0, 0.0);
            // Angles to the axis out to 12 widths of the peak (`cos^η(θ/2) ≈ e^{−ηθ²/8}`).
            let reach = (24.0 / p.exponent.max(1e-9).sqrt()).min(std::f64::consts::PI);
            for i in 0..ANGLES {
                let th = (i as f64 + 0.5) * reach / ANGLES as f64;
                let (s, c) = th.sin_cos();
                let dens = (0.5 * (1.0 + c)).powf(0.5 * p.exponent) * s;
                if dens < 1e-300 {
                    continue;
                }
                for j in 0..AZIMUTHS {
                    let ph = std::f64::consts::TAU * (j as f64 + 0.5) / AZIMUTHS as f64;
                    let m = f.to_world(DVec3::new(s * ph.cos(), s * ph.sin(), c));
                    if m.z > 0.0 {
                        wz += dens * m.z;
                        a += dens * m.z * lit_seen(m);
                        b += dens * m.z * seen(m);
                    }
                }
            }
            if wz > 0.0 {
                n += sh * a / wz;
                d += sh * b / wz;
            }
        }
        println!(
            "level {k:2} ({}x{}, {} lobes): S = {:.4}, {:.3} of the facets'",
            lv.cols,
            lv.rows,
            lv.lobes.len(),
            n / d,
            n / d / exact
        );
    }
}
