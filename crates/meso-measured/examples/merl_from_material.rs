//! A MERL binary generated from a meso material: its BRDF (meso-core's compiled plan,
//! `Policy::Accurate`) at every cell of the MERL table (the lower bin edges, as MERL's own
//! reader evaluates them), optionally with multiplicative noise that mimics a measurement. The
//! generated data of issue 13's goals ("measured on the MERL encodings … and on data you
//! generate"): `merl_compare` then scores `meso fit`'s default against a fresh GGX + Lambert on
//! it.
//!
//! ```text
//! cargo run --release -p meso-measured --example merl_from_material -- MATERIAL.toml OUT.binary \
//!     [--noise FRACTION] [--seed N]
//! ```
//!
//! `--noise 0.03` multiplies every cell by `1 + 0.03·u`, `u` uniform in [−1, 1] per cell and
//! channel (deterministic for a seed; default none). The material must be isotropic about the
//! normal (a MERL table is).

use meso_core::material::Material;
use meso_core::shading::{FastBrdf, Policy};
use meso_measured::merl::{CellPosition, MerlTable};
use std::path::PathBuf;

/// A hash of `(seed, bits of wi and wo, channel)` to a uniform number in [−1, 1]: the noise of
/// one cell and channel, the same on every run.
fn noise(seed: u64, wi: glam::DVec3, wo: glam::DVec3, c: u64) -> f64 {
    let mut h = seed ^ 0x9E37_79B9_7F4A_7C15;
    for v in [wi.x, wi.y, wi.z, wo.x, wo.y, wo.z] {
        h ^= v.to_bits();
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 31;
    }
    h ^= c;
    h = h.wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^= h >> 29;
    (h >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut files: Vec<PathBuf> = Vec::new();
    let (mut amount, mut seed) = (0.0f64, 1u64);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--noise" => amount = args.next().ok_or("--noise needs a fraction")?.parse()?,
            "--seed" => seed = args.next().ok_or("--seed needs N")?.parse()?,
            _ => files.push(a.into()),
        }
    }
    let [material, out] = files.as_slice() else {
        return Err(
            "usage: merl_from_material MATERIAL.toml OUT.binary [--noise F] [--seed N]".into(),
        );
    };
    let m = Material::from_file(material, &meso_core::material::NoExternalNdfs)?;
    let plan = FastBrdf::with_policy(&m, Policy::Accurate);
    let table = MerlTable::from_fn(CellPosition::Edge, |wi, wo| {
        let f = plan.eval(wi, wo);
        if amount > 0.0 {
            [0, 1, 2].map(|c| f[c] * (1.0 + amount * noise(seed, wi, wo, c as u64)))
        } else {
            f
        }
    })?;
    table.write(out)?;
    println!("wrote {} from {}", out.display(), material.display());
    Ok(())
}
