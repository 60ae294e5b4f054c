//! Writes `gallery.png` (or the path given as the first argument): a contact sheet showing
//! every kind of picture meso-plot makes — line plots (linear and log), a polar BRDF slice,
//! hemisphere maps with colour bars, colour maps and the font.

use meso_plot::color::{self, hex};
use meso_plot::font::{self, draw_text};
use meso_plot::{
    colorbar_scaled, hemisphere_map, Canvas, ColorMap, LinePlot, LineStyle, PolarPlot, PolarSeries,
    Rect, Series, Sheet, ValueScale,
};

fn phong_ndf(m: glam::DVec3, axis: glam::DVec3, n: f64) -> f64 {
    let c = m.dot(axis).max(0.0);
    (n + 2.0) / (2.0 * std::f64::consts::PI) * c.powf(n)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "gallery.png".into());
    let (tw, th) = (640u32, 440u32);
    let mut sheet = Sheet::new("meso-plot gallery", 3, tw, th);

    // 1. Line plot: Phong lobes of several exponents.
    let mut lp = LinePlot::new("Phong lobe cos^n θ");
    lp.x_label = "θ (deg)".into();
    lp.y_label = "D(θ) / D(0)".into();
    for (i, n) in [1.0f64, 5.0, 20.0, 100.0].iter().enumerate() {
        let pts = (0..=180)
            .map(|k| {
                let d = f64::from(k) * 0.5;
                [d, d.to_radians().cos().powf(*n)]
            })
            .collect();
        let style = if i == 3 {
            LineStyle::Dashed
        } else {
            LineStyle::Solid
        };
        lp.add(Series::new(format!("n = {n}"), pts).with_style(style));
    }
    sheet.add(lp.render(tw, th)?, "LinePlot, linear y");

    // 2. Log plot: data vs model with markers.
    let mut lg = LinePlot::new("Fit residual");
    lg.x_label = "iteration".into();
    lg.y_label = "error".into();
    lg.log_y = true;
    let model: Vec<[f64; 2]> = (0..=40)
        .map(|k| [f64::from(k), 2.0 * (-0.25 * f64::from(k)).exp() + 1e-4])
        .collect();
    let data: Vec<[f64; 2]> = model
        .iter()
        .step_by(4)
        .enumerate()
        .map(|(i, p)| [p[0], p[1] * (1.0 + 0.3 * ((i as f64) * 1.7).sin())])
        .collect();
    lg.add(Series::new("model", model));
    lg.add(Series::new("measured", data).with_style(LineStyle::None));
    sheet.add(lg.render(tw, th)?, "LinePlot, log y, markers");

    // 3. Polar slice of a BRDF-like lobe in the plane of incidence.
    let ti = -35f64.to_radians();
    let lobe = |t: f64| 0.2 + 1.6 * (t + ti).cos().max(0.0).powf(30.0);
    let mut pp = PolarPlot::new("BRDF slice, θi = 35°");
    pp.r_label = "f_r (1/sr)".into();
    pp.incident = Some(ti);
    pp.add(PolarSeries::from_fn("model", lobe, 361));
    let meas: Vec<[f64; 2]> = (0..=36)
        .map(|k| {
            let t = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * f64::from(k) / 36.0;
            [t, lobe(t) * (1.0 + 0.06 * (f64::from(k) * 2.3).sin())]
        })
        .collect();
    pp.add(PolarSeries::new("data", meas).with_style(LineStyle::None));
    sheet.add(pp.render(tw, th)?, "PolarPlot with incident ray");

    // 4–6. Hemisphere maps.
    let a1 = meso_core::frame::spherical_direction_deg(25.0, 30.0);
    let a2 = meso_core::frame::spherical_direction_deg(45.0, 200.0);
    let ndf = |m: glam::DVec3| 0.6 * phong_ndf(m, a1, 40.0) + 0.4 * phong_ndf(m, a2, 15.0);
    let lin = hemisphere_map(ndf, th, ColorMap::Viridis, ValueScale::Linear, true)?;
    sheet.add(
        lin.with_colorbar("D(m) (1/sr)"),
        "hemisphere_map, viridis, linear",
    );
    let log = hemisphere_map(ndf, th, ColorMap::Magma, ValueScale::Log, true)?;
    sheet.add(log.with_colorbar("D(m), log"), "hemisphere_map, magma, log");
    let diff = hemisphere_map(
        |m| {
            phong_ndf(m, a1, 40.0)
                - phong_ndf(
                    m,
                    meso_core::frame::spherical_direction_deg(28.0, 38.0),
                    40.0,
                )
        },
        th,
        ColorMap::BlueWhiteRed,
        ValueScale::Linear,
        true,
    )?;
    sheet.add(
        diff.with_colorbar("difference"),
        "diverging map of a difference",
    );

    // 7. Colour maps.
    let mut cm = Canvas::new(tw, th, color::PAPER);
    for (i, m) in ColorMap::ALL.iter().enumerate() {
        let y = 30 + i as i32 * 100;
        draw_text(&mut cm, 30, y, m.name(), 2, color::INK);
        colorbar_scaled(
            &mut cm,
            Rect::new(30, y + 26, 560, 22),
            *m,
            0.0,
            1.0,
            ValueScale::Linear,
            5,
            "",
            2,
        );
    }
    sheet.add(cm, "colour maps with colour bars");

    // 8. The font.
    let mut ft = Canvas::new(tw, th, color::PAPER);
    let lines = [
        " !\"#$%&'()*+,-./0123456789:;<=>?",
        "@ABCDEFGHIJKLMNOPQRSTUVWXYZ[\\]^_",
        "`abcdefghijklmnopqrstuvwxyz{|}~",
        "° θ φ · µ σ α π ² ³ × −",
    ];
    let mut y = 24;
    for l in lines {
        draw_text(&mut ft, 24, y, l, 2, color::INK);
        y += (font::LINE_HEIGHT * 2) as i32 + 4;
    }
    y += 10;
    draw_text(&mut ft, 24, y, "The quick brown fox jumps", 3, color::INK);
    y += (font::LINE_HEIGHT * 3) as i32;
    draw_text(&mut ft, 24, y, "over the lazy dog. 0.125", 3, color::INK);
    y += (font::LINE_HEIGHT * 3) as i32 + 8;
    draw_text(
        &mut ft,
        24,
        y,
        "Scale 1: D(m) = (n+2)/(2π) cos^n θm, θ ∈ [0°, 90°]",
        1,
        hex(0x4E79A7),
    );
    sheet.add(ft, "5×7 bitmap font, scales 1–3");

    // 9. Canvas primitives.
    let mut pr = Canvas::new(tw, th, color::PAPER);
    for k in 0..24u32 {
        let a = f64::from(k) / 24.0 * std::f64::consts::TAU;
        let c = [220.0, 220.0];
        pr.line(
            c,
            [c[0] + 180.0 * a.cos(), c[1] + 180.0 * a.sin()],
            1.0 + f64::from(k % 3),
            color::palette(k as usize),
        );
    }
    pr.disc_outlined([500.0, 120.0], 70.0, hex(0xF28E2B), 2.0, color::INK);
    pr.circle([500.0, 320.0], 70.0, 4.0, hex(0x59A14F));
    pr.fill_rect(Rect::new(440, 300, 40, 40), hex(0xB07AA1));
    sheet.add(pr, "anti-aliased primitives");

    let c = sheet.render()?;
    c.write_png(&out)?;
    println!("wrote {out} ({}×{})", c.width(), c.height());
    Ok(())
}
