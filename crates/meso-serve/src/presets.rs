//! The editor's preset materials, in the JSON form of [`crate::material_json`].
//!
//! The paper (Fournier 1992, §4, Figures 2–4) shows spheres with multiple surfaces of two, three
//! and seven normals, and two made-up cloths, velvet and silk; it gives no numbers, so the
//! lobes here are designed from the descriptions:
//!
//! * **2 normals** — a V-groove across the tangent: normals tilted ±25° in the tangent plane
//!   (φ = 0° and 180°), so every highlight splits in two along the tangent.
//! * **3 normals** — the unit normal and two tilted 30° along the tangent (the example of
//!   `docs/material-format.md`).
//! * **7 normals** — the filtered bump map of a cylinder along the tangent: normals on the
//!   great circle across the tangent (φ = 90°/270°) at θ = 0, ±22.5°, ±45°, ±67.5°, weighted
//!   by the area of the cylinder facets seen from above (∝ cos θ).
//! * **velvet** — fibres standing up scatter at grazing angles: a ring of eight broad peaks at
//!   θ = 80° (near the horizon) and a broad peak at the normal, with a dim coloured base, so the
//!   silhouette and a grazing light make the sheen.
//! * **silk** — threads along the tangent: the normals of a round thread lie on the great circle
//!   across it, so sharp peaks spread along φ = 90°/270° from −60° to 60°, with a weaker
//!   weft circle along φ = 0°/180°; anisotropic highlights stretched across the threads.
//! * **satin** — long warp floats: tight peaks along the circle across the warp (to ±45°), a
//!   broad peak at the normal for the soft sheen, a dark saturated base.
//! * **brushed metal** — grooves along the tangent: fifteen normals across the brushing
//!   direction (every 4° to ±28°, Gaussian weights, σ ≈ 11°), each a rough GGX conductor facet
//!   (aluminium, α = 0.1, enough to blend neighbouring normals).

use serde_json::{json, Value};

/// One preset: an id for URLs, a label, a description and the material.
#[derive(Debug, Clone)]
pub struct Preset {
    /// Short identifier (`paper-2`, `velvet`, …).
    pub id: &'static str,
    /// Label shown in the editor.
    pub label: &'static str,
    /// One sentence on what it models.
    pub description: &'static str,
    /// The material (JSON form).
    pub material: Value,
}

fn lobe(theta: f64, phi: f64, weight: f64, exponent: f64) -> Value {
    json!({ "axis": [theta, phi], "weight": round4(weight), "exponent": exponent })
}

fn normal(theta: f64, phi: f64, weight: f64) -> Value {
    json!({ "axis": [theta, phi], "weight": round4(weight) })
}

fn round4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

/// A signed angle on the great circle through the normal at azimuth `phi`: negative angles go
/// to `phi + 180°`.
fn on_circle(signed_theta: f64, phi: f64) -> (f64, f64) {
    if signed_theta >= 0.0 {
        (signed_theta, phi)
    } else {
        (-signed_theta, (phi + 180.0) % 360.0)
    }
}

/// All presets, in display order.
#[must_use]
pub fn presets() -> Vec<Preset> {
    let paper_transfer = json!({ "kind": "phong", "exponent": 60.0, "specular": [0.9, 0.9, 0.9] });
    let seven: Vec<Value> = [0.0f64, 22.5, -22.5, 45.0, -45.0, 67.5, -67.5]
        .iter()
        .map(|&t| {
            let (th, ph) = on_circle(t, 90.0);
            normal(th, ph, t.to_radians().cos())
        })
        .collect();
    let mut velvet: Vec<Value> = (0..8)
        .map(|k| lobe(80.0, f64::from(k) * 45.0, 0.1, 30.0))
        .collect();
    velvet.push(lobe(0.0, 0.0, 0.2, 6.0));
    let mut silk: Vec<Value> = [0.0f64, 20.0, -20.0, 40.0, -40.0, 60.0, -60.0]
        .iter()
        .map(|&t| {
            let (th, ph) = on_circle(t, 90.0);
            lobe(th, ph, (-(t / 45.0).powi(2)).exp(), 400.0)
        })
        .collect();
    for t in [20.0f64, -20.0] {
        let (th, ph) = on_circle(t, 0.0);
        silk.push(lobe(th, ph, 0.25, 400.0));
    }
    let mut satin: Vec<Value> = [0.0f64, 15.0, -15.0, 30.0, -30.0, 45.0, -45.0]
        .iter()
        .map(|&t| {
            let (th, ph) = on_circle(t, 90.0);
            lobe(th, ph, (-(t / 35.0).powi(2)).exp(), 900.0)
        })
        .collect();
    satin.push(lobe(0.0, 0.0, 0.8, 12.0));
    let brushed: Vec<Value> = (-7..=7)
        .map(|k| {
            let t = f64::from(k) * 4.0;
            let (th, ph) = on_circle(t, 90.0);
            normal(th, ph, (-0.5 * (t / 11.0).powi(2)).exp())
        })
        .collect();
    vec![
        Preset {
            id: "paper-2",
            label: "2 normals (paper)",
            description: "Multiple surface of two normals tilted ±25° along the tangent: \
                          highlights split in two.",
            material: json!({
                "name": "2 normals",
                "ndf": { "kind": "deltas", "lobes": [normal(25.0, 0.0, 0.5), normal(25.0, 180.0, 0.5)] },
                "transfer": paper_transfer,
                "diffuse": { "albedo": [0.18, 0.06, 0.04] }
            }),
        },
        Preset {
            id: "paper-3",
            label: "3 normals (paper)",
            description: "The normal and two normals tilted 30° along the tangent.",
            material: json!({
                "name": "3 normals",
                "ndf": { "kind": "deltas", "lobes": [
                    normal(0.0, 0.0, 1.0), normal(30.0, 0.0, 1.0), normal(30.0, 180.0, 1.0)] },
                "transfer": paper_transfer,
                "diffuse": { "albedo": [0.05, 0.12, 0.2] }
            }),
        },
        Preset {
            id: "paper-7",
            label: "7 normals (paper)",
            description: "Filtered bump map of a cylinder along the tangent: seven normals \
                          across it, weighted by facet area.",
            material: json!({
                "name": "7 normals",
                "ndf": { "kind": "deltas", "lobes": seven },
                "transfer": paper_transfer,
                "diffuse": { "albedo": [0.08, 0.16, 0.06] }
            }),
        },
        Preset {
            id: "velvet",
            label: "Velvet",
            description: "Grazing sheen: a ring of broad peaks near the horizon over a dark \
                          coloured base.",
            material: json!({
                "name": "velvet",
                "ndf": { "kind": "phong-peaks", "lobes": velvet },
                "transfer": { "kind": "phong", "exponent": 8.0, "specular": [0.55, 0.18, 0.3] },
                "diffuse": { "albedo": [0.16, 0.01, 0.04] }
            }),
        },
        Preset {
            id: "silk",
            label: "Silk",
            description: "Threads along the tangent: sharp peaks spread along the great circle \
                          across them, a weaker weft.",
            material: json!({
                "name": "silk",
                "ndf": { "kind": "phong-peaks", "lobes": silk },
                "transfer": { "kind": "phong", "exponent": 80.0, "specular": [0.95, 0.88, 0.75] },
                "diffuse": { "albedo": [0.3, 0.24, 0.16] }
            }),
        },
        Preset {
            id: "satin",
            label: "Satin",
            description: "Long warp floats: tight peaks across the warp and a broad sheen at \
                          the normal.",
            material: json!({
                "name": "satin",
                "ndf": { "kind": "phong-peaks", "lobes": satin },
                "transfer": { "kind": "phong", "exponent": 150.0, "specular": [0.8, 0.82, 0.9] },
                "diffuse": { "albedo": [0.03, 0.05, 0.16] }
            }),
        },
        Preset {
            id: "brushed-metal",
            label: "Brushed metal",
            description: "Grooves along the tangent: normals across the brushing direction, \
                          rough GGX aluminium facets.",
            material: json!({
                "name": "brushed aluminium",
                "ndf": { "kind": "deltas", "lobes": brushed },
                "transfer": { "kind": "microfacet", "distribution": "ggx", "alpha": 0.1,
                              "fresnel": "conductor",
                              "eta": [1.657, 0.88, 0.521], "k": [9.224, 6.27, 4.837] }
            }),
        },
    ]
}

/// The presets as the JSON answered by `GET /api/presets`.
#[must_use]
pub fn presets_json() -> Value {
    Value::Array(
        presets()
            .into_iter()
            .map(|p| {
                json!({ "id": p.id, "label": p.label, "description": p.description,
                        "material": p.material })
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_is_a_valid_material() {
        let all = presets();
        assert_eq!(all.len(), 7);
        for p in all {
            crate::material_json::validate(&p.material)
                .unwrap_or_else(|e| panic!("{}: {}", p.id, e.message));
        }
    }

    #[test]
    fn seven_normals_lie_across_the_tangent() {
        let p = presets().into_iter().find(|p| p.id == "paper-7").unwrap();
        let lobes = p.material["ndf"]["lobes"].as_array().unwrap().clone();
        assert_eq!(lobes.len(), 7);
        for l in lobes {
            let phi = l["axis"][1].as_f64().unwrap();
            let theta = l["axis"][0].as_f64().unwrap();
            assert!(theta == 0.0 || phi == 90.0 || phi == 270.0, "{l}");
        }
    }
}
