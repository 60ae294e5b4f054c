//! # meso-measured
//!
//! Measured BRDFs and their fitting (Fournier 1992, §3.3: "adjust the positions, amplitudes and
//! exponents of the Phong peaks … until the computed reflectance fits").
//!
//! * [`merl`] — the MERL binary format (reader with validation, nearest-cell lookup, cell
//!   iterator, writer from any BRDF closure), on the [`rusinkiewicz`] half/difference angles;
//! * [`csv`] — a plain CSV of samples `theta_i,phi_i,theta_o,phi_o,r,g,b`;
//! * [`samples`] — data to fit (weighted direction pairs), with a stratified MERL subsample;
//! * [`metric`] — the cosine-weighted L2 of Ngan et al. 2005 and the log metric of Löw et al. 2012;
//! * [`job`] — the core of `meso fit`: loading a data file, the lobe fits for either transfer;
//! * [`nonparametric`], [`nonparametric_aniso`] — the NDF itself tabulated (1-D in θm for MERL
//!   tables, 2-D for anisotropic samples) by power iteration, Fresnel and diffuse alongside;
//! * [`engine`] — engine (glTF metallic–roughness) parameters from a GGX + Lambert fit;
//! * the fits solve with meso-core's one Levenberg–Marquardt solver ([`meso_core::lm`]);
//! * [`fit`] — the [`fit::BrdfModel`] trait and the fitting driver (several starts, coarse to fine,
//!   linear per-channel amplitudes);
//! * [`plots`] — the PNG plots of a fit (polar slices, spheres with the exposure from the data);
//! * [`workflow`] — the whole `meso fit` workflow as one call returning a report value;
//! * [`model`] — the lobe-sum model of the paper and the baselines (Blinn-Phong, Cook-Torrance,
//!   GGX, Ashikhmin–Shirley, Lafortune).
//!
//! Conventions are meso-core's ([`meso_core::frame`]): unit directions, normal +z, tangent +x,
//! `i` towards the light and `o` towards the viewer, radians in code, degrees in files; BRDFs in
//! 1/sr without the cosine factor.
//!
//! ```no_run
//! use meso_measured::{fit, merl, model, samples};
//! let table = merl::MerlTable::read("gold-metallic-paint.binary".as_ref())?;
//! let (data, _stats) = samples::SampleSet::from_merl(&table, &samples::MerlSampling::default());
//! let m = model::LobeModel::new(2);
//! let r = fit::fit(&m, &data, &fit::FitOptions::default())?;
//! let toml = m.params(&r).to_material_toml(&format!("errors {:?}", r.errors));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

pub mod csv;
pub mod engine;
pub mod fit;
pub mod job;
pub mod merl;
pub mod metric;
pub mod model;
pub mod nonparametric;
pub mod nonparametric_aniso;
pub mod plots;
pub mod rusinkiewicz;
pub mod samples;
pub mod workflow;
