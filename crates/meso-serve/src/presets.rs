//! The editor's preset materials, in the JSON form of [`crate::material_json`].
//!
//! The paper's materials (Fournier 1992, §4: Figure 2's multiple surfaces of two, three and seven
//! normals, Figure 3's velvet and Figure 4's silk) are those of [`meso_core::catalogue`], the
//! same values the figures render: each preset is its material file
//! ([`meso_core::material::MaterialSpec::to_toml`]) read as the editor's Open… reads a file
//! ([`crate::material_json::parse_toml`]). The others are the editor's own:
//!
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

/// A material of [`meso_core::catalogue`] in the JSON form: its file read back as Open… reads it.
fn paper(m: &meso_core::catalogue::MultipleSurface) -> Value {
    crate::material_json::parse_toml(&m.spec().to_toml())
        .unwrap_or_else(|e| panic!("catalogue material {:?}: {}", m.name, e.message))
}

/// All presets, in display order.
#[must_use]
pub fn presets() -> Vec<Preset> {
    use meso_core::catalogue;
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
    let from_paper = |id, label, m: catalogue::MultipleSurface| Preset {
        id,
        label,
        description: m.description,
        material: paper(&m),
    };
    vec![
        from_paper("paper-2", "2 normals (paper)", catalogue::two_normals()),
        from_paper("paper-3", "3 normals (paper)", catalogue::three_normals()),
        from_paper("paper-7", "7 normals (paper)", catalogue::seven_normals()),
        from_paper("velvet", "Velvet (paper)", catalogue::velvet()),
        from_paper("silk", "Silk (paper)", catalogue::silk()),
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

    /// The paper's presets are the catalogue's materials: the preset's JSON, validated, is
    /// the catalogue's spec (the figures' material files), lobe for lobe.
    #[test]
    fn paper_presets_are_the_catalogue() {
        use meso_core::catalogue;
        use meso_core::material::MaterialSpec;
        let all = presets();
        for (id, m) in [
            ("paper-2", catalogue::two_normals()),
            ("paper-3", catalogue::three_normals()),
            ("paper-7", catalogue::seven_normals()),
            ("velvet", catalogue::velvet()),
            ("silk", catalogue::silk()),
        ] {
            let p = all.iter().find(|p| p.id == id).unwrap();
            assert_eq!(p.material["ndf"]["kind"], "deltas", "{id}");
            assert_eq!(
                p.material["ndf"]["lobes"].as_array().unwrap().len(),
                m.normals.len(),
                "{id}"
            );
            let v = crate::material_json::validate(&p.material).unwrap();
            let back = MaterialSpec::parse(&v.toml, std::path::Path::new("")).unwrap();
            assert_eq!(back, m.spec(), "{id}");
        }
    }
}
