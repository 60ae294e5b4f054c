//! A glTF 2.0 preview asset: a UV sphere and a plane with `POSITION`, `NORMAL`, `TANGENT` and
//! `TEXCOORD_0`, sharing one material that uses the exported textures.
//!
//! # Conventions
//! * glTF: +Y up, metres, right-handed; uv (0, 0) is the image's top-left, `v` grows down.
//! * Tangents point along increasing `u`, `w = +1`: the bitangent `normal × tangent` points up
//!   the image (decreasing `v`), which is the normal map's green (+y).
//! * The core textures reference PNG mip 0 (a core glTF 2.0 image is PNG or JPEG; plain RGBA8
//!   KTX2 is not Basis Universal, so `KHR_texture_basisu` does not apply). The KTX2 files with
//!   the fitted mip chains ship next to the asset for engines that load them directly.
//! * With an anisotropy texture the material carries `KHR_materials_anisotropy`
//!   (`anisotropyStrength = 1`, `anisotropyRotation = 0`, the texture's direction taken as it
//!   is in the mesh's tangent frame), listed in `extensionsUsed` (not required: a viewer without
//!   it shows the isotropic α_b).

use serde_json::{json, Value};

/// Paths (relative to the `.gltf` file) of the textures the material uses.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialTextures {
    /// The tangent-space normal map (PNG, RGB, OpenGL convention).
    pub normal: String,
    /// The metallicRoughness map (PNG, G = roughness, B = metallic).
    pub metallic_roughness: String,
    /// The base colour map (sRGB PNG), or `None` for a constant base colour.
    pub base_color: Option<String>,
    /// The KHR_materials_anisotropy texture (PNG, RG = direction, B = strength), or `None`
    /// for an isotropic material (no extension used).
    pub anisotropy: Option<String>,
}

/// Triangle mesh data for one primitive.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Mesh {
    /// Vertex positions (m).
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// Unit tangents along +u with handedness `w = ±1`.
    pub tangents: Vec<[f32; 4]>,
    /// Texture coordinates (glTF: v down).
    pub uvs: Vec<[f32; 2]>,
    /// Triangle indices, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

/// A UV sphere of radius `radius` (m) with `segments` columns and `rings` rows of quads; each
/// pole row is a fan of triangles (no degenerate triangle). The texture repeats `tiles` times
/// around and `tiles / 2` times from pole to pole (`u = tiles·φ/2π`, `v = tiles/2 · θ/π`).
#[must_use]
pub fn uv_sphere(radius: f32, segments: usize, rings: usize, tiles: f32) -> Mesh {
    let mut m = Mesh::default();
    let tau = std::f32::consts::TAU;
    let pi = std::f32::consts::PI;
    for i in 0..=rings {
        let th = pi * i as f32 / rings as f32;
        for j in 0..=segments {
            let ph = tau * j as f32 / segments as f32;
            let n = [th.sin() * ph.sin(), th.cos(), th.sin() * ph.cos()];
            m.positions.push(n.map(|c| c * radius));
            m.normals.push(n);
            // dP/dφ direction, defined at the poles too.
            m.tangents.push([ph.cos(), 0.0, -ph.sin(), 1.0]);
            m.uvs.push([
                tiles * j as f32 / segments as f32,
                tiles * 0.5 * i as f32 / rings as f32,
            ]);
        }
    }
    let row = segments as u32 + 1;
    for i in 0..rings as u32 {
        for j in 0..segments as u32 {
            let (a, b) = (i * row + j, i * row + j + 1);
            let (c, d) = ((i + 1) * row + j, (i + 1) * row + j + 1);
            // Seen from outside: a (top-left), c (bottom-left), d, b.
            if i != 0 {
                m.indices.extend_from_slice(&[a, c, b]);
            }
            if i + 1 != rings as u32 {
                m.indices.extend_from_slice(&[b, c, d]);
            }
        }
    }
    m
}

/// A square plane of side `size` (m) in the XY plane facing +Z, centred at the origin, with the
/// texture repeated `tiles` times across (image top at +Y).
#[must_use]
pub fn plane(size: f32, tiles: f32) -> Mesh {
    let h = size / 2.0;
    let mut m = Mesh::default();
    for (x, y) in [(-h, h), (h, h), (-h, -h), (h, -h)] {
        m.positions.push([x, y, 0.0]);
        m.normals.push([0.0, 0.0, 1.0]);
        m.tangents.push([1.0, 0.0, 0.0, 1.0]);
        m.uvs.push([tiles * (x + h) / size, tiles * (h - y) / size]);
    }
    m.indices = vec![0, 2, 1, 1, 2, 3];
    m
}

/// The binary buffer and the glTF JSON of the sphere (at x = −1.25 m) and the plane (at
/// x = +1.25 m) sharing one material. `bin_uri` is the buffer's file name.
#[must_use]
pub fn asset(
    meshes: &[(&str, Mesh)],
    tex: &MaterialTextures,
    bin_uri: &str,
    base_color: [f64; 4],
) -> (Vec<u8>, Value) {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut gl_meshes = Vec::new();
    let mut nodes = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, bytes: &[u8], target: u32| -> usize {
        bin.resize(bin.len().div_ceil(4) * 4, 0);
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len(), "target": target}));
        bin.extend_from_slice(bytes);
        views.len() - 1
    };
    let f32s =
        |v: &mut dyn Iterator<Item = f32>| -> Vec<u8> { v.flat_map(f32::to_le_bytes).collect() };
    for (k, (name, m)) in meshes.iter().enumerate() {
        let count = m.positions.len();
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in &m.positions {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        let base = accessors.len();
        let pv = push_view(
            &mut bin,
            &f32s(&mut m.positions.iter().flatten().copied()),
            34962,
        );
        accessors.push(json!({"bufferView": pv, "componentType": 5126, "count": count, "type": "VEC3", "min": lo, "max": hi}));
        let nv = push_view(
            &mut bin,
            &f32s(&mut m.normals.iter().flatten().copied()),
            34962,
        );
        accessors
            .push(json!({"bufferView": nv, "componentType": 5126, "count": count, "type": "VEC3"}));
        let tv = push_view(
            &mut bin,
            &f32s(&mut m.tangents.iter().flatten().copied()),
            34962,
        );
        accessors
            .push(json!({"bufferView": tv, "componentType": 5126, "count": count, "type": "VEC4"}));
        let uv = push_view(&mut bin, &f32s(&mut m.uvs.iter().flatten().copied()), 34962);
        accessors
            .push(json!({"bufferView": uv, "componentType": 5126, "count": count, "type": "VEC2"}));
        let idx: Vec<u8> = m.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let iv = push_view(&mut bin, &idx, 34963);
        accessors.push(json!({"bufferView": iv, "componentType": 5125, "count": m.indices.len(), "type": "SCALAR"}));
        gl_meshes.push(json!({
            "name": name,
            "primitives": [{
                "attributes": {"POSITION": base, "NORMAL": base + 1, "TANGENT": base + 2, "TEXCOORD_0": base + 3},
                "indices": base + 4,
                "material": 0,
                "mode": 4
            }]
        }));
        let x = if k == 0 { -1.25 } else { 1.25 };
        nodes.push(json!({"name": name, "mesh": k, "translation": [x, 0.0, 0.0]}));
    }
    bin.resize(bin.len().div_ceil(4) * 4, 0);
    let mut images = vec![
        json!({"uri": tex.normal, "mimeType": "image/png"}),
        json!({"uri": tex.metallic_roughness, "mimeType": "image/png"}),
    ];
    let mut pbr = json!({
        "baseColorFactor": base_color,
        "metallicFactor": 1.0,
        "roughnessFactor": 1.0,
        "metallicRoughnessTexture": {"index": 1}
    });
    if let Some(bc) = &tex.base_color {
        images.push(json!({"uri": bc, "mimeType": "image/png"}));
        pbr["baseColorTexture"] = json!({"index": images.len() - 1});
    }
    let mut material = json!({
        "name": "meso",
        "pbrMetallicRoughness": pbr,
        "normalTexture": {"index": 0, "scale": 1.0}
    });
    if let Some(an) = &tex.anisotropy {
        images.push(json!({"uri": an, "mimeType": "image/png"}));
        material["extensions"] = json!({
            "KHR_materials_anisotropy": {
                "anisotropyStrength": 1.0,
                "anisotropyRotation": 0.0,
                "anisotropyTexture": {"index": images.len() - 1}
            }
        });
    }
    let textures: Vec<Value> = (0..images.len())
        .map(|i| json!({"sampler": 0, "source": i}))
        .collect();
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("meso export ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": gl_meshes,
        "materials": [material],
        "textures": textures,
        "images": images,
        // LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT.
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
        "buffers": [{"uri": bin_uri, "byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors
    });
    if tex.anisotropy.is_some() {
        doc["extensionsUsed"] = json!(["KHR_materials_anisotropy"]);
    }
    (bin, doc)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }
    fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    /// Frames are orthonormal, triangles face outwards, and the bitangent `n × t` points towards
    /// decreasing v (up the image).
    #[test]
    fn sphere_frames_and_winding() {
        let m = uv_sphere(1.0, 16, 8, 2.0);
        for k in 0..m.positions.len() {
            let (n, t) = (m.normals[k], m.tangents[k]);
            let t3 = [t[0], t[1], t[2]];
            assert!((dot(n, n) - 1.0).abs() < 1e-5 && (dot(t3, t3) - 1.0).abs() < 1e-5);
            assert!(dot(n, t3).abs() < 1e-5);
        }
        for tri in m.indices.chunks(3) {
            let p = [0, 1, 2].map(|k| m.positions[tri[k] as usize]);
            let e1 = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
            let e2 = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
            let c = cross(e1, e2);
            assert!(dot(c, c) > 0.0, "degenerate triangle");
            assert!(dot(c, p[0]) > 0.0, "triangle facing inwards");
            // Bitangent vs the uv gradient: along the triangle, v decreases towards +b.
            let k = tri[0] as usize;
            let b = cross(
                m.normals[k],
                [m.tangents[k][0], m.tangents[k][1], m.tangents[k][2]],
            );
            assert!(b[1] >= -1e-5, "bitangent points south");
        }
        let p = plane(2.0, 1.0);
        assert_eq!(p.uvs[0], [0.0, 0.0]); // top-left corner (−1, +1)
    }
}
