//! The facet material of the far-field examples (`bench_facade`, `facade_sweep`): one place
//! that writes it, so that their timings and their images are of the same material.

use meso_core::material::Material;

/// GGX facets of roughness `alpha` (Fresnel 1) when `alpha > 0`, with a Lambert diffuse term
/// of albedo `diffuse` (grey) when `diffuse > 0` (the glossy facets of `tests/steep.rs` have
/// 0.1); otherwise Lambert facets of the default albedo.
///
/// # Panics
/// When the material does not parse (an `alpha` or `diffuse` that is not a finite number).
pub fn facet_material(alpha: f64, diffuse: f64) -> Material {
    let text = if alpha > 0.0 {
        let mut t =
            format!("[transfer]\nkind = \"microfacet\"\ndistribution = \"ggx\"\nalpha = {alpha}\n");
        if diffuse > 0.0 {
            t += &format!("[diffuse]\nalbedo = [{diffuse}, {diffuse}, {diffuse}]\n");
        }
        t
    } else {
        "[transfer]\nkind = \"lambert\"\n".to_string()
    };
    Material::from_toml_str(&text).expect("the facet material")
}
