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

function checkKtx(name, g) {
  const c = readKtx(new Uint8Array(fs.readFileSync(path.join(outDir, name))));
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

test('scene.gltf: gltf-validator reports zero errors', async () => {
  const file = path.join(outDir, 'scene.gltf');
  const result = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: 'scene.gltf',
    format: 'gltf',
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.join(outDir, decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data)));
      }),
  });
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

test('an unwritable target fails with the path named and leaves no files', () => {
  const blocker = path.join(art, 'plain-file');
  fs.writeFileSync(blocker, 'x');
  const r = spawnSync(bin, ['export', path.join(inDir, 'height.png'), '--texel-size', '1',
    '--height-scale', '1', '--out', path.join(blocker, 'out')], { encoding: 'utf8' });
  assert.notEqual(r.status, 0);
  assert.match(r.stderr, /plain-file/);
  assert.equal(fs.statSync(blocker).isFile(), true);
});
