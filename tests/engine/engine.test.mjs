// meso export checked in a real engine (issue #15 item 5): three.js in headless Chromium renders a
// glossy plane with (a) the exported normal + fitted-roughness mip chains and (b) the original normal
// map with three.js' own generated mips and constant roughness, at several distances; both are
// compared with meso's supersampled bump-mapped render of the same normal map. See docs/engine.md.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { grey16, srgb8 } from './png.mjs';
import { meso, mean, mae, openPage, mesoRender as render } from './harness.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const art = path.join(here, 'artifacts');
const expDir = path.join(art, 'export');
const N = 256;                      // height map size
const TEXEL = 1 / N;                // one map copy per world unit (uv_scale 1)
const HEIGHT = 0.0125;              // full code range: RMS slope ≈ 0.15 per axis
const ALPHA = 0.08;                 // base GGX width (glossy)
const BASE = 0.8;                   // the exported glTF material's base colour (metallic 1): F0 = 0.8
const SPP = Number(process.env.ENGINE_SPP || 1024);
// Distances: an orthographic camera whose width grows with the distance, 128 px across; at d = 1 a
// pixel spans one texel across (1.15 along the tilted axis), at d = 32 it spans 32 × 37 texels.
const DISTANCES = [1, 2, 4, 8, 16, 32];
const view = {
  eye: [0, -2.5, 4.330127], up: [0, 1, 0],            // 30° from the normal
  lightDir: [0, 0.5, 0.8660254], irradiance: 1,        // the mirror direction: the specular peak
};

// Height map: a sum of cosines with random integer frequencies 8..55 cycles per map (fine detail,
// periodic), even in x and y about the texel centres.
function heightMap() {
  let s = 15;
  const rnd = () => { s = (s + 0x6d2b79f5) | 0; let t = Math.imul(s ^ (s >>> 15), 1 | s); t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t; return ((t ^ (t >>> 14)) >>> 0) / 4294967296; };
  const terms = [];
  for (let k = 0; k < 24; k++) terms.push([8 + Math.floor(rnd() * 48), 8 + Math.floor(rnd() * 48), 0.5 + rnd()]);
  const h = new Float64Array(N * N);
  for (let y = 0; y < N; y++) for (let x = 0; x < N; x++) {
    let v = 0;
    for (const [fx, fy, a] of terms) v += a / Math.hypot(fx, fy) * Math.cos(2 * Math.PI * fx * (x + 0.5) / N) * Math.cos(2 * Math.PI * fy * (y + 0.5) / N);
    h[y * N + x] = v;
  }
  let lo = Infinity, hi = -Infinity;
  for (const v of h) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  return Uint16Array.from(h, (v) => Math.round(65535 * (v - lo) / (hi - lo)));
}

const transfer = `[transfer]
kind = "microfacet"
distribution = "ggx"
alpha = ${ALPHA}
fresnel = "schlick"
f0 = [${BASE}, ${BASE}, ${BASE}]
`;

const mesoRender = (name, width, material) => render(art, name, view, width, material, SPP);

let browser, page, info, asset;
let levels = 0;
const results = [];
let calib = 1;

before(async () => {
  fs.mkdirSync(art, { recursive: true });
  fs.writeFileSync(path.join(art, 'height.png'), grey16(N, N, heightMap()));
  fs.rmSync(expDir, { recursive: true, force: true });
  execFileSync(meso, ['export', path.join(art, 'height.png'), '--texel-size', String(TEXEL), '--height-scale', String(HEIGHT),
    '--alpha', String(ALPHA), '--metallic', '1', '--out', expDir], { stdio: ['ignore', 'inherit', 'inherit'] });
  while (fs.existsSync(path.join(expDir, `normal_mip${levels}.png`))) levels++;
  fs.writeFileSync(path.join(art, 'reference.toml'),
    `[texture]\nkind = "bump-mapped"\nnormal_map = "export/normal_mip0.png"\nconvention = "gl"\n${transfer}`);

  ({ browser, page } = await openPage({ exp: expDir }));
  info = await page.evaluate((n) => window.loadMaps(n), levels);
  asset = await page.evaluate(() => window.loadAsset());
});

after(async () => { if (browser) await browser.close(); });

const three = (mode, width, extra = {}) => page.evaluate((o) => window.renderView(o),
  { ...view, mode, width, alpha: ALPHA, baseColor: BASE, uvScale: 1, singleScatter: true, ...extra });

test('three.js has WebGL2 in headless Chromium and the export has a full mip chain', () => {
  console.log(`# three.js r${info.revision}, ${info.renderer}; ${levels} levels`);
  assert.ok(info.webgl2);
  assert.ok(info.msPatchable, 'three.js multiple-scattering line found (the single-scattering patch applies)');
  assert.equal(levels, Math.log2(N) + 1);
});

test('the exported glTF as three.js loads it: material, tangent frame, full KTX2 chains', () => {
  // GLTFLoader's reading of scene.gltf and KTX2Loader's of the two chains (independent readers).
  console.log(`# glTF plane: min tangent·∂p/∂u ${asset.tangentAlongU.toFixed(6)}, min bitangent·(−∂p/∂v) ${asset.bitangentUp.toFixed(6)}; ` +
    `metalness ${asset.metalness}, roughness ${asset.roughness}, colour ${asset.color.map((c) => c.toFixed(4)).join(' ')}, ` +
    `normalScale ${asset.normalScale.join(' ')}; KTX2 levels ${asset.levels.join(', ')}`);
  assert.ok(asset.hasTangents, 'the plane carries TANGENT');
  assert.ok(asset.tangentAlongU > 0.9999, 'tangent along +u');
  assert.ok(asset.bitangentUp > 0.9999, 'bitangent w·(n × t) up the image (−v): green = +Y, the glTF convention');
  assert.equal(asset.metalness, 1);
  assert.equal(asset.roughness, 1);
  for (const c of asset.color.slice(0, 3)) assert.ok(Math.abs(c - BASE) < 1e-6, `base colour ${c}`);
  assert.deepEqual(asset.normalScale, [1, 1], 'GLTFLoader keeps normalScale (1, 1) for meshes with tangents');
  assert.deepEqual(asset.levels, [levels, levels], 'KTX2Loader reads the full chains');
});

test('flat plane: three.js and meso agree radiometrically (calibration)', async () => {
  // The same GGX (height-correlated Smith, Schlick F0 = 0.8) at the specular peak, no normal map,
  // at the base α and at the rougher widths the exported levels reach.
  for (const alpha of [ALPHA, 0.2, 0.5]) {
    fs.writeFileSync(path.join(art, `flat_${alpha}.toml`), transfer.replace(`alpha = ${ALPHA}`, `alpha = ${alpha}`));
    const ref = mesoRender(`flat_${alpha}`, 0.5, `flat_${alpha}.toml`);
    const t = await three('flat', 0.5, { alpha });
    const shipped = await three('flat', 0.5, { alpha, singleScatter: false });
    const k = mean(ref) / mean(t);
    if (alpha === ALPHA) calib = k;
    console.log(`# flat α = ${alpha}: meso ${mean(ref).toFixed(4)}, three.js ${mean(t).toFixed(4)} (as shipped, with multiple scattering: ` +
      `${mean(shipped).toFixed(4)}), meso / three.js ${k.toFixed(4)}`);
    assert.ok(Math.abs(k - 1) < 0.03, `calibration factor ${k} at α = ${alpha}`);
  }
});

test('magnified, the level-0 normal map lands on the same texels in three.js as in meso (alignment)', async () => {
  // 4 pixels per texel: meso shades each texel's normal (piecewise constant), three.js interpolates
  // bilinearly, so the error is not small; a map shifted by a fraction of its period is much worse.
  const ref = mesoRender('align', 0.125, 'reference.toml');
  const aligned = await three('standard', 0.125);
  const shifted = await three('standard', 0.125, { uvOffset: [0.37, 0.21] });
  const eA = mae(aligned, ref) / mean(ref), eS = mae(shifted, ref) / mean(ref);
  console.log(`# aligned: relative pixel error ${eA.toFixed(3)}; shifted map ${eS.toFixed(3)}`);
  assert.ok(eA < 0.6 * eS, 'the texture lands where meso puts it');
});

for (const d of DISTANCES) {
  test(`distance ${d}: the exported maps are closer to meso's supersampled reference than standard mips`, async () => {
    const width = 0.5 * d;
    const ref = mesoRender(`ref_d${d}`, width, 'reference.toml');
    const a = (await three('exported', width)).map((v) => v * calib);
    const b = (await three('standard', width)).map((v) => v * calib);
    const g = (await three('gltf', width)).map((v) => v * calib);
    const a2 = await three('exported', width, { singleScatter: false });
    const b2 = await three('standard', width, { singleScatter: false });
    const r = {
      d, ref: mean(ref), exported: mean(a), standard: mean(b), gltf: mean(g), maeGltf: mae(g, ref) / mean(ref),
      gltfVsExported: mae(g, a) / mean(a),
      maeExported: mae(a, ref) / mean(ref), maeStandard: mae(b, ref) / mean(ref),
      shipped: { exported: mean(a2), standard: mean(b2), maeExported: mae(a2, ref) / mean(ref), maeStandard: mae(b2, ref) / mean(ref) },
    };
    results.push(r);
    if (process.env.ENGINE_FIGURES) {
      const dir = process.env.ENGINE_FIGURES;
      fs.mkdirSync(dir, { recursive: true });
      const stops = -3;   // radiance 8 → white, the same for every picture
      for (const [n, img] of [['reference', ref], ['exported', a], ['standard', b], ['gltf', g]]) {
        fs.writeFileSync(path.join(dir, `d${d}_${n}.png`), srgb8(128, 128, img, stops));
      }
    }
    console.log(`# d = ${d}: mean luminance ref ${r.ref.toFixed(4)} exported ${r.exported.toFixed(4)} standard ${r.standard.toFixed(4)}; ` +
      `pixel error (MAE / mean ref) exported ${(100 * r.maeExported).toFixed(1)} % standard ${(100 * r.maeStandard).toFixed(1)} %`);
    assert.ok(Math.abs(r.exported - r.ref) < Math.abs(r.standard - r.ref), 'mean luminance closer with the exported maps');
    assert.ok(r.maeExported < r.maeStandard, 'pixel error smaller with the exported maps');
    // The asset as an engine loads it (GLTFLoader + KTX2Loader, vertex tangents) shades as the PNG chains do.
    console.log(`# d = ${d}, glTF + KTX2: mean ${r.gltf.toFixed(4)}, pixel error ${(100 * r.maeGltf).toFixed(1)} %, ` +
      `against the PNG chains ${(100 * r.gltfVsExported).toFixed(2)} %`);
    assert.ok(r.gltfVsExported < 0.01, 'glTF + KTX2 render equals the PNG-chain render within 1 % per pixel');
    assert.ok(Math.abs(r.gltf - r.ref) < Math.abs(r.standard - r.ref) && r.maeGltf < r.maeStandard, 'glTF + KTX2 closer than standard mips');
    const s2 = r.shipped;
    console.log(`# d = ${d}, three.js as shipped (multiple-scattering compensation): exported ${s2.exported.toFixed(4)} standard ${s2.standard.toFixed(4)}; ` +
      `pixel error exported ${(100 * s2.maeExported).toFixed(1)} % standard ${(100 * s2.maeStandard).toFixed(1)} %`);
    assert.ok(Math.abs(s2.exported - r.ref) < Math.abs(s2.standard - r.ref), 'as shipped too: mean luminance closer');
    assert.ok(s2.maeExported < s2.maeStandard, 'as shipped too: pixel error smaller');
  });
}

test('summary table', () => {
  fs.writeFileSync(path.join(art, 'results.json'), JSON.stringify({ spp: SPP, calib, results }, null, 1));
  console.log('# | d | texels / pixel | reference | exported | standard | error exported | error standard | glTF + KTX2 | error glTF | glTF vs PNG chains |');
  for (const r of results) {
    console.log(`# | ${r.d} | ${r.d} × ${(r.d / Math.cos(Math.PI / 6)).toFixed(1)} | ${r.ref.toFixed(3)} | ${r.exported.toFixed(3)} (${(100 * (r.exported / r.ref - 1)).toFixed(1)} %) | ` +
      `${r.standard.toFixed(3)} (${(100 * (r.standard / r.ref - 1)).toFixed(1)} %) | ${(100 * r.maeExported).toFixed(1)} % | ${(100 * r.maeStandard).toFixed(1)} % | ` +
      `${r.gltf.toFixed(3)} | ${(100 * r.maeGltf).toFixed(1)} % | ${(100 * r.gltfVsExported).toFixed(2)} % |`);
  }
  console.log('# three.js as shipped: | d | exported | standard | error exported | error standard |');
  for (const r of results) {
    const s2 = r.shipped;
    console.log(`# | ${r.d} | ${s2.exported.toFixed(3)} (${(100 * (s2.exported / r.ref - 1)).toFixed(1)} %) | ${s2.standard.toFixed(3)} (${(100 * (s2.standard / r.ref - 1)).toFixed(1)} %) | ` +
      `${(100 * s2.maeExported).toFixed(1)} % | ${(100 * s2.maeStandard).toFixed(1)} % |`);
  }
  assert.equal(results.length, DISTANCES.length);
});
