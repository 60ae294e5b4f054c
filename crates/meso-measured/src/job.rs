//! The reusable core of `meso fit` (CLI) and `meso.fit` (Python): loading a data file (MERL
//! binary or sample CSV) into a [`SampleSet`] with the hold-out rule and a description, the lobe
//! fits for either facet transfer ([`fit_lobes`], [`Lobes`]) and the comment written at the top
//! of the fitted material file ([`material_comment`]).

use crate::csv::CsvError;
use crate::fit::{FitError, FitOptions, FitResult};
use crate::merl::{MerlError, MerlTable, MERL_FILE_BYTES};
use crate::model::{self, LobeGgxParams, LobeMicrofacetParams, LobeParams, TransferExponent};
use crate::samples::{MerlSampling, SampleSet};
use glam::DVec3;
use meso_core::budget::BudgetError;
use meso_core::display::Num;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Largest sample CSV read (bytes actually read).
pub const MAX_CSV_BYTES: u64 = 1 << 30;

/// Largest BRDF value (1/sr, any channel) of data to fit: 10¹². Measured BRDFs stay far
/// below (a MERL table's sharpest specular peaks are near 10⁴); values near `f64`'s range make
/// the fit's squared errors and fitted albedos infinite.
pub const MAX_BRDF_VALUE: f64 = 1e12;

/// Refuse samples (fitted or held out) with a BRDF value above [`MAX_BRDF_VALUE`]; `what`
/// names the data in the error.
fn check_values(samples: &SampleSet, what: &str) -> Result<(), LoadError> {
    let too_large = samples
        .samples
        .iter()
        .chain(&samples.held_out)
        .flat_map(|s| s.rgb)
        .find(|v| *v > MAX_BRDF_VALUE);
    match too_large {
        Some(value) => Err(LoadError::TooLarge {
            what: what.to_owned(),
            value,
        }),
        None => Ok(()),
    }
}

/// Scattered data (CSV) with at least this many samples above the horizon keep every
/// [`HOLD_OUT_EVERY`]-th sample out of the fit, to report the held-out residual.
pub const HOLD_OUT_MIN: usize = 200;
/// See [`HOLD_OUT_MIN`].
pub const HOLD_OUT_EVERY: usize = 10;

/// Errors loading the data to fit. The messages name the file; causes are kept as sources.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file cannot be opened or read.
    #[error("{}: cannot read", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The CSV file cannot be read (too large, or an I/O error: `error` says which).
    #[error("{}: {}{error}", path.display(), if error.kind() == std::io::ErrorKind::FileTooLarge { "" } else { "cannot read: " })]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong (part of the message, not a source).
        error: std::io::Error,
    },
    /// Fitting the MERL table would exceed the memory budget.
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// The MERL table is invalid.
    #[error(transparent)]
    Merl(#[from] MerlError),
    /// The MERL table has no usable cells.
    #[error("{}: no measured cells with θi, θo < 80° (of {total} cells, {missing} missing)", path.display())]
    NoMerlCells {
        /// The file.
        path: PathBuf,
        /// Cells in the table.
        total: usize,
        /// Cells not measured.
        missing: usize,
    },
    /// Every measured cell of the MERL table is 0: no reflectance to fit.
    #[error("{}: every measured cell is 0 ({cells} cells): no reflectance to fit", path.display())]
    AllZero {
        /// The file.
        path: PathBuf,
        /// Measured cells (θi, θo < 80°).
        cells: usize,
    },
    /// Neither a MERL binary nor UTF-8 text.
    #[error("{}: neither a MERL binary (header 90, 90, 180) nor a UTF-8 sample CSV", path.display())]
    NotUtf8 {
        /// The file.
        path: PathBuf,
    },
    /// The text is not a valid sample CSV.
    #[error("{}: not a valid sample CSV", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// The cause (line and column).
        source: CsvError,
    },
    /// A BRDF value is above [`MAX_BRDF_VALUE`]: not data the fit can represent.
    #[error(
        "{what}: BRDF value {} is above {} 1/sr, more than the fit can represent (its error \
         sums would overflow to infinity); check the data's units",
        Num(*value),
        Num(MAX_BRDF_VALUE)
    )]
    TooLarge {
        /// The data (a file path as displayed, or a description).
        what: String,
        /// The first value above the limit.
        value: f64,
    },
    /// No sample has both directions above the horizon.
    #[error("{what}: no sample has both directions above the horizon")]
    NoneAboveHorizon {
        /// The data (a file path as displayed, or a description).
        what: String,
    },
}

/// The loaded data.
#[derive(Clone, Debug)]
pub struct Data {
    /// The samples fitted (with the held-out ones, if any).
    pub samples: SampleSet,
    /// The MERL table, when the data is one.
    pub merl: Option<MerlTable>,
    /// One line: the kind of data, how many samples are fitted and held out.
    pub description: String,
    /// The MERL cells asked for (`meso fit --samples`: the stratified subsample's target, 0 =
    /// all valid cells) when the data is a MERL table, `None` for sample CSVs; written into the
    /// fitted material's header so that its command line re-runs the same fit.
    pub merl_target: Option<usize>,
}

/// Load a MERL binary (detected by its header, its size or the `.binary` extension; `target`
/// cells in a stratified subsample, 0 = all valid ones) or a CSV of samples (the samples with
/// both directions above the horizon; every [`HOLD_OUT_EVERY`]-th one held out when there are
/// at least [`HOLD_OUT_MIN`]), as `meso fit DATA` does.
///
/// # Errors
/// [`LoadError`] naming the file.
pub fn load(path: &Path, target: usize) -> Result<Data, LoadError> {
    let io = |source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    let mut head = [0u8; 12];
    let n = {
        use std::io::Read;
        meso_core::io::note_input(path);
        let mut f = std::fs::File::open(path).map_err(io)?;
        let mut n = 0;
        while n < 12 {
            let k = f.read(&mut head[n..]).map_err(io)?;
            if k == 0 {
                break;
            }
            n += k;
        }
        n
    };
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let is_merl = MerlTable::has_header(&head[..n])
        || meta.len() == MERL_FILE_BYTES
        || ext.eq_ignore_ascii_case("binary");
    if is_merl {
        // The table and, after reading, its sampling (reading checks its own peak too); a
        // file with a wrong header or size is refused by the reader, before it allocates.
        if MerlTable::has_header(&head[..n]) && meta.len() == MERL_FILE_BYTES {
            meso_core::budget::check(
                path,
                "fitting a MERL table",
                crate::merl::MERL_READ_BYTES
                    .max(crate::merl::MERL_TABLE_BYTES + crate::samples::merl_sampling_bytes()),
            )?;
        }
        let table = MerlTable::read(path)?;
        let (samples, stats) = SampleSet::from_merl(
            &table,
            &MerlSampling {
                target,
                ..MerlSampling::default()
            },
        );
        if samples.is_empty() {
            return Err(LoadError::NoMerlCells {
                path: path.to_path_buf(),
                total: stats.total,
                missing: stats.missing,
            });
        }
        check_values(&samples, &path.display().to_string())?;
        let zero = |v: &[crate::samples::Sample]| v.iter().all(|s| s.rgb == [0.0; 3]);
        if zero(&samples.samples) && zero(&samples.held_out) {
            return Err(LoadError::AllZero {
                path: path.to_path_buf(),
                cells: samples.len() + samples.held_out.len(),
            });
        }
        return Ok(Data {
            description: format!(
                "MERL binary, {} of {} valid cells fitted, {} other cells held out (θi, θo < 80°; {} cells not measured)",
                stats.kept, stats.valid, samples.held_out.len(), stats.missing
            ),
            samples,
            merl: Some(table),
            merl_target: Some(target),
        });
    }
    let bytes =
        meso_core::io::read_limited(path, MAX_CSV_BYTES).map_err(|error| LoadError::Read {
            path: path.to_path_buf(),
            error,
        })?;
    let Ok(text) = String::from_utf8(bytes) else {
        return Err(LoadError::NotUtf8 {
            path: path.to_path_buf(),
        });
    };
    let rows = crate::csv::parse_csv(&text).map_err(|source| LoadError::Csv {
        path: path.to_path_buf(),
        source,
    })?;
    scattered(
        SampleSet::from_csv(&rows),
        "sample CSV",
        &path.display().to_string(),
    )
}

/// Scattered samples (a CSV's, or arrays') prepared for fitting: the samples with both
/// directions above the horizon, every [`HOLD_OUT_EVERY`]-th one held out when there are at least
/// [`HOLD_OUT_MIN`]. `kind` starts the description (`"sample CSV"`); `what` names the data in
/// the error.
///
/// # Errors
/// [`LoadError::TooLarge`] for a BRDF value above [`MAX_BRDF_VALUE`];
/// [`LoadError::NoneAboveHorizon`] when no sample is usable.
pub fn scattered(samples: SampleSet, kind: &str, what: &str) -> Result<Data, LoadError> {
    check_values(&samples, what)?;
    let above = |s: &crate::samples::Sample| s.wi.z > 1e-9 && s.wo.z > 1e-9;
    if !samples.samples.iter().any(above) {
        return Err(LoadError::NoneAboveHorizon {
            what: what.to_owned(),
        });
    }
    let samples = SampleSet {
        samples: samples.samples.into_iter().filter(above).collect(),
        ..samples
    };
    let n = samples.len();
    let samples = if n >= HOLD_OUT_MIN {
        samples.hold_out_every(HOLD_OUT_EVERY)
    } else {
        samples
    };
    Ok(Data {
        description: format!(
            "{kind}, {n} samples above the horizon, {} fitted, {} held out",
            samples.len(),
            samples.held_out.len()
        ),
        samples,
        merl: None,
        merl_target: None,
    })
}

/// The facet transfer function of the lobe model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transfer {
    /// Phong facets `max(0, m·H)^η_t`, multiple-surface form ([`model::LobeModel`]).
    Phong,
    /// Mirror facets with Schlick Fresnel and Smith masking–shadowing, microfacet form
    /// ([`model::LobeMicrofacetModel`]).
    Microfacet,
    /// Mirror facets as [`Transfer::Microfacet`] under a mixture of GGX lobes (NDFs with long
    /// tails; each lobe GGX or Beckmann, whichever fits better) instead of Phong peaks
    /// ([`model::LobeGgxModel`]); K = 1 is GGX + Lambert or Beckmann + Lambert.
    GgxLobes,
    /// [`Transfer::GgxLobes`] with a third candidate per lobe, a Student-t lobe whose tail
    /// exponent γ is fitted too ([`model::lobes_ggx::GGX_BECKMANN_OR_STUDENT_T`]): tails between
    /// Beckmann's (γ → ∞) and heavier than GGX's (γ = 2). Not among `--transfer auto`'s families
    /// ([`Transfer::ALL`]): docs/measured.md, "Student-t lobes", gives its cost and its results.
    StudentTLobes,
}

impl Transfer {
    /// Every family, in the order `--transfer auto` tries them.
    pub const ALL: [Transfer; 3] = [Transfer::Microfacet, Transfer::Phong, Transfer::GgxLobes];

    /// Every family there is: [`Transfer::ALL`] and [`Transfer::StudentTLobes`].
    pub const EVERY: [Transfer; 4] = [
        Transfer::Microfacet,
        Transfer::Phong,
        Transfer::GgxLobes,
        Transfer::StudentTLobes,
    ];

    /// The name `meso fit --transfer` takes (`phong`, `microfacet`, `ggx-lobes`,
    /// `student-t-lobes`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Transfer::Phong => "phong",
            Transfer::Microfacet => "microfacet",
            Transfer::GgxLobes => "ggx-lobes",
            Transfer::StudentTLobes => "student-t-lobes",
        }
    }

    /// The family named `s` ([`Transfer::name`]).
    #[must_use]
    pub fn from_name(s: &str) -> Option<Transfer> {
        Transfer::EVERY.into_iter().find(|t| t.name() == s)
    }
}

/// The progressive fits K = 1..k of one family, each lobe material with its fit result.
pub type Fits = Vec<(Lobes, FitResult)>;

/// `meso fit --lobes auto`: one more lobe must lower the held-out error ([`selection_error`]) by
/// at least this fraction (1 %) to be kept …
pub const AUTO_LOBES_GAIN: f64 = 0.01;

/// … and by at least this much in the metric's own unit (10⁻⁴; fits of MERL materials have
/// held-out log-metric errors of 10⁻³ to 4·10⁻², docs/measured.md): below it a lobe fits noise
/// or rounding, not the material.
pub const AUTO_LOBES_FLOOR: f64 = 1e-4;

/// `meso fit --lobes auto` fits up to this many lobes.
pub const AUTO_LOBES_MAX: usize = 6;

/// The number of lobes `--lobes auto` keeps from progressive fits K = 1..n: the smallest K after
/// which one more lobe lowers the [`selection_error`] by less than [`AUTO_LOBES_GAIN`] of it or
/// less than [`AUTO_LOBES_FLOOR`].
#[must_use]
pub fn auto_lobes(fits: &Fits, data: &SampleSet, metric: crate::metric::Metric) -> usize {
    let errors: Vec<f64> = fits
        .iter()
        .map(|(l, _)| selection_error(l, data, metric).0)
        .collect();
    for k in 1..errors.len() {
        let gain = errors[k - 1] - errors[k];
        if gain < AUTO_LOBES_GAIN * errors[k - 1] || gain < AUTO_LOBES_FLOOR {
            return k;
        }
    }
    errors.len().max(1)
}

/// One transfer family tried by [`fit_best`]: its K-lobe fit's error in the metric minimised.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tried {
    /// The family.
    pub transfer: Transfer,
    /// Mean over r, g, b of the error in the metric minimised (1/sr for Ngan's L2, dimensionless
    /// for the log metric and for [`Metric::Both`](crate::metric::Metric::Both), whose error is
    /// [`Objective::error`](crate::metric::Objective::error) with the weights of the fitted
    /// samples).
    pub error: f64,
    /// Whether `error` is on held-out samples (false: on the fitted ones, when none are held out).
    pub held_out: bool,
}

/// The error of `lobes` that picks a family: the channel mean of the metric `opts.metric` on the
/// held-out samples, or on the fitted ones when none are held out.
#[must_use]
pub fn selection_error(
    lobes: &Lobes,
    data: &SampleSet,
    metric: crate::metric::Metric,
) -> (f64, bool) {
    let eval = |wi, wo| lobes.eval(wi, wo);
    let (e, held_out) = if data.held_out.is_empty() {
        (crate::fit::evaluate_fn(data, eval), false)
    } else {
        (crate::fit::evaluate_samples_fn(&data.held_out, eval), true)
    };
    let v = metric.objective(&data.samples).error(&e);
    ((v[0] + v[1] + v[2]) / 3.0, held_out)
}

/// Fit K lobes with each of `candidates` ([`fit_lobes`]; with `auto_k`, up to K and cut at
/// [`auto_lobes`]) and keep the family whose last fit has the lowest [`selection_error`]
/// (`meso fit --transfer auto`, the default, tries [`Transfer::ALL`]: measured on MERL data,
/// docs/measured.md). Returns the winner, its
/// progressive fits and every family's error.
///
/// # Errors
/// The first fit that fails.
pub fn fit_best(
    k: usize,
    auto_k: bool,
    candidates: &[Transfer],
    data: &SampleSet,
    opts: &FitOptions,
) -> Result<(Transfer, Fits, Vec<Tried>), FitError> {
    let mut best: Option<(Transfer, Fits, f64)> = None;
    let mut tried = Vec::new();
    for &t in candidates {
        let mut fits = fit_lobes(k, t, data, opts)?;
        if auto_k {
            fits.truncate(auto_lobes(&fits, data, opts.metric));
        }
        let Some((lobes, _)) = fits.last() else {
            continue;
        };
        let (error, held_out) = selection_error(lobes, data, opts.metric);
        tried.push(Tried {
            transfer: t,
            error,
            held_out,
        });
        if best.as_ref().is_none_or(|b| error < b.2) {
            best = Some((t, fits, error));
        }
    }
    let (t, fits, _) = best.expect("at least one candidate transfer");
    Ok((t, fits, tried))
}

/// A fitted lobe material (either transfer).
#[derive(Clone, Debug)]
pub enum Lobes {
    /// Phong transfer.
    Phong(LobeParams),
    /// Mirror transfer (microfacet form).
    Microfacet(LobeMicrofacetParams),
    /// Mirror transfer (microfacet form) under a mixture of GGX / Beckmann lobes.
    GgxLobes(LobeGgxParams),
}

impl Lobes {
    /// The closed-form BRDF (1/sr, RGB).
    #[must_use]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        match self {
            Lobes::Phong(p) => p.eval(wi, wo),
            Lobes::Microfacet(p) => p.eval(wi, wo),
            Lobes::GgxLobes(p) => p.eval(wi, wo),
        }
    }

    /// The Phong peaks of the NDF (none for a GGX / Beckmann mixture: its lobes are
    /// [`LobeGgxParams::lobes`]).
    #[must_use]
    pub fn lobes(&self) -> &[meso_core::ndf::PhongLobe] {
        match self {
            Lobes::Phong(p) => &p.lobes,
            Lobes::Microfacet(p) => &p.lobes,
            Lobes::GgxLobes(_) => &[],
        }
    }

    /// The material of the fit ([`meso_core::material::MaterialSpec`]).
    ///
    /// # Errors
    /// Parameters that make no NDF (a fit that diverged to non-finite numbers).
    pub fn to_spec(&self) -> Result<meso_core::material::MaterialSpec, meso_core::NdfError> {
        match self {
            Lobes::Phong(p) => p.to_spec(),
            Lobes::Microfacet(p) => p.to_spec(),
            Lobes::GgxLobes(p) => p.to_spec(),
        }
    }

    /// The meso material file ([`Lobes::to_spec`] written by `MaterialSpec::to_toml`),
    /// `comment` as `#` lines at the top.
    #[must_use]
    pub fn to_toml(&self, comment: &str) -> String {
        crate::model::material_file(self.to_spec(), comment)
    }

    /// A table of the lobes and the transfer and diffuse parameters (several lines, no final
    /// newline).
    #[must_use]
    pub fn describe(&self) -> String {
        let mut s = String::new();
        if let Lobes::GgxLobes(p) = self {
            let _ = writeln!(
                s,
                "  {:>4}  {:<8}  {:>9}  {:>9}  {:>12}",
                "lobe", "kind", "alpha", "weight(D)", "weight(Eq.1)"
            );
            for (j, (l, w)) in p.lobes.iter().zip(p.eq1_weights()).enumerate() {
                let _ = writeln!(
                    s,
                    "  {:>4}  {:<8}  {:>9.5}  {:>9.4}  {:>12.4}",
                    j + 1,
                    match l.distribution.gamma() {
                        Some(g) => format!("t(γ={g:.2})"),
                        None => l.distribution.name().to_owned(),
                    },
                    l.alpha,
                    l.d_weight,
                    w
                );
            }
        } else {
            let _ = writeln!(s, "  lobe  theta(deg)  phi(deg)    weight    exponent");
        }
        for (j, l) in self.lobes().iter().enumerate() {
            let (t, p) = meso_core::frame::spherical_angles(l.axis);
            let (t, p) = (t.to_degrees(), if t < 1e-9 { 0.0 } else { p.to_degrees() });
            let _ = writeln!(
                s,
                "  {:>4}  {:>10.3}  {:>8.2}  {:>8.4}  {:>10.2}",
                j + 1,
                t,
                p,
                l.weight,
                l.exponent
            );
        }
        match self {
            Lobes::Phong(p) => {
                let _ = writeln!(
                    s,
                    "  transfer phong: exponent {:.3}, specular [{:.4}, {:.4}, {:.4}]",
                    p.transfer_exponent, p.specular[0], p.specular[1], p.specular[2]
                );
                let _ = write!(
                    s,
                    "  diffuse albedo [{:.4}, {:.4}, {:.4}]",
                    p.albedo[0], p.albedo[1], p.albedo[2]
                );
            }
            Lobes::Microfacet(LobeMicrofacetParams {
                f0,
                specular,
                albedo,
                ..
            })
            | Lobes::GgxLobes(LobeGgxParams {
                f0,
                specular,
                albedo,
                ..
            }) => {
                let _ = writeln!(
                    s,
                    "  transfer mirror, Schlick f0 [{:.4}, {:.4}, {:.4}], specular [{:.4}, {:.4}, {:.4}], \
                     Smith masking-shadowing",
                    f0[0], f0[1], f0[2], specular[0], specular[1], specular[2]
                );
                let _ = write!(
                    s,
                    "  diffuse albedo [{:.4}, {:.4}, {:.4}]",
                    albedo[0], albedo[1], albedo[2]
                );
            }
        }
        s
    }

    /// Channel `c` of a per-channel fit as a grey material (specular, albedo and `f0` of
    /// channel `c` in all three).
    #[must_use]
    pub fn grey(&self, c: usize) -> Lobes {
        match self {
            Lobes::Phong(p) => Lobes::Phong(LobeParams {
                specular: [p.specular[c]; 3],
                albedo: [p.albedo[c]; 3],
                ..p.clone()
            }),
            Lobes::Microfacet(p) => Lobes::Microfacet(LobeMicrofacetParams {
                f0: [p.f0[c]; 3],
                specular: [p.specular[c]; 3],
                albedo: [p.albedo[c]; 3],
                ..p.clone()
            }),
            Lobes::GgxLobes(p) => Lobes::GgxLobes(LobeGgxParams {
                f0: [p.f0[c]; 3],
                specular: [p.specular[c]; 3],
                albedo: [p.albedo[c]; 3],
                ..p.clone()
            }),
        }
    }
}

/// Fit K = 1..k lobe sums progressively (each size started from the previous one); every size
/// with its result, the last one of `k` lobes (`k` clamped to 1..=6).
///
/// # Errors
/// [`FitError`] from the fitting driver.
pub fn fit_lobes(
    k: usize,
    transfer: Transfer,
    data: &SampleSet,
    opts: &FitOptions,
) -> Result<Vec<(Lobes, FitResult)>, FitError> {
    Ok(match transfer {
        Transfer::Phong => model::fit_lobes_progressive(k, TransferExponent::Free, data, opts)?
            .into_iter()
            .map(|(m, r)| (Lobes::Phong(m.params(&r)), r))
            .collect(),
        Transfer::Microfacet => model::fit_microfacet_lobes_progressive(k, data, opts)?
            .into_iter()
            .map(|(m, r)| (Lobes::Microfacet(m.params(&r)), r))
            .collect(),
        Transfer::GgxLobes | Transfer::StudentTLobes => {
            let candidates: &[meso_core::ndf::Distribution] = if transfer == Transfer::GgxLobes {
                &model::lobes_ggx::GGX_OR_BECKMANN
            } else {
                &model::lobes_ggx::GGX_BECKMANN_OR_STUDENT_T
            };
            model::fit_ggx_lobes_progressive(k, candidates, data, opts)?
                .into_iter()
                .map(|(m, r)| (Lobes::GgxLobes(m.params(&r)), r))
                .collect()
        }
    })
}

/// Three numbers with `prec` decimals, separated by spaces.
#[must_use]
pub fn fmt3(v: [f64; 3], prec: usize) -> String {
    format!("{:.p$} {:.p$} {:.p$}", v[0], v[1], v[2], p = prec)
}

/// How a fit was asked for, as written in the material file's comment.
#[derive(Clone, Copy, Debug)]
pub struct FitSettings<'a> {
    /// The data as named on the command line (a path as displayed).
    pub data: &'a str,
    /// Number of lobes.
    pub k: usize,
    /// The metric minimised.
    pub metric: crate::metric::Metric,
    /// The transfer.
    pub transfer: Transfer,
    /// Where the axes went.
    pub axes: crate::fit::LobeAxes,
    /// `Some(c)`: channel `c` of a per-channel-lobes fit.
    pub channel: Option<usize>,
    /// The MERL cells asked for (`--samples`, [`Data::merl_target`]); `None` for sample CSVs.
    pub samples: Option<usize>,
}

/// The comment at the top of a fitted material file (`meso fit`'s): the command, the model,
/// the data's description, the time and iterations, the errors of the fit `r`.
#[must_use]
pub fn material_comment(s: &FitSettings<'_>, description: &str, r: &FitResult) -> String {
    let mut comment = format!(
        "meso fit {} --lobes {} --metric {} --transfer {} --axes {}{}{}\n{}: fitted {} in {:.2} s, {} LM iterations\n",
        s.data,
        s.k,
        s.metric.cli_name(),
        s.transfer.name(),
        s.axes.name(),
        s.samples.map(|n| format!(" --samples {n}")).unwrap_or_default(),
        if s.channel.is_some() { " --per-channel-lobes" } else { "" },
        r.model,
        description,
        r.seconds,
        r.iterations
    );
    if let Some(c) = s.channel {
        let _ = writeln!(
            comment,
            "per-channel lobes: this file is the {} channel of the fit (grey material)",
            ["red", "green", "blue"][c]
        );
    }
    let _ = writeln!(
        comment,
        "errors of the fitted closed form: ngan-l2 [{}], low-log [{}]",
        fmt3(r.errors.ngan_l2, 5),
        fmt3(r.errors.low_log, 5)
    );
    if let Some(h) = &r.held_out {
        let _ = writeln!(
            comment,
            "errors on {} held-out samples: ngan-l2 [{}], low-log [{}]",
            r.held_out_count,
            fmt3(h.ngan_l2, 5),
            fmt3(h.low_log, 5)
        );
    }
    comment
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_is_named_and_auto_leaves_out_the_student_t_lobes() {
        for t in Transfer::EVERY {
            assert_eq!(Transfer::from_name(t.name()), Some(t));
        }
        assert!(!Transfer::ALL.contains(&Transfer::StudentTLobes));
        assert_eq!(Transfer::from_name("gaussian"), None);
    }

    fn csv_file(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("meso-job-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn csv_hold_out_rule_and_description() {
        let mut text = String::from("theta_i,phi_i,theta_o,phi_o,r,g,b\n");
        for k in 0..250 {
            let t = 5.0 + f64::from(k % 60);
            text.push_str(&format!("{t},0,{t},180,0.3,0.3,0.3\n"));
        }
        // Below the horizon: dropped.
        text.push_str("90,0,30,180,0.3,0.3,0.3\n");
        let p = csv_file("rule.csv", &text);
        let d = load(&p, 0).unwrap();
        assert_eq!(
            d.description,
            "sample CSV, 250 samples above the horizon, 225 fitted, 25 held out"
        );
        assert!(d.merl.is_none());
        let r = fit_lobes(1, Transfer::Phong, &d.samples, &FitOptions::default()).unwrap();
        assert_eq!(r.len(), 1);
        assert!(r[0].0.to_toml("x").starts_with("# x\n"));
    }

    #[test]
    fn errors_name_the_file_and_keep_the_cause() {
        let p = csv_file("bad.csv", "a,b\n1,2\n");
        let e = load(&p, 0).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("{}: not a valid sample CSV", p.display())
        );
        assert!(std::error::Error::source(&e).is_some());
        let missing = p.with_file_name("missing.csv");
        let e = load(&missing, 0).unwrap_err();
        assert!(matches!(e, LoadError::Io { .. }), "{e}");
        let p = csv_file(
            "low.csv",
            "theta_i,phi_i,theta_o,phi_o,r,g,b\n90,0,90,0,1,1,1\n",
        );
        assert!(matches!(
            load(&p, 0).unwrap_err(),
            LoadError::NoneAboveHorizon { .. }
        ));
    }
}
