//! `meso ndf plot|stats MATERIAL` — look at a material's NDF.

use super::ndf_plot::PlotArgs;
use anyhow::Result;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Inspect the NDF of a material.
#[derive(clap::Subcommand, Debug)]
pub enum NdfCommand {
    /// Picture of the NDF: equal-area maps of the upper and lower hemispheres with a colour scale,
    /// and polar slices through the mean normal.
    Plot(PlotArgs),
    /// Normalisation integral (Eq. 1), mean normal and covariance of the NDF.
    Stats(StatsArgs),
}

/// Arguments of `meso ndf stats`.
#[derive(clap::Args, Debug)]
pub struct StatsArgs {
    /// Material file (TOML).
    pub material: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Run the subcommand.
pub fn run(c: NdfCommand) -> Result<()> {
    match c {
        NdfCommand::Stats(a) => stats(a),
        NdfCommand::Plot(a) => super::ndf_plot::plot(&a),
    }
}

fn stats(a: StatsArgs) -> Result<()> {
    let m = crate::load_material(&a.material)?;
    let s = m.ndf.stats();
    let mu = s.mean_normal;
    let c = s.covariance;
    let (theta, phi) = if mu.length() > 1e-12 {
        let (t, p) = meso_core::frame::spherical_angles(mu);
        (t.to_degrees(), p.to_degrees())
    } else {
        (f64::NAN, f64::NAN)
    };
    let rows = [c.x_axis, c.y_axis, c.z_axis];
    if a.json {
        let json = format!(
            "{{\"kind\":\"{}\",\"integral\":{:.9},\"mean_normal\":[{:.9},{:.9},{:.9}],\"mean_length\":{:.9},\"mean_theta_deg\":{},\"mean_phi_deg\":{},\"covariance\":[[{:.9},{:.9},{:.9}],[{:.9},{:.9},{:.9}],[{:.9},{:.9},{:.9}]]}}",
            m.ndf.kind(),
            s.integral,
            mu.x, mu.y, mu.z,
            mu.length(),
            json_num(theta),
            json_num(phi),
            rows[0].x, rows[1].x, rows[2].x,
            rows[0].y, rows[1].y, rows[2].y,
            rows[0].z, rows[1].z, rows[2].z,
        );
        return crate::util::print_stdout(&(json + "\n"));
    }
    let mut t = String::new();
    let _ = writeln!(t, "ndf kind        {}", m.ndf.kind());
    let _ = writeln!(t, "integral (Eq.1) {:.6}", s.integral);
    let _ = writeln!(
        t,
        "mean normal     [{:.6}, {:.6}, {:.6}]  (length {:.6}; theta {:.2} deg, phi {:.2} deg)",
        mu.x,
        mu.y,
        mu.z,
        mu.length(),
        theta,
        phi
    );
    let _ = writeln!(
        t,
        "covariance      [{:+.6} {:+.6} {:+.6}]",
        rows[0].x, rows[1].x, rows[2].x
    );
    let _ = writeln!(
        t,
        "                [{:+.6} {:+.6} {:+.6}]",
        rows[0].y, rows[1].y, rows[2].y
    );
    let _ = writeln!(
        t,
        "                [{:+.6} {:+.6} {:+.6}]",
        rows[0].z, rows[1].z, rows[2].z
    );
    crate::util::print_stdout(&t)
}

fn json_num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.6}")
    } else {
        "null".into()
    }
}
