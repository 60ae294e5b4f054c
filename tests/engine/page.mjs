// Runs in headless Chromium: three.js renders of the exported plane into a float render target.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { KTX2Loader } from 'three/addons/loaders/KTX2Loader.js';

const W = 128, H = 128;
const renderer = new THREE.WebGLRenderer({ antialias: false, alpha: false });
renderer.setPixelRatio(1);
renderer.setSize(W, H);
renderer.toneMapping = THREE.NoToneMapping;
renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
const target = new THREE.WebGLRenderTarget(W, H, { type: THREE.FloatType, format: THREE.RGBAFormat, depthBuffer: true });

async function bitmap(url) {
  const blob = await (await fetch(url)).blob();
  return createImageBitmap(blob, { colorSpaceConversion: 'none', premultiplyAlpha: 'none' });
}
function texture(levels, generate) {
  const t = new THREE.Texture(levels[0]);
  if (!generate) t.mipmaps = levels;
  t.generateMipmaps = generate;
  t.flipY = false;                       // image row 0 at v = 0, as glTF
  t.wrapS = t.wrapT = THREE.RepeatWrapping;
  t.magFilter = THREE.LinearFilter;
  t.minFilter = THREE.LinearMipmapLinearFilter;
  t.anisotropy = 1;
  t.colorSpace = THREE.NoColorSpace;     // data, not colour
  t.needsUpdate = true;
  return t;
}

// The plane z = 0 (normal +z); uv = (x, −y) / uvScale: three.js and glTF put uv (0, 0) at the image's
// top-left with v growing down the image, meso's scene uv grows up it (docs/conventions.md).
// `tangents`: a glTF TANGENT attribute as meso's asset writes it (+u = +x, w = +1, so the bitangent
// n × t = +y points up the image); without it three.js derives the frame from screen-space uv
// derivatives.
function plane(uvScale, half, offset = [0, 0], tangents = false) {
  const g = new THREE.BufferGeometry();
  const p = [-half, -half, 0, half, -half, 0, half, half, 0, -half, half, 0];
  const uv = [];
  for (let i = 0; i < 4; i++) uv.push(p[3 * i] / uvScale + offset[0], -p[3 * i + 1] / uvScale + offset[1]);
  g.setAttribute('position', new THREE.Float32BufferAttribute(p, 3));
  g.setAttribute('normal', new THREE.Float32BufferAttribute([0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1], 3));
  g.setAttribute('uv', new THREE.Float32BufferAttribute(uv, 2));
  if (tangents) g.setAttribute('tangent', new THREE.Float32BufferAttribute([1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1], 4));
  g.setIndex([0, 1, 2, 0, 2, 3]);
  return g;
}

// three.js (r16x+) multiplies direct GGX light by a multiple-scattering energy compensation,
// 1 + F0·(1/E_ss − 1) with E_ss from its DFG table; meso's reference is single-scattering GGX. With
// `singleScatter` that one line is replaced by 1 so both shade the same model; without, three.js as shipped.
const MS_LINE = 'material.multiScatteringCompensation = 1.0 + material.specularColorBlended * ( 1.0 / EssMs - 1.0 );';
const msPatchable = THREE.ShaderChunk.lights_fragment_begin.includes(MS_LINE);
// KHR_materials_anisotropy in three.js takes the anisotropy tangent and bitangent from the geometric
// tangent frame `tbn`, not orthogonal to the normal-mapped `normal`; its anisotropic D then peaks
// about the geometric normal whatever the normal map says (a tilted texel shades like a flat one,
// even at strength 0). With `anisoFrame` the two lines are replaced by the frame meso's fit assumes:
// the direction projected onto the shading normal's tangent plane, the bitangent normal × tangent.
const ANISO_LINES = 'material.anisotropyT = tbn[ 0 ] * anisotropyV.x + tbn[ 1 ] * anisotropyV.y;\n\tmaterial.anisotropyB = tbn[ 1 ] * anisotropyV.x - tbn[ 0 ] * anisotropyV.y;';
const ANISO_FIXED = 'vec3 mesoT = tbn[ 0 ] * anisotropyV.x + tbn[ 1 ] * anisotropyV.y;\n\tmaterial.anisotropyT = normalize( mesoT - dot( mesoT, normal ) * normal );\n\tmaterial.anisotropyB = cross( normal, material.anisotropyT );';
const anisoPatchable = THREE.ShaderChunk.lights_physical_fragment.includes(ANISO_LINES);
function patch(mat, { singleScatter, anisoFrame }) {
  if (!singleScatter && !anisoFrame) return;
  mat.onBeforeCompile = (shader) => {
    if (singleScatter) {
      shader.fragmentShader = shader.fragmentShader.replace('#include <lights_fragment_begin>',
        THREE.ShaderChunk.lights_fragment_begin.replace(MS_LINE, 'material.multiScatteringCompensation = vec3( 1.0 );'));
    }
    if (anisoFrame) {
      shader.fragmentShader = shader.fragmentShader.replace('#include <lights_physical_fragment>',
        THREE.ShaderChunk.lights_physical_fragment.replace(ANISO_LINES, ANISO_FIXED));
    }
  };
  mat.customProgramCacheKey = () => `meso-${singleScatter ? 'ss' : 'ms'}-${anisoFrame ? 'frame' : 'tbn'}`;
}

let maps = null;
window.loadMaps = async (levels) => {
  const nrm = [], mr = [];
  for (let k = 0; k < levels; k++) {
    nrm.push(await bitmap(`http://meso.test/exp/normal_mip${k}.png`));
    mr.push(await bitmap(`http://meso.test/exp/metallic_roughness_mip${k}.png`));
  }
  maps = {
    exportedNormal: texture(nrm, false),
    exportedMR: texture(mr, false),
    originalNormal: texture([await bitmap('http://meso.test/exp/normal_mip0.png')], true),
  };
  const gl = renderer.getContext();
  return { webgl2: renderer.capabilities.isWebGL2 !== false, renderer: gl.getParameter(gl.RENDERER), revision: THREE.REVISION, msPatchable, anisoPatchable };
};

// The exported asset as an engine reads it: `scene.gltf` through three.js's GLTFLoader (its material,
// its plane's tangent frame), then the fitted chains from `normal.ktx2` and `metallic_roughness.ktx2`
// (and `anisotropy.ktx2` when the material has KHR_materials_anisotropy) through KTX2Loader (core glTF
// images are PNG or JPEG, one level: the chains ship as KTX2 beside the asset), with the glTF
// sampler's wrap and filters. `dir`: the export's folder under http://meso.test/; `key`: the name
// renderView's `asset` option picks it by. Returns what the tests check.
const assets = {};
window.loadAsset = async (dir = 'exp', key = 'main') => {
  const gltf = await new GLTFLoader().loadAsync(`http://meso.test/${dir}/scene.gltf`);
  let mesh = null;
  gltf.scene.traverse((o) => { if (o.isMesh && o.name === 'plane') mesh = o; });
  if (!mesh) throw new Error('scene.gltf: no mesh named "plane"');
  const g = mesh.geometry, mat = mesh.material;
  // The plane's tangent frame against its uv: the tangent along +u, the bitangent w·(n × t) along −v
  // (up the image), from each triangle's edges.
  const P = g.attributes.position, U = g.attributes.uv, T = g.attributes.tangent, N = g.attributes.normal;
  const idx = g.index.array;
  let tangentAlongU = 1, bitangentUp = 1;
  for (let f = 0; f < idx.length; f += 3) {
    const [a, b, c] = [idx[f], idx[f + 1], idx[f + 2]];
    const e1 = new THREE.Vector3().fromBufferAttribute(P, b).sub(new THREE.Vector3().fromBufferAttribute(P, a));
    const e2 = new THREE.Vector3().fromBufferAttribute(P, c).sub(new THREE.Vector3().fromBufferAttribute(P, a));
    const [du1, dv1] = [U.getX(b) - U.getX(a), U.getY(b) - U.getY(a)];
    const [du2, dv2] = [U.getX(c) - U.getX(a), U.getY(c) - U.getY(a)];
    const r = 1 / (du1 * dv2 - du2 * dv1);
    const dpdu = e1.clone().multiplyScalar(dv2).addScaledVector(e2, -dv1).multiplyScalar(r).normalize();
    const dpdv = e2.clone().multiplyScalar(du1).addScaledVector(e1, -du2).multiplyScalar(r).normalize();
    const t = new THREE.Vector3().fromBufferAttribute(T, a);
    const n = new THREE.Vector3().fromBufferAttribute(N, a);
    const bt = n.clone().cross(t).multiplyScalar(T.getW(a));
    tangentAlongU = Math.min(tangentAlongU, t.dot(dpdu));
    bitangentUp = Math.min(bitangentUp, -bt.dot(dpdv));
  }
  const ktx2 = new KTX2Loader().setTranscoderPath('/no-transcoder/').detectSupport(renderer);
  const chain = async (file, like) => {
    const t = await ktx2.loadAsync(`http://meso.test/${dir}/${file}`);
    t.wrapS = like.wrapS; t.wrapT = like.wrapT;
    t.magFilter = like.magFilter; t.minFilter = like.minFilter;
    t.flipY = like.flipY; t.anisotropy = 1;
    t.needsUpdate = true;
    return t;
  };
  const normal = await chain('normal.ktx2', mat.normalMap);
  const mr = await chain('metallic_roughness.ktx2', mat.roughnessMap);
  const asset = mat.clone();
  asset.normalMap = normal;
  asset.roughnessMap = mr;
  asset.metalnessMap = mr;
  const levels = [normal.mipmaps.length, mr.mipmaps.length];
  const anisotropic = mat.anisotropyMap != null;
  if (anisotropic) {
    asset.anisotropyMap = await chain('anisotropy.ktx2', mat.anisotropyMap);
    levels.push(asset.anisotropyMap.mipmaps.length);
  }
  assets[key] = asset;
  ktx2.dispose();
  return {
    tangentAlongU, bitangentUp, hasTangents: T !== undefined,
    metalness: mat.metalness, roughness: mat.roughness, color: mat.color.toArray(),
    normalScale: mat.normalScale.toArray(), levels,
    pngLevels: [mat.normalMap.mipmaps.length, mat.roughnessMap.mipmaps.length],
    physical: mat.isMeshPhysicalMaterial === true, anisotropic,
    anisotropy: mat.anisotropy ?? 0, anisotropyRotation: mat.anisotropyRotation ?? 0,
  };
};

// mode: 'flat' (no maps, constant roughness), 'exported' (meso's normal + roughness chains),
// 'standard' (level-0 normal map with three.js' generated mips, constant roughness), 'gltf' (the asset's
// own material with the KTX2 chains, on a plane with the asset's tangent convention; `o.asset` names
// which loaded asset, default 'main').
window.renderView = (o) => {
  const scene = new THREE.Scene();
  const gltf = o.mode === 'gltf';
  const mat = gltf ? assets[o.asset || 'main'].clone() : new THREE.MeshStandardMaterial({ metalness: 1, roughness: Math.sqrt(o.alpha) });
  if (!gltf) mat.color.setRGB(o.baseColor, o.baseColor, o.baseColor, THREE.LinearSRGBColorSpace);
  if (o.mode === 'exported') {
    mat.normalMap = maps.exportedNormal;
    mat.roughnessMap = maps.exportedMR;     // G = √α; metalness stays the constant 1
    mat.roughness = 1;
  } else if (o.mode === 'standard') {
    mat.normalMap = maps.originalNormal;
  }
  patch(mat, { singleScatter: o.singleScatter, anisoFrame: o.anisoFrame });
  // Without tangents, v grows down the image: green = −∂p/∂v (GLTFLoader does the same for meshes without
  // TANGENT); the glTF mode keeps the loader's normalScale and uses the vertex tangents.
  if (mat.normalMap && !gltf) mat.normalScale.set(1, -1);
  scene.add(new THREE.Mesh(plane(o.uvScale, 40, o.uvOffset, gltf), mat));
  const light = new THREE.DirectionalLight(0xffffff, o.irradiance);
  light.position.set(...o.lightDir);
  light.target.position.set(0, 0, 0);
  scene.add(light, light.target);
  const w = o.width, h = o.width * H / W;
  const cam = new THREE.OrthographicCamera(-w / 2, w / 2, h / 2, -h / 2, 0.01, 100);
  cam.position.set(...o.eye);
  cam.up.set(...o.up);
  cam.lookAt(0, 0, 0);
  cam.updateProjectionMatrix();
  renderer.setRenderTarget(target);
  renderer.render(scene, cam);
  const buf = new Float32Array(W * H * 4);
  renderer.readRenderTargetPixels(target, 0, 0, W, H, buf);
  renderer.setRenderTarget(null);
  mat.dispose();
  // luminance, rows top-down (readPixels gives the bottom row first)
  const y = new Array(W * H);
  for (let r = 0; r < H; r++) for (let c = 0; c < W; c++) {
    const i = ((H - 1 - r) * W + c) * 4;
    y[r * W + c] = 0.2126 * buf[i] + 0.7152 * buf[i + 1] + 0.0722 * buf[i + 2];
  }
  return y;
};
window.ready = true;
