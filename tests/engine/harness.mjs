// What the engine tests share: headless Chromium with three.js served from node_modules and export
// folders served under http://meso.test/<prefix>/, meso's reference renders of a tilted plane
// (orthographic camera, one directional light; luminance per pixel, rows top-down), and the two
// image measures the tests compare by.
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';
import { readExr } from './exr.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
/** The meso binary the tests run (`MESO_BIN`, else the release build). */
export const meso = process.env.MESO_BIN || path.join(here, '../../target/release/meso');

/** Mean of an array. */
export const mean = (a) => a.reduce((s, v) => s + v, 0) / a.length;
/** Mean absolute difference of two arrays of the same length. */
export const mae = (a, b) => a.reduce((s, v, i) => s + Math.abs(v - b[i]), 0) / a.length;

/**
 * Launch headless Chromium (SwiftShader WebGL 2) on page.mjs. `dirs` maps a URL prefix (e.g. 'exp')
 * to a folder whose files are served by base name under http://meso.test/<prefix>/. Resolves when the
 * page says it is ready; returns { browser, page }.
 */
export async function openPage(dirs) {
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  const page = await browser.newPage();
  page.on('pageerror', (e) => console.error('page error:', e));
  page.on('console', (m) => { if (m.type() === 'error' || m.type() === 'warning') console.error('page:', m.text()); });
  const files = {
    '/three.module.js': path.join(here, 'node_modules/three/build/three.module.js'),
    '/three.core.js': path.join(here, 'node_modules/three/build/three.core.js'),
    '/page.mjs': path.join(here, 'page.mjs'),
  };
  // three.js's own loaders (GLTFLoader, KTX2Loader and what they import) from its examples folder.
  const addons = path.join(here, 'node_modules/three/examples/jsm');
  const types = { '.png': 'image/png', '.gltf': 'model/gltf+json', '.bin': 'application/octet-stream', '.ktx2': 'image/ktx2', '.js': 'text/javascript', '.mjs': 'text/javascript' };
  await page.route('http://meso.test/**', (route) => {
    const p = new URL(route.request().url()).pathname;
    if (p === '/') {
      return route.fulfill({ contentType: 'text/html', body: '<!doctype html><script type="importmap">{"imports":{"three":"/three.module.js","three/addons/":"/addons/"}}</script><script type="module" src="/page.mjs"></script>' });
    }
    let f = files[p] || null;
    const prefix = p.split('/')[1];
    if (!f && Object.hasOwn(dirs, prefix)) f = path.join(dirs[prefix], path.basename(p));
    if (!f && p.startsWith('/addons/')) {
      f = path.join(addons, path.normalize(p.slice('/addons/'.length)));
      if (!f.startsWith(addons)) f = null;
    }
    if (!f || !fs.existsSync(f)) return route.fulfill({ status: 404, body: 'not found' });
    return route.fulfill({ body: fs.readFileSync(f), contentType: types[path.extname(f)] || 'application/octet-stream' });
  });
  await page.goto('http://meso.test/');
  await page.waitForFunction(() => window.ready === true, null, { timeout: 60000 });
  return { browser, page };
}

/**
 * The scene file of meso's reference: the plane z = 0 (uv_scale 1, tangent +x) seen by an
 * orthographic camera `width` across at `view.eye`, lit by one directional light, 128² at `spp`.
 */
export function sceneToml(view, width, material, spp) {
  return `[camera]
kind = "orthographic"
position = [${view.eye.join(', ')}]
look_at = [0.0, 0.0, 0.0]
up = [${view.up.join(', ')}]
width = ${width}
[image]
width = 128
height = 128
spp = ${spp}
[[object]]
kind = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
tangent = [1.0, 0.0, 0.0]
uv_scale = 1.0
material = "${material}"
[[light]]
kind = "directional"
direction = [${view.lightDir.join(', ')}]
irradiance = [${view.irradiance}, ${view.irradiance}, ${view.irradiance}]
`;
}

/** Render `sceneToml(view, width, material, spp)` with meso in `dir`; the luminance per pixel. */
export function mesoRender(dir, name, view, width, material, spp) {
  const scene = path.join(dir, `scene_${name}.toml`);
  fs.writeFileSync(scene, sceneToml(view, width, material, spp));
  const out = path.join(dir, `${name}.exr`);
  execFileSync(meso, ['render', scene, '-o', out], { stdio: ['ignore', 'ignore', 'inherit'] });
  const img = readExr(fs.readFileSync(out));
  const { R, G, B } = img.channels;
  return Array.from(R, (r, i) => 0.2126 * r + 0.7152 * G[i] + 0.0722 * B[i]);
}
