// K lobes in a shader, executed: the shipped GLSL (crates/meso-export/shaders/meso_lobes.glsl)
// runs in WebGL 2 and the shipped WGSL (meso_lobes.wgsl) in a WebGPU compute shader (headless
// Chromium, SwiftShader for both) on the cases of meso-export's example
// `lobe_cases` (lobe texels, wi, wo, f0) and must give the CPU reference `meso_export::lobes::
// eval_texel` that the example wrote beside them: relative error ≤ 2e-3 (f32 against f64) with an
// absolute floor of 1e-5 / sr. Results in artifacts/lobes_results.json.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = path.dirname(fileURLToPath(import.meta.url));
const root = path.resolve(here, '../..');
const art = path.join(here, 'artifacts');
const casesFile = path.join(art, 'lobe_cases.json');
const glsl = fs.readFileSync(path.join(root, 'crates/meso-export/shaders/meso_lobes.glsl'), 'utf8');
const wgsl = fs.readFileSync(path.join(root, 'crates/meso-export/shaders/meso_lobes.wgsl'), 'utf8');

let browser, page, cases;

before(async () => {
  fs.mkdirSync(art, { recursive: true });
  execFileSync('cargo', ['run', '-q', '--release', '-p', 'meso-export', '--example', 'lobe_cases', '--', casesFile],
    { cwd: root, stdio: ['ignore', 'inherit', 'inherit'] });
  cases = JSON.parse(fs.readFileSync(casesFile, 'utf8'));
  browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--enable-unsafe-webgpu', '--enable-features=Vulkan', '--use-webgpu-adapter=swiftshader', '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  page = await browser.newPage();
  page.on('pageerror', (e) => console.error('page error:', e));
  // http://localhost is a secure context (WebGPU needs one); nothing leaves the browser.
  await page.route('http://localhost/**', (route) => route.fulfill({ contentType: 'text/html', body: '<!doctype html><canvas id="c" width="1" height="1"></canvas>' }));
  await page.goto('http://localhost/');
});

after(async () => { if (browser) await browser.close(); });

// In the page: one row of a RGBA32F data texture per case (K lobe texels, then wi, wo, f0), one
// output texel per case in a RGBA32F render target, read back with readPixels.
function runInPage({ glsl, k, rows }) {
  const gl = document.getElementById('c').getContext('webgl2');
  if (!gl) return { error: 'no WebGL 2 context' };
  if (!gl.getExtension('EXT_color_buffer_float')) return { error: 'no EXT_color_buffer_float' };
  const n = rows.length / ((k + 3) * 4);
  const vs = '#version 300 es\nvoid main() { vec2 p = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID >> 1) * 4 - 1)); gl_Position = vec4(p, 0.0, 1.0); }';
  const fs = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
${glsl}
uniform sampler2D data;
out vec4 color;
void main() {
  int row = int(gl_FragCoord.y);
  vec4 s = vec4(0.0);
  for (int j = 0; j < ${k}; j++) s = meso_lobe_add(texelFetch(data, ivec2(j, row), 0), texelFetch(data, ivec2(${k}, row), 0).xyz, texelFetch(data, ivec2(${k + 1}, row), 0).xyz, s);
  color = vec4(meso_lobes_finish(s, texelFetch(data, ivec2(${k}, row), 0).xyz, texelFetch(data, ivec2(${k + 1}, row), 0).xyz, texelFetch(data, ivec2(${k + 2}, row), 0).xyz), 1.0);
}`;
  const sh = (type, src) => {
    const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const prog = gl.createProgram();
  gl.attachShader(prog, sh(gl.VERTEX_SHADER, vs));
  gl.attachShader(prog, sh(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) return { error: gl.getProgramInfoLog(prog) };
  const tex = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, k + 3, n, 0, gl.RGBA, gl.FLOAT, new Float32Array(rows));
  const out = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, out);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, 1, n, 0, gl.RGBA, gl.FLOAT, null);
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, out, 0);
  if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) return { error: 'float framebuffer incomplete' };
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.useProgram(prog);
  gl.uniform1i(gl.getUniformLocation(prog, 'data'), 0);
  gl.viewport(0, 0, 1, n);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const px = new Float32Array(4 * n);
  gl.readPixels(0, 0, 1, n, gl.RGBA, gl.FLOAT, px);
  const dbg = gl.getExtension('WEBGL_debug_renderer_info');
  return { renderer: gl.getParameter(dbg ? dbg.UNMASKED_RENDERER_WEBGL : gl.RENDERER), values: Array.from(px) };
}

// In the page: the WGSL in a compute shader, one invocation per case, same data layout.
async function runWgslInPage({ wgsl, k, rows }) {
  if (!navigator.gpu) return { error: 'no navigator.gpu' };
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) return { error: 'no WebGPU adapter' };
  const device = await adapter.requestDevice();
  const n = rows.length / ((k + 3) * 4);
  const code = `${wgsl}
@group(0) @binding(0) var<storage, read> data: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> outv: array<vec4<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  let i = id.x;
  if (i >= ${n}u) { return; }
  let b = i * ${k + 3}u;
  let wi = data[b + ${k}u].xyz;
  let wo = data[b + ${k + 1}u].xyz;
  var s = vec4<f32>(0.0);
  for (var j = 0u; j < ${k}u; j++) { s = meso_lobe_add(data[b + j], wi, wo, s); }
  outv[i] = vec4<f32>(meso_lobes_finish(s, wi, wo, data[b + ${k + 2}u].xyz), 1.0);
}`;
  device.pushErrorScope('validation');
  const module = device.createShaderModule({ code });
  const info = await module.getCompilationInfo();
  const errs = info.messages.filter((m) => m.type === 'error');
  if (errs.length) return { error: errs.map((m) => `${m.lineNum}:${m.linePos} ${m.message}`).join('; ') };
  const pipeline = device.createComputePipeline({ layout: 'auto', compute: { module, entryPoint: 'main' } });
  const input = device.createBuffer({ size: rows.length * 4, usage: GPUBufferUsage.STORAGE, mappedAtCreation: true });
  new Float32Array(input.getMappedRange()).set(rows);
  input.unmap();
  const output = device.createBuffer({ size: n * 16, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_SRC });
  const read = device.createBuffer({ size: n * 16, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST });
  const bind = device.createBindGroup({ layout: pipeline.getBindGroupLayout(0), entries: [
    { binding: 0, resource: { buffer: input } }, { binding: 1, resource: { buffer: output } }] });
  const enc = device.createCommandEncoder();
  const pass = enc.beginComputePass();
  pass.setPipeline(pipeline);
  pass.setBindGroup(0, bind);
  pass.dispatchWorkgroups(Math.ceil(n / 64));
  pass.end();
  enc.copyBufferToBuffer(output, 0, read, 0, n * 16);
  device.queue.submit([enc.finish()]);
  const err = await device.popErrorScope();
  if (err) return { error: err.message };
  await read.mapAsync(GPUMapMode.READ);
  const values = Array.from(new Float32Array(read.getMappedRange()));
  const ai = adapter.info || {};
  return { renderer: `WebGPU ${ai.vendor || ''} ${ai.architecture || ''}`.trim(), values };
}

function caseRows() {
  const rows = [];
  for (const c of cases.cases) {
    for (const t of c.texels) rows.push(...t);
    rows.push(...c.wi, 0, ...c.wo, 0, ...c.f0, 0);
  }
  return rows;
}

test('the WGSL lobe function in WebGPU matches the CPU reference', async () => {
  const { k } = cases;
  const r = await page.evaluate(runWgslInPage, { wgsl, k, rows: caseRows() });
  assert.ok(!r.error, r.error);
  let worst = 0, worstAt = -1;
  cases.cases.forEach((c, i) => {
    for (let ch = 0; ch < 3; ch++) {
      const got = r.values[4 * i + ch], want = c.f[ch];
      assert.ok(Number.isFinite(got), `case ${i}: ${got}`);
      const e = Math.abs(got - want) / Math.max(Math.abs(want), 1e-5 / 2e-3);
      if (e > worst) { worst = e; worstAt = i; }
    }
  });
  fs.writeFileSync(path.join(art, 'lobes_wgsl_results.json'), JSON.stringify({ renderer: r.renderer, cases: cases.cases.length, k, worstRelative: worst, worstCase: cases.cases[worstAt] ?? null }, null, 1));
  console.log(`# ${r.renderer}: WGSL, ${cases.cases.length} cases, worst relative error ${worst.toExponential(2)}`);
  assert.ok(worst <= 2e-3, `worst relative error ${worst} at case ${worstAt}`);
  // The check can fail: the same wrong normalisation is caught.
  const c = cases.cases.find((x) => x.f[1] > 1e-3);
  const rows = [...c.texels.flat(), ...c.wi, 0, ...c.wo, 0, ...c.f0, 0];
  const b = await page.evaluate(runWgslInPage, { wgsl: wgsl.replace('(8.0 * MESO_PI)', '(4.0 * MESO_PI)'), k, rows });
  assert.ok(!b.error, b.error);
  assert.ok(Math.abs(b.values[1] / c.f[1] - 2) < 1e-2, `broken WGSL gave ${b.values[1]} for ${c.f[1]}`);
});

test('the GLSL lobe function in WebGL 2 matches the CPU reference', async () => {
  const { k } = cases;
  const rows = caseRows();
  const r = await page.evaluate(runInPage, { glsl, k, rows });
  assert.ok(!r.error, r.error);
  let worst = 0, worstAt = -1, nonzero = 0;
  cases.cases.forEach((c, i) => {
    for (let ch = 0; ch < 3; ch++) {
      const got = r.values[4 * i + ch], want = c.f[ch];
      assert.ok(Number.isFinite(got), `case ${i}: ${got}`);
      const e = Math.abs(got - want) / Math.max(Math.abs(want), 1e-5 / 2e-3);
      if (want > 1e-5) nonzero++;
      if (e > worst) { worst = e; worstAt = i; }
    }
  });
  fs.writeFileSync(path.join(art, 'lobes_results.json'), JSON.stringify({ renderer: r.renderer, cases: cases.cases.length, k, nonzero, worstRelative: worst, worstCase: cases.cases[worstAt] ?? null, gpu: r.values.slice(4 * worstAt, 4 * worstAt + 3) }, null, 1));
  console.log(`# ${r.renderer}: ${cases.cases.length} cases (K = ${k}, ${nonzero} non-zero values), worst relative error ${worst.toExponential(2)}`);
  assert.ok(nonzero > cases.cases.length, 'the cases should mostly reflect something');
  assert.ok(worst <= 2e-3, `worst relative error ${worst} at case ${worstAt}`);
});

test('the check can fail: a wrong normalisation in the GLSL is caught', async () => {
  const broken = glsl.replace('(8.0 * MESO_PI)', '(4.0 * MESO_PI)');
  assert.notEqual(broken, glsl);
  const { k } = cases;
  const c = cases.cases.find((x) => x.f[1] > 1e-3);
  const rows = [...c.texels.flat(), ...c.wi, 0, ...c.wo, 0, ...c.f0, 0];
  const r = await page.evaluate(runInPage, { glsl: broken, k, rows });
  assert.ok(!r.error, r.error);
  assert.ok(Math.abs(r.values[1] / c.f[1] - 2) < 1e-2, `broken shader gave ${r.values[1]} for ${c.f[1]}`);
});
