// `meso export --anisotropic` checked in a real engine (issue #15 item 4a): a plane of grooves
// (slopes along the image direction (2, 1), 26.6° from the u axis, so a flipped or swapped direction
// shows) exported twice, isotropic and anisotropic; three.js in headless Chromium loads each
// `scene.gltf` with GLTFLoader (KHR_materials_anisotropy → MeshPhysicalMaterial) and the fitted
// chains with KTX2Loader, and renders it at several distances beside three.js's standard mips;
// all three are compared with meso's supersampled bump-mapped render of the level-0 normal map.
// Results in artifacts/aniso/results.json; docs/engine.md has the table.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { grey16 } from './png.mjs';
import { meso, mean, mae, openPage, mesoRender } from './harness.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const art = path.join(here, 'artifacts', 'aniso');
const isoDir = path.join(art, 'iso');
const anisoDir = path.join(art, 'aniso');
const N = 128;                      // height map size
const TEXEL = 1 / N;                // one map copy per world unit (uv_scale 1)
const SLOPE = 0.25;                 // RMS slope across the grooves
const ALPHA = 0.08;                 // base GGX width (glossy)
const BASE = 0.8;                   // metallic 1: F0 = 0.8
const SPP = Number(process.env.ENGINE_SPP || 1024);
const DISTANCES = [1, 4, 16, 32];   // the camera's width is 0.5·d: at d = 1 a pixel spans one texel
const view = {
  eye: [0, -2.5, 4.330127], up: [0, 1, 0],            // 30° from the normal
  lightDir: [0, 0.5, 0.8660254], irradiance: 1,        // the mirror direction: the specular peak
};

// Grooves: Σ a_k cos(2π k (2x + y) / N) over a few k (periodic on the map), heights as 16-bit codes,
// and the height scale that gives them an RMS slope of SLOPE.
function grooves() {
  const terms = [[3, 1.0], [4, 0.7], [5, 0.8], [7, 0.5], [9, 0.45], [11, 0.3]];
  const h = new Float64Array(N * N);
  for (let y = 0; y < N; y++) for (let x = 0; x < N; x++) {
    let v = 0;
    for (const [k, a] of terms) v += (a / k) * Math.cos(2 * Math.PI * k * (2 * (x + 0.5) + (y + 0.5)) / N);
    h[y * N + x] = v;
  }
  let lo = Infinity, hi = -Infinity;
  for (const v of h) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  const codes = Uint16Array.from(h, (v) => Math.round(65535 * (v - lo) / (hi - lo)));
  let g2 = 0;   // mean squared central-difference gradient of the codes / 65535, per texel
  for (let y = 0; y < N; y++) for (let x = 0; x < N; x++) {
    const at = (i, j) => codes[((j + N) % N) * N + ((i + N) % N)] / 65535;
    const gx = (at(x + 1, y) - at(x - 1, y)) / 2, gy = (at(x, y + 1) - at(x, y - 1)) / 2;
    g2 += gx * gx + gy * gy;
  }
  const height = SLOPE * TEXEL / Math.sqrt(g2 / (N * N));
  return { codes, height };
}

const transfer = (alpha) => `[transfer]
kind = "microfacet"
distribution = "ggx"
alpha = ${alpha}
fresnel = "schlick"
f0 = [${BASE}, ${BASE}, ${BASE}]
`;

let browser, page, info, iso, aniso;
let levels = 0;
let calib = 1;
const results = [];

before(async () => {
  fs.rmSync(art, { recursive: true, force: true });
  fs.mkdirSync(art, { recursive: true });
  const { codes, height } = grooves();
  const input = path.join(art, 'grooves.png');
  fs.writeFileSync(input, grey16(N, N, codes));
  for (const [dir, extra] of [[isoDir, []], [anisoDir, ['--anisotropic']]]) {
    execFileSync(meso, ['export', input, '--texel-size', String(TEXEL), '--height-scale', String(height),
      '--alpha', String(ALPHA), '--metallic', '1', ...extra, '--out', dir], { stdio: ['ignore', 'inherit', 'inherit'] });
  }
  while (fs.existsSync(path.join(anisoDir, `normal_mip${levels}.png`))) levels++;
  fs.writeFileSync(path.join(art, 'reference.toml'),
    `[texture]\nkind = "bump-mapped"\nnormal_map = "aniso/normal_mip0.png"\nconvention = "gl"\n${transfer(ALPHA)}`);
  fs.writeFileSync(path.join(art, 'flat.toml'), transfer(ALPHA));
  // 'exp' serves the isotropic export to loadMaps (its level-0 normal map is the standard-mips input).
  ({ browser, page } = await openPage({ exp: isoDir, iso: isoDir, aniso: anisoDir }));
  info = await page.evaluate((n) => window.loadMaps(n), levels);
  iso = await page.evaluate(() => window.loadAsset('iso', 'iso'));
  aniso = await page.evaluate(() => window.loadAsset('aniso', 'aniso'));
});

after(async () => { if (browser) await browser.close(); });

const three = (mode, width, extra = {}) => page.evaluate((o) => window.renderView(o),
  { ...view, mode, width, alpha: ALPHA, baseColor: BASE, uvScale: 1, singleScatter: true, ...extra });

test('three.js reads KHR_materials_anisotropy from the exported glTF, and the three KTX2 chains', () => {
  assert.ok(info.anisoPatchable, 'three.js anisotropy-frame lines found (the frame patch applies)');
  console.log(`# anisotropic asset: physical ${aniso.physical}, anisotropy ${aniso.anisotropy}, rotation ${aniso.anisotropyRotation}, ` +
    `KTX2 levels ${aniso.levels.join(', ')}; isotropic asset: physical ${iso.physical}, anisotropy ${iso.anisotropy}`);
  assert.equal(levels, Math.log2(N) + 1);
  assert.ok(aniso.physical && aniso.anisotropic, 'GLTFLoader made a MeshPhysicalMaterial with an anisotropy map');
  assert.equal(aniso.anisotropy, 1);
  assert.equal(aniso.anisotropyRotation, 0);
  assert.deepEqual(aniso.levels, [levels, levels, levels], 'normal, metallic-roughness and anisotropy chains full');
  assert.ok(!iso.anisotropic && iso.anisotropy === 0, 'the isotropic export has no anisotropy');
  assert.ok(aniso.tangentAlongU > 0.9999 && aniso.bitangentUp > 0.9999, 'the glTF tangent frame');
});

test('flat plane: three.js and meso agree radiometrically (calibration)', async () => {
  const ref = mesoRender(art, 'flat', view, 0.5, 'flat.toml', SPP);
  const t = await three('flat', 0.5);
  calib = mean(ref) / mean(t);
  console.log(`# flat α = ${ALPHA}: meso / three.js ${calib.toFixed(4)}`);
  assert.ok(Math.abs(calib - 1) < 0.03, `calibration factor ${calib}`);
});

for (const d of DISTANCES) {
  test(`distance ${d}: grooves with the anisotropic export against the isotropic one and standard mips`, async () => {
    const width = 0.5 * d;
    const ref = mesoRender(art, `ref_d${d}`, view, width, 'reference.toml', SPP);
    const a = (await three('gltf', width, { asset: 'aniso', anisoFrame: true })).map((v) => v * calib);
    const shipped = (await three('gltf', width, { asset: 'aniso' })).map((v) => v * calib);
    const i = (await three('gltf', width, { asset: 'iso' })).map((v) => v * calib);
    const s = (await three('standard', width)).map((v) => v * calib);
    const m = mean(ref);
    const r = {
      d, ref: m, aniso: mean(a), anisoShipped: mean(shipped), iso: mean(i), standard: mean(s),
      maeAniso: mae(a, ref) / m, maeAnisoShipped: mae(shipped, ref) / m, maeIso: mae(i, ref) / m, maeStandard: mae(s, ref) / m,
    };
    results.push(r);
    const off = (v) => Math.abs(v - m);
    if (d === 1) {
      // Level 0 has strength 0: the anisotropic material is the isotropic one.
      assert.ok(Math.abs(r.aniso - r.iso) < 0.01 * r.iso, 'at d = 1 the anisotropic export shades as the isotropic one');
      // three.js's own anisotropy frame ignores the normal map's tilt (page.mjs, ANISO_LINES): the
      // grooves shade like a flat mirror. If this fails, three.js changed: update docs/engine.md.
      assert.ok(r.anisoShipped > 2 * m, 'three.js r187 with its own anisotropy frame loses the normal map (documented limit)');
    } else {
      assert.ok(r.maeAniso < r.maeIso, 'pixel error smaller with the anisotropic export than with the isotropic one');
      assert.ok(r.maeAniso < r.maeStandard, 'pixel error smaller with the anisotropic export than with standard mips');
      // (At d = 1 three.js's bilinear normals are 3 % brighter than meso's piecewise-constant texels.)
      assert.ok(off(r.aniso) < 0.03 * m, 'mean luminance within 3 % of the reference');
    }
    assert.ok(off(r.aniso) <= off(r.iso) + 1e-3 * m, 'mean luminance at least as close with the anisotropic export');
    console.log(`# d = ${d}: mean luminance ref ${m.toFixed(4)} aniso ${r.aniso.toFixed(4)} (three.js's own frame ${r.anisoShipped.toFixed(4)}) ` +
      `iso ${r.iso.toFixed(4)} standard ${r.standard.toFixed(4)}; pixel error aniso ${(100 * r.maeAniso).toFixed(1)} % ` +
      `(three.js's own frame ${(100 * r.maeAnisoShipped).toFixed(1)} %) iso ${(100 * r.maeIso).toFixed(1)} % standard ${(100 * r.maeStandard).toFixed(1)} %`);
  });
}

test('summary', () => {
  fs.writeFileSync(path.join(art, 'results.json'), JSON.stringify({ spp: SPP, calib, results }, null, 1));
  const pc = (v) => `${(100 * v).toFixed(1)} %`;
  console.log('# | d | reference | anisotropic | (three.js frame) | isotropic | standard | error aniso | (three.js frame) | error iso | error standard |');
  for (const r of results) {
    console.log(`# | ${r.d} | ${r.ref.toFixed(3)} | ${r.aniso.toFixed(3)} | ${r.anisoShipped.toFixed(3)} | ${r.iso.toFixed(3)} | ${r.standard.toFixed(3)} | ` +
      `${pc(r.maeAniso)} | ${pc(r.maeAnisoShipped)} | ${pc(r.maeIso)} | ${pc(r.maeStandard)} |`);
  }
  assert.equal(results.length, DISTANCES.length);
});
