  const $ = (id) => document.getElementById(id);
  const PALETTE = ['#e0a84a', '#6fa8dc', '#e06c75', '#98c379', '#c678dd', '#56b6c2',
    '#d19a66', '#61afef', '#be5046', '#a6e22e', '#f4bf75', '#ae81ff'];
  const lobeColor = (i) => PALETTE[i % PALETTE.length];
  const clamp = (x, a, b) => Math.min(b, Math.max(a, x));
  const deg = (r) => r * 180 / Math.PI;
  const rad = (d) => d * Math.PI / 180;
  const round = (x, n) => { const k = Math.pow(10, n); return Math.round(x * k) / k; };
  const clone = (x) => JSON.parse(JSON.stringify(x));

  // ---------------------------------------------------------------- state
  const state = {
    material: {
      name: 'untitled',
      ndf: { kind: 'phong-peaks', lobes: [{ axis: [0, 0], weight: 1, exponent: 100 }] },
      transfer: { kind: 'phong', exponent: 50, specular: [1, 1, 1] },
    },
    selected: 0,
    view: { object: 'sphere', exposure: 0, tangent_deg: 0, size: 384, spp: 1 },
    lights: [
      { name: 'Key', on: true, azimuth_deg: -35, elevation_deg: 40, intensity: 3, color: [1, 1, 1], dot: '#f2f2f2' },
      { name: 'Grazing', on: true, azimuth_deg: 80, elevation_deg: 6, intensity: 4, color: [1, 0.92, 0.8], dot: '#ffd9a0' },
      { name: 'Rim', on: false, azimuth_deg: 165, elevation_deg: 25, intensity: 3, color: [0.8, 0.88, 1], dot: '#b8d0ff' },
    ],
    ndfScale: 'linear',
    sliceTheta: 45,
    // The open texture (POST /api/texture): {id, info, file, image, level, row, col, lobes,
    // previousNdf}; null when none is open.
    texture: null,
  };
  let presets = [];
  const history = { undo: [], redo: [], committed: null };
  // The NDF a kind switch left behind, per family (lobe lists, GGX/Beckmann roughness), so that
  // switching back restores it. Page state, not part of the material; reset when a material loads.
  const ndfMemory = { lobes: null, analytic: null };
  const blend = { a: null, b: null, t: 0 };

  // ---------------------------------------------------------------- colour helpers
  const srgbToLin = (c) => (c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4));
  const linToSrgb = (c) => (c <= 0.0031308 ? 12.92 * c : 1.055 * Math.pow(c, 1 / 2.4) - 0.055);
  const hexToLin = (h) => [1, 3, 5].map((i) => round(srgbToLin(parseInt(h.substr(i, 2), 16) / 255), 4));
  const linToHex = (rgb) => '#' + rgb.map((c) => Math.round(clamp(linToSrgb(clamp(c, 0, 1)), 0, 1) * 255)
    .toString(16).padStart(2, '0')).join('');

