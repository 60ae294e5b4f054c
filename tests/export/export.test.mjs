// Independent checks of `meso export`: the KTX2 files read by ktx-parse (Khronos-compatible
// reader by Don McCurdy), the glTF asset by Khronos' gltf-validator. The input height map,
// roughness map and base colour are PNGs this file writes itself (zlib + CRC32 from node).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import zlib from 'node:zlib';
import { fileURLToPath } from 'node:url';
import { read as readKtx } from 'ktx-parse';
import validator from 'gltf-validator';

const here = path.dirname(fileURLToPath(import.meta.url));
const art = path.join(here, 'artifacts');
const bin = process.env.MESO_BIN;
fs.mkdirSync(art, { recursive: true });

/** A PNG (8-bit grey/RGB or 16-bit grey) from raw rows, top row first. */
function png(width, height, colorType, bitDepth, raw) {
  const chunk = (type, data) => {
    const len = Buffer.alloc(4);
    len.writeUInt32BE(data.length);
    const td = Buffer.concat([Buffer.from(type, 'ascii'), data]);
    const crc = Buffer.alloc(4);
    crc.writeUInt32BE(zlib.crc32(td) >>> 0);
    return Buffer.concat([len, td, crc]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr[8] = bitDepth;
  ihdr[9] = colorType;
  const bpp = (colorType === 2 ? 3 : 1) * (bitDepth / 8);
  const rows = [];
  for (let r = 0; r < height; r++) {
    rows.push(Buffer.from([0]), raw.subarray(r * width * bpp, (r + 1) * width * bpp));
  }
  return Buffer.concat([
    Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]),
    chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(Buffer.concat(rows))),
    chunk('IEND', Buffer.alloc(0)),
  ]);
}

const N = 64;
function inputs(dir) {
  // Height: periodic bumps (two sine products), 16-bit grey.
  const h = Buffer.alloc(N * N * 2);
  const rough = Buffer.alloc(N * N);
  const color = Buffer.alloc(N * N * 3);
  for (let r = 0; r < N; r++) {
    for (let c = 0; c < N; c++) {
      const x = (2 * Math.PI * c) / N, y = (2 * Math.PI * r) / N;
      const v = 0.5 + 0.25 * Math.sin(4 * x) * Math.sin(4 * y) + 0.2 * Math.sin(13 * x + 3 * y);
      h.writeUInt16BE(Math.round(Math.min(1, Math.max(0, v)) * 65535), (r * N + c) * 2);
      rough[r * N + c] = c < N / 2 ? 90 : 160; // glTF roughness ≈ 0.35 | 0.63
      color.set([200, 120 + (r % 8) * 10, 60], (r * N + c) * 3);
    }
  }
  fs.writeFileSync(path.join(dir, 'height.png'), png(N, N, 0, 16, h));
  fs.writeFileSync(path.join(dir, 'rough.png'), png(N, N, 0, 8, rough));
  fs.writeFileSync(path.join(dir, 'color.png'), png(N, N, 2, 8, color));
}

const inDir = path.join(art, 'input');
const outDir = path.join(art, 'out');
fs.mkdirSync(inDir, { recursive: true });
fs.rmSync(outDir, { recursive: true, force: true });
inputs(inDir);
const report = execFileSync(bin, [
  'export', path.join(inDir, 'height.png'), '--texel-size', '1', '--height-scale', '3',
  '--roughness-map', path.join(inDir, 'rough.png'), '--base-color', path.join(inDir, 'color.png'),
  '--metallic', '0.25', '--out', outDir,
], { encoding: 'utf8' });
fs.writeFileSync(path.join(art, 'report.txt'), report);

function checkKtx(name, g, dir = outDir) {
  const c = readKtx(new Uint8Array(fs.readFileSync(path.join(dir, name))));
  assert.equal(c.vkFormat, 37, 'VK_FORMAT_R8G8B8A8_UNORM');
  assert.equal(c.typeSize, 1);
  assert.equal(c.pixelWidth, N);
  assert.equal(c.pixelHeight, N);
  assert.equal(c.faceCount, 1);
  assert.equal(c.supercompressionScheme, 0);
  assert.equal(c.levelCount, Math.log2(N) + 1);
  assert.equal(c.levels.length, c.levelCount);
  c.levels.forEach((l, k) => {
    const w = Math.max(1, N >> k);
    assert.equal(l.levelData.byteLength, w * w * 4, `level ${k} size`);
    assert.equal(l.uncompressedByteLength, w * w * 4);
  });
  const dfd = c.dataFormatDescriptor[0];
  assert.equal(dfd.colorModel, 1, 'RGBSDA');
  assert.equal(dfd.colorPrimaries, 1, 'BT.709');
  assert.equal(dfd.transferFunction, 1, 'linear');
  assert.equal(dfd.bytesPlane[0], 4);
  assert.deepEqual(dfd.samples.map((s) => s.channelType), [0, 1, 2, 15]);
  assert.deepEqual(dfd.samples.map((s) => s.bitOffset), [0, 8, 16, 24]);
  assert.equal(c.keyValue.KTXorientation, 'rd');
  assert.match(String(c.keyValue.KTXwriter), /^meso export/);
  g(c);
}

test('normal.ktx2: ktx-parse reads a full RGBA8 chain of unit normals above the surface', () => {
  checkKtx('normal.ktx2', (c) => {
    c.levels.forEach((l, k) => {
      const d = l.levelData;
      for (let i = 0; i < d.length; i += 4) {
        const n = [0, 1, 2].map((j) => d[i + j] / 127.5 - 1);
        const len = Math.hypot(...n);
        assert.ok(Math.abs(len - 1) < 0.02, `level ${k} texel ${i / 4}: |n| = ${len}`);
        assert.ok(n[2] > 0, `level ${k}: n_z > 0`);
        assert.equal(d[i + 3], 255);
      }
    });
    // The 1 × 1 level of a periodic bump map points (nearly) straight up.
    const top = c.levels[c.levels.length - 1].levelData;
    assert.ok(top[2] >= 250, `top-level n_z code ${top[2]}`);
  });
});

test('metallic_roughness.ktx2: ktx-parse reads G = roughness growing with the level, B = metallic', () => {
  checkKtx('metallic_roughness.ktx2', (c) => {
    const mean = (d) => {
      let s = 0;
      for (let i = 1; i < d.length; i += 4) s += d[i];
      return s / (d.length / 4);
    };
    const g0 = mean(c.levels[0].levelData);
    // Level 0 is the input: left half 90, right half 160.
    assert.ok(Math.abs(g0 - 125) < 0.6, `level 0 mean G ${g0}`);
    for (let k = 1; k < c.levels.length; k++) {
      const gk = mean(c.levels[k].levelData);
      assert.ok(gk > g0 + 5, `level ${k}: mean roughness code ${gk} ≤ level 0's ${g0}`);
    }
    for (const l of c.levels) {
      for (let i = 0; i < l.levelData.length; i += 4) {
        assert.equal(l.levelData[i + 2], 64, 'B = metallic 0.25');
      }
    }
  });
});

/** Khronos' gltf-validator on `dir`/scene.gltf with its external files. */
async function validate(dir) {
  const file = path.join(dir, 'scene.gltf');
  return validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: 'scene.gltf',
    format: 'gltf',
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.join(dir, decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data)));
      }),
  });
}

test('scene.gltf: gltf-validator reports zero errors', async () => {
  const result = await validate(outDir);
  fs.writeFileSync(path.join(art, 'validator.json'), JSON.stringify(result, null, 2));
  const i = result.issues;
  console.log(`gltf-validator: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints`);
  assert.equal(i.numErrors, 0, JSON.stringify(i.messages.filter((m) => m.severity === 0)));
  assert.equal(i.numWarnings, 0, JSON.stringify(i.messages.filter((m) => m.severity === 1)));
  assert.equal(result.info.resources.filter((r) => r.storage === 'external').length, 4);
  assert.ok(result.info.hasTextures);
  assert.equal(result.info.materialCount, 1);
  assert.equal(result.info.drawCallCount, 2);
});

test('with --base-color the glTF draws the texture at full strength: baseColorFactor = 1', () => {
  // glTF multiplies baseColorTexture by baseColorFactor; the 0.8 grey is only the colour of an
  // export without a texture (before 2026-12-04 it stayed, drawing the texture at 80 %).
  const doc = JSON.parse(fs.readFileSync(path.join(outDir, 'scene.gltf'), 'utf8'));
  const pbr = doc.materials[0].pbrMetallicRoughness;
  assert.equal(doc.images[doc.textures[pbr.baseColorTexture.index].source].uri, 'base_color.png');
  assert.deepEqual(pbr.baseColorFactor, [1, 1, 1, 1]);
});

test('an unwritable target fails with the path named and leaves no files', () => {
  const blocker = path.join(art, 'plain-file');
  fs.writeFileSync(blocker, 'x');
  const r = spawnSync(bin, ['export', path.join(inDir, 'height.png'), '--texel-size', '1',
    '--height-scale', '1', '--out', path.join(blocker, 'out')], { encoding: 'utf8' });
  assert.notEqual(r.status, 0);
  assert.match(r.stderr, /plain-file/);
  assert.equal(fs.statSync(blocker).isFile(), true);
});

// --anisotropic: parallel grooves at 45° (h = 0.5 + 0.4 sin(2π·8(x + y)/N), height scale 0.3: slope
// amplitude 0.13, about 2.7 α₀; map coordinates with
// y up the image; 16-bit), whose slopes — the wide direction of every coarse texel's lobe — lie
// along 45°. Written in image order: image row r is map row N − 1 − r.
const anisoDir = path.join(art, 'out-aniso');
fs.rmSync(anisoDir, { recursive: true, force: true });
{
  const h = Buffer.alloc(N * N * 2);
  for (let r = 0; r < N; r++) {
    const y = N - 1 - r;
    for (let x = 0; x < N; x++) {
      const v = 0.5 + 0.4 * Math.sin((2 * Math.PI * 8 * (x + y)) / N);
      h.writeUInt16BE(Math.round(v * 65535), (r * N + x) * 2);
    }
  }
  fs.writeFileSync(path.join(inDir, 'grooves45.png'), png(N, N, 0, 16, h));
}
const anisoReport = execFileSync(bin, [
  'export', path.join(inDir, 'grooves45.png'), '--texel-size', '1', '--height-scale', '0.3',
  '--alpha', '0.05', '--anisotropic', '--out', anisoDir,
], { encoding: 'utf8' });
fs.writeFileSync(path.join(art, 'report-aniso.txt'), anisoReport);

/** errors.csv as objects keyed by the header's names. */
function errorsCsv(dir) {
  const [head, ...rows] = fs.readFileSync(path.join(dir, 'errors.csv'), 'utf8').trim().split('\n');
  const keys = head.split(',');
  return rows.map((r) => Object.fromEntries(r.split(',').map((v, i) => [keys[i], Number(v)])));
}

test('anisotropy.ktx2: direction of the 45° grooves, strength 0 at level 0, fitted means within quantisation', () => {
  const mr = readKtx(new Uint8Array(fs.readFileSync(path.join(anisoDir, 'metallic_roughness.ktx2'))));
  const csv = errorsCsv(anisoDir);
  let worstDir = 0, worstT = 0, worstB = 0;
  checkKtx('anisotropy.ktx2', (c) => {
    assert.equal(csv.length, c.levelCount);
    c.levels.forEach((l, k) => {
      const d = l.levelData;
      const g = mr.levels[k].levelData;
      let sumT = 0, sumB = 0, strong = 0;
      const n = d.length / 4;
      for (let i = 0; i < d.length; i += 4) {
        // KHR_materials_anisotropy: direction = RG·2 − 1, strength = B, α_b = roughness², α_t = mix(α_b, 1, s²).
        const x = (d[i] / 255) * 2 - 1, y = (d[i + 1] / 255) * 2 - 1, s = d[i + 2] / 255;
        const ab = (g[i + 1] / 255) ** 2;
        sumB += ab;
        sumT += ab * (1 - s * s) + s * s;
        assert.equal(d[i + 3], 255);
        assert.ok(Math.abs(Math.hypot(x, y) - 1) < 0.01, `level ${k}: |direction| = ${Math.hypot(x, y)}`);
        if (k === 0) assert.equal(d[i + 2], 0, 'level 0 is the isotropic input');
        if (d[i + 2] >= 10) {
          strong++;
          let a = Math.abs(Math.atan2(y, x) * 180 / Math.PI - 45) % 180;
          a = Math.min(a, 180 - a);
          worstDir = Math.max(worstDir, a);
          assert.ok(a < 2.5, `level ${k} texel ${i / 4}: direction ${Math.atan2(y, x) * 180 / Math.PI}°`);
        }
      }
      if (k >= 2) assert.ok(strong / n > 0.9, `level ${k}: only ${strong} of ${n} texels anisotropic`);
      // The level means of the decoded texels against the fitted means in errors.csv.
      worstT = Math.max(worstT, Math.abs(sumT / n - csv[k].mean_alpha_t));
      worstB = Math.max(worstB, Math.abs(sumB / n - csv[k].mean_alpha));
    });
  }, anisoDir);
  console.log(`anisotropy: worst direction error ${worstDir.toFixed(2)}°, level means |Δα_t| ≤ ${worstT.toFixed(4)}, |Δα_b| ≤ ${worstB.toFixed(4)}`);
  assert.ok(worstT < 0.005, `mean α_t off by ${worstT}`);
  assert.ok(worstB < 0.003, `mean α_b off by ${worstB}`);
  // The anisotropic fit is clearly better than the isotropic one on the same directions (levels ≥ 2;
  // measured 0.61–0.68×, the bound of the Rust test crates/meso-export/tests/aniso.rs).
  for (const row of csv.slice(2)) {
    assert.ok(row.mean_error_pct < 0.7 * row.iso_fit_error_pct, JSON.stringify(row));
  }
});

test('anisotropy PNGs hold the KTX2 texels', () => {
  const c = readKtx(new Uint8Array(fs.readFileSync(path.join(anisoDir, 'anisotropy.ktx2'))));
  c.levels.forEach((l, k) => {
    const f = fs.readFileSync(path.join(anisoDir, `anisotropy_mip${k}.png`));
    assert.equal(f.readUInt32BE(16), Math.max(1, N >> k), 'PNG width');
    assert.equal(f[25], 2, 'RGB');
  });
});

test('scene.gltf with KHR_materials_anisotropy: gltf-validator reports zero errors and knows the extension', async () => {
  const result = await validate(anisoDir);
  fs.writeFileSync(path.join(art, 'validator-aniso.json'), JSON.stringify(result, null, 2));
  const i = result.issues;
  console.log(`gltf-validator ${result.validatorVersion} (--anisotropic): ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints; extensionsUsed ${JSON.stringify(result.info.extensionsUsed)}`);
  assert.equal(i.numErrors, 0, JSON.stringify(i.messages.filter((m) => m.severity === 0)));
  assert.equal(i.numWarnings, 0, JSON.stringify(i.messages.filter((m) => m.severity === 1)));
  assert.ok(!i.messages.some((m) => /UNSUPPORTED_EXTENSION/.test(m.code)), JSON.stringify(i.messages));
  assert.deepEqual(result.info.extensionsUsed, ['KHR_materials_anisotropy']);
  assert.equal(result.info.resources.filter((r) => r.storage === 'external').length, 4);
  const doc = JSON.parse(fs.readFileSync(path.join(anisoDir, 'scene.gltf'), 'utf8'));
  const ext = doc.materials[0].extensions.KHR_materials_anisotropy;
  assert.equal(doc.images[doc.textures[ext.anisotropyTexture.index].source].uri, 'anisotropy_mip0.png');
});

test('--anisotropic on a 1 × 1 map fails with the file and the reason named', () => {
  const one = path.join(inDir, 'one.png');
  fs.writeFileSync(one, png(1, 1, 0, 8, Buffer.from([128])));
  const r = spawnSync(bin, ['export', one, '--texel-size', '1', '--height-scale', '1',
    '--anisotropic', '--out', path.join(art, 'out-one')], { encoding: 'utf8' });
  assert.notEqual(r.status, 0);
  assert.match(r.stderr, /one\.png/);
  assert.match(r.stderr, /1 × 1/);
  assert.equal(fs.existsSync(path.join(art, 'out-one')), false);
});

test('a material file exports its engine parameters: gltf-validator reports zero errors, the factors are the material\'s', async () => {
  // A dielectric GGX + Lambert material (α 0.09: glTF roughness 0.3, F0 0.04: metallic 0, the
  // Lambert albedo as base colour), as `meso fit` writes materials.
  const mat = path.join(art, 'dielectric.toml');
  fs.writeFileSync(mat, 'form = "microfacet"\n[ndf]\nkind = "ggx"\nalpha = 0.09\n[transfer]\nkind = "mirror"\n'
    + 'fresnel = "schlick"\nf0 = [0.04, 0.04, 0.04]\n[shadowing]\nkind = "smith"\n[diffuse]\nalbedo = [0.5, 0.3, 0.2]\n');
  const dir = path.join(art, 'out-material');
  fs.rmSync(dir, { recursive: true, force: true });
  const r = spawnSync(bin, ['export', mat, '--out', dir], { encoding: 'utf8' });
  assert.equal(r.status, 0, r.stderr);
  assert.match(r.stderr, /engine \(glTF metallic-roughness/);
  const result = await validate(dir);
  fs.writeFileSync(path.join(art, 'validator-material.json'), JSON.stringify(result, null, 2));
  const i = result.issues;
  console.log(`gltf-validator (material file): ${i.numErrors} errors, ${i.numWarnings} warnings`);
  assert.equal(i.numErrors, 0, JSON.stringify(i.messages.filter((m) => m.severity === 0)));
  assert.equal(i.numWarnings, 0, JSON.stringify(i.messages.filter((m) => m.severity === 1)));
  const doc = JSON.parse(fs.readFileSync(path.join(dir, 'scene.gltf'), 'utf8'));
  const bc = doc.materials[0].pbrMetallicRoughness.baseColorFactor;
  [0.5, 0.3, 0.2].forEach((a, c) => assert.ok(Math.abs(bc[c] - a) < 0.06, `base colour ${bc}`));
  // metallicRoughness: G = roughness, B = metallic, the same in every texel of every level.
  const c = readKtx(new Uint8Array(fs.readFileSync(path.join(dir, 'metallic_roughness.ktx2'))));
  assert.equal(c.vkFormat, 37, 'VK_FORMAT_R8G8B8A8_UNORM');
  assert.equal(c.levelCount, 3, 'a flat 4 × 4 map: 4, 2, 1');
  for (const l of c.levels) {
    for (let t = 0; t < l.levelData.length; t += 4) {
      const g = l.levelData[t + 1] / 255, b = l.levelData[t + 2] / 255;
      assert.ok(Math.abs(g - 0.3) < 0.03, `roughness ${g}`);
      assert.ok(b < 0.1, `metallic ${b}`);
    }
  }
});
