'use strict';
// meso NDF editor. One page, no dependencies. The material is kept in the JSON form of the TOML
// material format (docs/material-format.md, docs/http-api.md); every edit re-renders through the
// server's API with at most one request of each kind in flight (latest wins).

(() => {
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

  // ---------------------------------------------------------------- history
  function snapshot() { return JSON.stringify(state.material); }
  function commit() {
    const s = snapshot();
    if (history.committed !== null && s !== history.committed) {
      history.undo.push(history.committed);
      if (history.undo.length > 200) history.undo.shift();
      history.redo = [];
    }
    history.committed = s;
    updateHistoryButtons();
  }
  function restore(s) {
    state.material = JSON.parse(s);
    history.committed = s;
    const n = state.material.ndf;
    const ownTexel = isTexel(n) && state.texture && n.texture === state.texture.id;
    if (state.texture && !ownTexel) closeTexture(false);
    state.selected = Math.max(0, Math.min(state.selected, lobes().length - 1));
    buildAll();
    changed();
    if (ownTexel) pickTexel(n.level, n.texel[0], n.texel[1]);
  }
  function undo() { if (history.undo.length) { history.redo.push(snapshot()); restore(history.undo.pop()); updateHistoryButtons(); } }
  function redo() { if (history.redo.length) { history.undo.push(snapshot()); restore(history.redo.pop()); updateHistoryButtons(); } }
  function updateHistoryButtons() {
    $('btn-undo').disabled = history.undo.length === 0;
    $('btn-redo').disabled = history.redo.length === 0;
  }

  // ---------------------------------------------------------------- material helpers
  // NDF kinds the page edits: lobe lists and the analytic microfacet distributions.
  const LOBE_KINDS = ['phong-peaks', 'deltas'];
  const ANALYTIC_KINDS = ['ggx', 'beckmann'];
  const isAnalytic = (kind) => ANALYTIC_KINDS.includes(kind === undefined ? (state.material.ndf || {}).kind : kind);
  const isLobeKind = (kind) => LOBE_KINDS.includes(kind === undefined ? (state.material.ndf || {}).kind : kind);
  // A texel of an open texture: {kind: 'map', texture: id, level, texel: [row, col]}.
  const isTexel = (n) => !!(n && n.kind === 'map' && n.texture);
  // The lobes of a lobe NDF; other NDFs (analytic, mixtures, radial, texture texels, …) have
  // none here (an empty list not attached to them, so that no `lobes` key reaches the server).
  function lobes() {
    const m = state.material;
    if (!m.ndf) m.ndf = { kind: 'deltas', lobes: [{ axis: [0, 0], weight: 1 }] };
    if (!isLobeKind(m.ndf.kind)) return [];
    if (!Array.isArray(m.ndf.lobes)) m.ndf.lobes = [];
    return m.ndf.lobes;
  }
  const isPeaks = () => state.material.ndf && state.material.ndf.kind === 'phong-peaks';
  // The roughness keys of an analytic NDF: `alpha`, or `alpha_x` and `alpha_y`.
  function alphaFields(n) {
    if (n && n.alpha !== undefined) return { alpha: n.alpha };
    if (n && n.alpha_x !== undefined && n.alpha_y !== undefined) return { alpha_x: n.alpha_x, alpha_y: n.alpha_y };
    return { alpha: 0.2 };
  }
  const meanAlpha = (n) => (n.alpha !== undefined ? n.alpha : Math.sqrt(n.alpha_x * n.alpha_y));
  // A Phong peak about as wide as an analytic NDF of roughness α: cos^η(θ/2) ≈ exp(−ηθ²/8)
  // against Beckmann's exp(−θ²/α²) gives η = 8/α².
  const peakExponent = (alpha) => round(clamp(8 / (alpha * alpha), 0.5, 1e5), 1);

  // Client-side blend, the same rule as POST /api/blend.
  function blendMaterials(a, b, t) {
    const ka = a.ndf.kind, kb = b.ndf.kind;
    const kind = ka === kb ? ka : 'phong-peaks';
    const part = (m, k, s) => {
      const total = m.ndf.lobes.reduce((acc, l) => acc + (l.weight || 0), 0) || 1;
      if (s <= 0) return [];
      return m.ndf.lobes.map((l) => {
        const o = clone(l);
        o.weight = round(l.weight / total * s, 6);
        if (k === 'deltas' && kind === 'phong-peaks') o.exponent = 20000;
        return o;
      });
    };
    const out = clone(t < 0.5 ? a : b);
    out.ndf = { kind, lobes: part(a, ka, 1 - t).concat(part(b, kb, t)) };
    const alb = (m) => (m.diffuse && m.diffuse.albedo) || [0, 0, 0];
    const da = alb(a), db = alb(b);
    if (da.some((x) => x) || db.some((x) => x)) out.diffuse = { albedo: da.map((x, i) => round(x * (1 - t) + db[i] * t, 4)) };
    out.name = `blend ${Math.round((1 - t) * 100)}% ${a.name || 'a'} / ${Math.round(t * 100)}% ${b.name || 'b'}`;
    return out;
  }

  // ---------------------------------------------------------------- the API
  async function api(path, body, kind) {
    const opts = { method: 'POST', body: typeof body === 'string' ? body : JSON.stringify(body),
      headers: { 'content-type': typeof body === 'string' ? 'application/toml' : 'application/json' } };
    if (kind && kind.signal) opts.signal = kind.signal;
    const r = await fetch(path, opts);
    if (!r.ok) {
      let msg = `${r.status}`;
      try { msg = (await r.json()).error || msg; } catch (e) { /* not JSON */ }
      const err = new Error(msg); err.status = r.status; throw err;
    }
    return r;
  }
  // Messages by source ('render', 'file', …): a successful render clears only its own.
  const errors = {};
  function showError(msg, source) {
    errors[source || 'edit'] = msg || '';
    const text = Object.values(errors).filter((m) => m).join('\n');
    const e = $('error');
    e.textContent = text;
    e.hidden = !text;
  }

  // A request pipeline: at most one request in flight; a newer change replaces a queued one.
  function pipeline(run, delay) {
    let busy = false, pending = false, timer = null;
    const go = async () => {
      if (busy) { pending = true; return; }
      busy = true; pending = false;
      try { await run(); } catch (e) { if (e.name !== 'AbortError') console.warn(e); }
      busy = false;
      if (pending) go();
    };
    return () => {
      if (delay) { clearTimeout(timer); timer = setTimeout(go, delay); } else go();
    };
  }

  // ---------------------------------------------------------------- preview
  let lastFullMs = 0;
  let renderSeq = 0;
  let shownSeq = 0;
  let previewUrl = null;
  const stats = { renders: 0, lastMs: 0, lastPath: '', lastSide: 0 };
  function renderBody(side) {
    const t = state.texture;
    return {
      ...(t ? { texture: t.id } : {}),
      material: state.material,
      view: { object: state.view.object, width: side, height: side, spp: state.view.spp,
        exposure: state.view.exposure, tangent_deg: state.view.tangent_deg },
      lights: state.lights.filter((l) => l.on).map((l) => ({ azimuth_deg: l.azimuth_deg,
        elevation_deg: l.elevation_deg, intensity: l.intensity, color: l.color })),
    };
  }
  async function renderOnce(side, seq) {
    const t0 = performance.now();
    const r = await api(state.texture ? '/api/texture/render' : '/api/render', renderBody(side));
    const blob = await r.blob();
    if (seq < shownSeq) return 0;
    shownSeq = seq;
    const url = URL.createObjectURL(blob);
    const img = $('preview');
    await new Promise((res) => { img.onload = res; img.onerror = res; img.src = url; });
    if (previewUrl) URL.revokeObjectURL(previewUrl);
    previewUrl = url;
    const ms = parseFloat(r.headers.get('x-render-ms') || '0');
    stats.renders++; stats.lastMs = ms; stats.lastSide = side; stats.lastPath = r.headers.get('x-brdf-path') || '';
    $('render-stats').textContent = `${side}×${side} · render ${ms.toFixed(1)} ms · round trip ${(performance.now() - t0).toFixed(0)} ms`;
    $('render-path').textContent = stats.lastPath;
    img.dataset.renders = String(stats.renders);
    return ms;
  }
  const previewPipe = pipeline(async () => {
    const seq = ++renderSeq;
    const full = state.view.size;
    $('preview-busy').hidden = false;
    try {
      // Progressive: a quarter-pixel pass first when a full pass is slower than ~60 ms.
      if (lastFullMs > 60) await renderOnce(Math.max(64, Math.round(full / 2)), seq);
      if (seq === renderSeq) lastFullMs = await renderOnce(full, seq);
      showError('', 'render');
    } catch (e) {
      showError(e.message, 'render');
    } finally {
      $('preview-busy').hidden = true;
    }
  }, 0);

  // ---------------------------------------------------------------- NDF and slice pictures
  let discImage = null;
  let ndfUrl = null, sliceUrl = null, discUrl = null;
  const picturePipe = pipeline(async () => {
    const m = state.material;
    const dpr = Math.min(2, window.devicePixelRatio || 1);
    const discSize = Math.round(2 * DISC.r * dpr);
    const [disc, ndf, slices] = await Promise.all([
      api('/api/ndf.png', { material: m, size: clamp(discSize, 64, 1024), style: 'disc', scale: state.ndfScale }).then((r) => r.blob()),
      api('/api/ndf.png', { material: m, size: 360, style: 'plot', scale: state.ndfScale }).then((r) => r.blob()),
      api('/api/slices.png', { material: m, width: 480, height: 320, theta_i_deg: [state.sliceTheta], planes_deg: [0, 90] }).then((r) => r.blob()),
    ]);
    const swap = (old, blob) => { if (old) URL.revokeObjectURL(old); return URL.createObjectURL(blob); };
    discUrl = swap(discUrl, disc);
    const im = new Image();
    await new Promise((res) => { im.onload = res; im.onerror = res; im.src = discUrl; });
    discImage = im;
    drawDisc();
    ndfUrl = swap(ndfUrl, ndf); $('ndf-img').src = ndfUrl;
    sliceUrl = swap(sliceUrl, slices); $('slices-img').src = sliceUrl;
  }, 40);

  function changed() {
    drawDisc();
    previewPipe();
    picturePipe();
  }
  function viewChanged() { previewPipe(); }

  // ---------------------------------------------------------------- the hemisphere disc
  const canvas = $('disc');
  const ctx = canvas.getContext('2d');
  const DISC = { cx: 160, cy: 160, r: 126 };
  function setupCanvas() {
    const dpr = Math.min(2, window.devicePixelRatio || 1);
    canvas.width = 320 * dpr; canvas.height = 320 * dpr;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  }
  // Lambert azimuthal equal-area: ρ = √2 sin(θ/2); φ from +x (right) towards +y (up).
  function axisToXY(thetaDeg, phiDeg) {
    const rho = Math.SQRT2 * Math.sin(rad(Math.min(thetaDeg, 90)) / 2);
    return [DISC.cx + DISC.r * rho * Math.cos(rad(phiDeg)), DISC.cy - DISC.r * rho * Math.sin(rad(phiDeg))];
  }
  function xyToAxis(x, y) {
    const u = (x - DISC.cx) / DISC.r, v = -(y - DISC.cy) / DISC.r;
    const rho = Math.min(1, Math.hypot(u, v));
    const theta = deg(2 * Math.asin(rho / Math.SQRT2));
    let phi = deg(Math.atan2(v, u));
    if (phi < 0) phi += 360;
    return [round(theta, 1), rho < 1e-6 ? 0 : round(phi, 1)];
  }
  function dirOf(thetaDeg, phiDeg) {
    const t = rad(thetaDeg), p = rad(phiDeg);
    return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)];
  }
  function xyOfDir(d) {
    const k = Math.sqrt(1 / (1 + Math.abs(d[2])));
    return [DISC.cx + DISC.r * d[0] * k, DISC.cy - DISC.r * d[1] * k];
  }
  // Angular half width (degrees) where a Phong peak falls to half: cos^η(α/2) = 1/2.
  const halfWidth = (eta) => (eta > 0 ? deg(2 * Math.acos(Math.pow(0.5, 1 / eta))) : 180);
  function handleRadius(l) {
    const total = lobes().reduce((a, x) => a + (x.weight || 0), 0) || 1;
    return clamp(5 + 9 * Math.sqrt((l.weight || 0) / total), 5, 14);
  }
  function drawDisc() {
    const W = 320;
    ctx.clearRect(0, 0, W, W);
    const { cx, cy, r } = DISC;
    ctx.save();
    ctx.beginPath(); ctx.arc(cx, cy, r, 0, 2 * Math.PI); ctx.clip();
    if (discImage && discImage.naturalWidth) ctx.drawImage(discImage, cx - r, cy - r, 2 * r, 2 * r);
    else { ctx.fillStyle = '#101114'; ctx.fillRect(cx - r, cy - r, 2 * r, 2 * r); }
    ctx.restore();
    // Guides: θ = 30°, 60° circles, φ spokes every 45°.
    ctx.strokeStyle = 'rgba(255,255,255,0.16)'; ctx.lineWidth = 1;
    for (const t of [30, 60]) {
      ctx.beginPath(); ctx.arc(cx, cy, r * Math.SQRT2 * Math.sin(rad(t) / 2), 0, 2 * Math.PI); ctx.stroke();
    }
    for (let p = 0; p < 360; p += 45) {
      ctx.beginPath(); ctx.moveTo(cx, cy);
      ctx.lineTo(cx + r * Math.cos(rad(p)), cy - r * Math.sin(rad(p))); ctx.stroke();
    }
    ctx.strokeStyle = '#5a5e67'; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(cx, cy, r, 0, 2 * Math.PI); ctx.stroke();
    // Labels.
    ctx.fillStyle = '#8a8d94'; ctx.font = '11px system-ui, sans-serif';
    ctx.textAlign = 'left'; ctx.textBaseline = 'middle'; ctx.fillText('0°', cx + r + 5, cy);
    ctx.textAlign = 'right'; ctx.fillText('180°', cx - r - 5, cy);
    ctx.textAlign = 'center'; ctx.textBaseline = 'bottom'; ctx.fillText('90°', cx, cy - r - 4);
    ctx.textBaseline = 'top'; ctx.fillText('270°', cx, cy + r + 4);
    ctx.fillStyle = 'rgba(255,255,255,0.38)'; ctx.font = '10px system-ui, sans-serif';
    ctx.textAlign = 'left'; ctx.textBaseline = 'top';
    for (const t of [30, 60]) {
      const rr = r * Math.SQRT2 * Math.sin(rad(t) / 2) * Math.SQRT1_2;
      ctx.fillText(`θ ${t}°`, cx + rr + 2, cy + rr + 1);
    }
    // GGX / Beckmann: the half-maximum contour of the NDF.
    if (isAnalytic()) drawHalfMaxContour();
    // Lobe extents (half-maximum rings) for Phong peaks.
    const ls = lobes();
    if (isPeaks()) {
      ls.forEach((l, i) => {
        const a = halfWidth(l.exponent || 0);
        if (a >= 170) return;
        const n = dirOf(l.axis[0], l.axis[1]);
        const t1 = Math.abs(n[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0];
        // Orthonormal basis around the axis.
        let u = [n[1] * t1[2] - n[2] * t1[1], n[2] * t1[0] - n[0] * t1[2], n[0] * t1[1] - n[1] * t1[0]];
        const ul = Math.hypot(...u); u = u.map((x) => x / ul);
        const v = [n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]];
        ctx.strokeStyle = lobeColor(i); ctx.globalAlpha = i === state.selected ? 0.9 : 0.45;
        ctx.setLineDash([3, 3]); ctx.lineWidth = 1.2; ctx.beginPath();
        let first = true;
        const ca = Math.cos(rad(a)), sa = Math.sin(rad(a));
        for (let k = 0; k <= 96; k++) {
          const b = 2 * Math.PI * k / 96;
          const d = [0, 1, 2].map((j) => n[j] * ca + sa * (Math.cos(b) * u[j] + Math.sin(b) * v[j]));
          if (d[2] < 0) { first = true; continue; }
          const [x, y] = xyOfDir(d);
          if (first) ctx.moveTo(x, y); else ctx.lineTo(x, y);
          first = false;
        }
        ctx.stroke(); ctx.setLineDash([]); ctx.globalAlpha = 1;
      });
    }
    // A texel's lobes (not editable): rings at their axes, sized by weight.
    const tx = state.texture;
    if (tx && tx.lobes && isTexel(state.material.ndf)) {
      tx.lobes.forEach((l, i) => {
        const [x, y] = axisToXY(l.axis[0], l.axis[1]);
        ctx.beginPath(); ctx.arc(x, y, clamp(4 + 9 * Math.sqrt(l.weight), 4, 13), 0, 2 * Math.PI);
        ctx.lineWidth = 2; ctx.strokeStyle = lobeColor(i); ctx.stroke();
      });
    }
    // Handles.
    ls.forEach((l, i) => {
      const [x, y] = axisToXY(l.axis[0], l.axis[1]);
      const hr = handleRadius(l);
      const below = l.axis[0] > 90;
      ctx.beginPath(); ctx.arc(x, y, hr + 2, 0, 2 * Math.PI);
      ctx.fillStyle = 'rgba(0,0,0,0.55)'; ctx.fill();
      ctx.beginPath(); ctx.arc(x, y, hr, 0, 2 * Math.PI);
      ctx.fillStyle = below ? 'transparent' : lobeColor(i); ctx.fill();
      ctx.lineWidth = i === state.selected ? 2.5 : 1.5;
      ctx.strokeStyle = i === state.selected ? '#ffffff' : 'rgba(0,0,0,0.8)';
      if (below) ctx.strokeStyle = lobeColor(i);
      ctx.stroke();
      ctx.fillStyle = '#111'; ctx.font = 'bold 10px system-ui, sans-serif';
      ctx.textAlign = 'center'; ctx.textBaseline = 'middle';
      if (!below) ctx.fillText(String(i + 1), x, y + 0.5);
    });
  }
  // Where an analytic NDF falls to half its value at the normal, per azimuth φ: with t = tan θ and
  // q = cos²φ/α_x² + sin²φ/α_y², D(θ)/D(0) is (1 + t²)² / (1 + q t²)² for GGX and
  // e^(−q t²) (1 + t²)² for Beckmann. Marched in θ, then bisected; azimuths where D stays above
  // half (α ≳ 1) leave a gap.
  function halfMaxTheta(kind, ax, ay, phi) {
    const q = Math.cos(phi) ** 2 / (ax * ax) + Math.sin(phi) ** 2 / (ay * ay);
    const ratio = (th) => {
      const t2 = Math.tan(th) ** 2;
      return kind === 'ggx' ? ((1 + t2) / (1 + q * t2)) ** 2 : Math.exp(-q * t2) * (1 + t2) ** 2;
    };
    const step = rad(0.5);
    let lo = 0;
    for (let th = step; th < rad(89.5); th += step) {
      if (ratio(th) < 0.5) {
        let hi = th;
        for (let k = 0; k < 30; k++) { const mid = 0.5 * (lo + hi); if (ratio(mid) < 0.5) hi = mid; else lo = mid; }
        return 0.5 * (lo + hi);
      }
      lo = th;
    }
    return null;
  }
  function drawHalfMaxContour() {
    const n = state.material.ndf;
    const ax = n.alpha !== undefined ? n.alpha : n.alpha_x;
    const ay = n.alpha !== undefined ? n.alpha : n.alpha_y;
    if (!(ax > 0 && ay > 0)) return;
    ctx.strokeStyle = PALETTE[0]; ctx.globalAlpha = 0.9; ctx.setLineDash([3, 3]); ctx.lineWidth = 1.2;
    ctx.beginPath();
    let first = true;
    for (let k = 0; k <= 120; k++) {
      const phi = 2 * Math.PI * k / 120;
      const th = halfMaxTheta(n.kind, ax, ay, phi);
      if (th === null) { first = true; continue; }
      const [x, y] = axisToXY(deg(th), deg(phi));
      if (first) ctx.moveTo(x, y); else ctx.lineTo(x, y);
      first = false;
    }
    ctx.stroke(); ctx.setLineDash([]); ctx.globalAlpha = 1;
  }
  function hitHandle(x, y) {
    const ls = lobes();
    for (let i = ls.length - 1; i >= 0; i--) {
      const [hx, hy] = axisToXY(ls[i].axis[0], ls[i].axis[1]);
      if (Math.hypot(x - hx, y - hy) <= handleRadius(ls[i]) + 4) return i;
    }
    return -1;
  }
  let drag = null;
  function canvasXY(e) {
    const b = canvas.getBoundingClientRect();
    return [(e.clientX - b.left) * 320 / b.width, (e.clientY - b.top) * 320 / b.height];
  }
  canvas.addEventListener('pointerdown', (e) => {
    const [x, y] = canvasXY(e);
    const i = hitHandle(x, y);
    if (i < 0) return;
    state.selected = i;
    drag = { i, id: e.pointerId };
    canvas.setPointerCapture(e.pointerId);
    highlightSelected();
    drawDisc();
    e.preventDefault();
  });
  canvas.addEventListener('pointermove', (e) => {
    const [x, y] = canvasXY(e);
    const inside = Math.hypot(x - DISC.cx, y - DISC.cy) <= DISC.r;
    if (inside) {
      const [t, p] = xyToAxis(x, y);
      $('disc-readout').textContent = `θ ${t.toFixed(1)}°  φ ${p.toFixed(1)}°`;
    } else if (!drag) $('disc-readout').textContent = '';
    canvas.style.cursor = drag ? 'grabbing' : (hitHandle(x, y) >= 0 ? 'grab' : 'crosshair');
    if (!drag) return;
    const l = lobes()[drag.i];
    l.axis = xyToAxis(x, y);
    syncLobeRow(drag.i);
    changed();
  });
  const endDrag = () => { if (drag) { drag = null; commit(); } };
  canvas.addEventListener('pointerup', endDrag);
  canvas.addEventListener('pointercancel', endDrag);
  canvas.addEventListener('dblclick', (e) => {
    const [x, y] = canvasXY(e);
    if (!isLobeKind()) return;
    if (Math.hypot(x - DISC.cx, y - DISC.cy) > DISC.r || hitHandle(x, y) >= 0) return;
    addLobe(xyToAxis(x, y));
  });
  canvas.addEventListener('wheel', (e) => {
    const [x, y] = canvasXY(e);
    if (isAnalytic()) {
      // Scroll over the disc: scale the roughness (up = smoother, as it sharpens a Phong peak).
      if (Math.hypot(x - DISC.cx, y - DISC.cy) > DISC.r) return;
      e.preventDefault();
      const n = state.material.ndf;
      const f = Math.pow(1.15, e.deltaY < 0 ? -1 : 1);
      const scale = (a) => round(clamp(a * f, 1e-4, 10), 4);
      if (n.alpha !== undefined) n.alpha = scale(n.alpha);
      else { n.alpha_x = scale(n.alpha_x); n.alpha_y = scale(n.alpha_y); }
      alphaRows.forEach((r) => r.update());
      changed();
      clearTimeout(canvas._wheelCommit); canvas._wheelCommit = setTimeout(commit, 300);
      return;
    }
    const i = hitHandle(x, y);
    if (i < 0 || !isPeaks()) return;
    e.preventDefault();
    const l = lobes()[i];
    l.exponent = round(clamp((l.exponent || 1) * Math.pow(1.15, e.deltaY < 0 ? 1 : -1), 0.5, 1e5), 2);
    state.selected = i;
    syncLobeRow(i); highlightSelected(); changed();
    clearTimeout(canvas._wheelCommit); canvas._wheelCommit = setTimeout(commit, 300);
  }, { passive: false });

  // ---------------------------------------------------------------- controls
  // A slider with a number field: spec {label, unit, min, max, step, log, get(), set(v), digits}.
  function control(spec) {
    const row = document.createElement('div');
    row.className = 'ctl';
    const lbl = document.createElement('span'); lbl.className = 'lbl'; lbl.textContent = spec.label;
    const range = document.createElement('input'); range.type = 'range';
    const num = document.createElement('input'); num.type = 'number';
    const unit = document.createElement('span'); unit.className = 'unit'; unit.textContent = spec.unit || '';
    const log = !!spec.log;
    const toSlider = (v) => (log ? Math.log10(Math.max(v, spec.min)) : v);
    const fromSlider = (s) => (log ? Math.pow(10, s) : s);
    range.min = toSlider(spec.min); range.max = toSlider(spec.max);
    range.step = log ? 0.001 : (spec.step || 0.01);
    num.step = spec.step || 'any'; num.min = spec.min; num.max = spec.max;
    const digits = spec.digits === undefined ? 2 : spec.digits;
    const show = (v) => { range.value = toSlider(v); num.value = round(v, digits); };
    show(spec.get());
    range.addEventListener('input', () => {
      const v = round(fromSlider(parseFloat(range.value)), digits);
      num.value = v; spec.set(v);
    });
    range.addEventListener('change', () => spec.commit && spec.commit());
    num.addEventListener('change', () => {
      let v = parseFloat(num.value);
      if (!isFinite(v)) { show(spec.get()); return; }
      v = clamp(v, spec.hardMin === undefined ? spec.min : spec.hardMin, spec.hardMax === undefined ? spec.max : spec.hardMax);
      show(v); spec.set(v); if (spec.commit) spec.commit();
    });
    if (spec.field) { range.dataset.field = spec.field; num.dataset.field = spec.field; }
    if (spec.lobe !== undefined) { range.dataset.lobe = spec.lobe; num.dataset.lobe = spec.lobe; }
    row.append(lbl, range, num, unit);
    row.update = () => show(spec.get());
    return row;
  }
  const materialSet = (f) => (v) => { f(v); changed(); };

  // Lobe list.
  const lobeRows = [];
  function buildLobes() {
    const box = $('lobes');
    box.textContent = '';
    lobeRows.length = 0;
    const ls = lobes();
    $('lobe-count').textContent = `(${ls.length})`;
    ls.forEach((l, i) => {
      const el = document.createElement('div');
      el.className = 'lobe'; el.dataset.lobe = i;
      const top = document.createElement('div'); top.className = 'lobe-top';
      const sw = document.createElement('span'); sw.className = 'swatch'; sw.style.background = lobeColor(i);
      const title = document.createElement('span'); title.className = 'lobe-title'; title.textContent = `#${i + 1}`;
      const angles = document.createElement('span'); angles.className = 'angles';
      const th = document.createElement('input'); th.type = 'number'; th.min = 0; th.max = 180; th.step = 0.5; th.title = 'θ: degrees from the normal';
      const ph = document.createElement('input'); ph.type = 'number'; ph.min = -360; ph.max = 720; ph.step = 1; ph.title = 'φ: degrees from the tangent towards the bitangent';
      th.dataset.field = 'theta'; ph.dataset.field = 'phi'; th.dataset.lobe = ph.dataset.lobe = i;
      th.value = l.axis[0]; ph.value = l.axis[1];
      th.addEventListener('change', () => { const v = parseFloat(th.value); if (isFinite(v)) { l.axis[0] = clamp(v, 0, 180); th.value = l.axis[0]; changed(); commit(); } });
      ph.addEventListener('change', () => { const v = parseFloat(ph.value); if (isFinite(v)) { l.axis[1] = ((v % 360) + 360) % 360; ph.value = l.axis[1]; changed(); commit(); } });
      angles.append('θ', th, '° φ', ph, '°');
      const del = document.createElement('button'); del.className = 'icon'; del.textContent = '✕'; del.title = 'Remove this lobe';
      del.disabled = ls.length <= 1;
      del.addEventListener('click', (e) => { e.stopPropagation(); removeLobe(i); });
      top.append(sw, title, angles, del);
      el.append(top);
      const w = control({ label: 'weight', unit: '', min: 0, max: 1, step: 0.001, digits: 3, hardMax: 1e6, field: 'weight', lobe: i,
        get: () => l.weight, set: materialSet((v) => { l.weight = v; }), commit });
      el.append(w);
      let ex = null;
      if (isPeaks()) {
        ex = control({ label: 'exponent η', unit: '', min: 0.5, max: 1e5, log: true, digits: 1, hardMin: 0, hardMax: 1e7, field: 'exponent', lobe: i,
          get: () => l.exponent, set: materialSet((v) => { l.exponent = v; }), commit });
        el.append(ex);
      }
      el.addEventListener('pointerdown', () => { if (state.selected !== i) { state.selected = i; highlightSelected(); drawDisc(); } });
      box.append(el);
      lobeRows.push({ el, th, ph, w, ex });
    });
    highlightSelected();
  }
  function syncLobeRow(i) {
    const r = lobeRows[i]; const l = lobes()[i];
    if (!r || !l) return;
    r.th.value = l.axis[0]; r.ph.value = l.axis[1];
    r.w.update(); if (r.ex) r.ex.update();
  }
  function highlightSelected() {
    lobeRows.forEach((r, i) => r.el.classList.toggle('selected', i === state.selected));
  }
  function addLobe(axis) {
    if (!isLobeKind()) return;
    const ls = lobes();
    if (ls.length >= 64) { showError('at most 64 lobes in the editor'); return; }
    const l = { axis: axis || [0, 0], weight: ls.length ? round(ls.reduce((a, x) => a + x.weight, 0) / ls.length, 4) : 1 };
    if (isPeaks()) l.exponent = 100;
    ls.push(l);
    state.selected = ls.length - 1;
    buildLobes(); changed(); commit();
  }
  function removeLobe(i) {
    const ls = lobes();
    if (ls.length <= 1) return;
    ls.splice(i, 1);
    state.selected = clamp(state.selected, 0, ls.length - 1);
    buildLobes(); changed(); commit();
  }

  // Transfer function.
  const CONDUCTORS = {
    aluminium: { eta: [1.657, 0.88, 0.521], k: [9.224, 6.27, 4.837] },
    gold: { eta: [0.143, 0.374, 1.442], k: [3.983, 2.385, 1.603] },
    copper: { eta: [0.2, 0.924, 1.102], k: [3.912, 2.452, 2.142] },
    silver: { eta: [0.155, 0.117, 0.138], k: [4.827, 3.122, 2.147] },
  };
  function colorRow(label, get, set) {
    const row = document.createElement('div'); row.className = 'row';
    const l = document.createElement('span'); l.className = 'lbl'; l.textContent = label;
    const c = document.createElement('input'); c.type = 'color';
    const lin = document.createElement('span'); lin.className = 'mono muted';
    const show = () => { const v = get(); c.value = linToHex(v); lin.textContent = `linear ${v.map((x) => x.toFixed(3)).join(' ')}`; };
    show();
    c.addEventListener('input', () => { set(hexToLin(c.value)); show(); changed(); });
    c.addEventListener('change', commit);
    row.append(l, c, lin);
    return row;
  }
  function selectRow(label, options, get, set) {
    const row = document.createElement('div'); row.className = 'row';
    const l = document.createElement('span'); l.className = 'lbl'; l.textContent = label;
    const s = document.createElement('select');
    for (const [v, t] of options) { const o = document.createElement('option'); o.value = v; o.textContent = t; s.append(o); }
    s.value = get();
    s.addEventListener('change', () => { set(s.value); changed(); commit(); });
    row.append(l, s);
    return row;
  }
  // The Fresnel keys of a mirror or microfacet transfer (none when absent: reflectance 1).
  const FRESNEL_KEYS = ['fresnel', 'eta', 'k', 'f0'];
  function fresnelOf(t) {
    const out = {};
    for (const key of FRESNEL_KEYS) if (t[key] !== undefined) out[key] = clone(t[key]);
    return out;
  }
  function fresnelRows(box, t) {
    box.append(selectRow('fresnel', [['none', 'none (R = 1)'], ['schlick', 'Schlick f0'], ['dielectric', 'dielectric η'], ['conductor', 'conductor η, k']],
      () => t.fresnel || 'none', (v) => {
        delete t.eta; delete t.k; delete t.f0;
        t.fresnel = v;
        if (v === 'schlick') t.f0 = [0.04, 0.04, 0.04];
        if (v === 'dielectric') t.eta = 1.5;
        if (v === 'conductor') Object.assign(t, clone(CONDUCTORS.aluminium));
        if (v === 'none') delete t.fresnel;
        buildTransfer();
      }));
    if (t.fresnel === 'schlick') box.append(colorRow('f0', () => t.f0, (v) => { t.f0 = v; }));
    if (t.fresnel === 'dielectric') {
      box.append(control({ label: 'IOR η', min: 1, max: 3, step: 0.01, digits: 3, hardMin: 0.001, hardMax: 100, field: 'eta',
        get: () => t.eta, set: materialSet((v) => { t.eta = v; }), commit }));
    }
    if (t.fresnel === 'conductor') {
      const cur = Object.keys(CONDUCTORS).find((k) => JSON.stringify(CONDUCTORS[k].eta) === JSON.stringify(t.eta)) || 'custom';
      const opts = Object.keys(CONDUCTORS).map((k) => [k, k]);
      if (cur === 'custom') opts.push(['custom', `custom η ${t.eta} k ${t.k}`]);
      box.append(selectRow('metal', opts, () => cur, (v) => { if (CONDUCTORS[v]) Object.assign(t, clone(CONDUCTORS[v])); buildTransfer(); }));
    }
  }
  // 'spec. scale': the largest specular component, the others scaled with it (a black specular
  // becomes grey). `max` bounds it: 1 for the mirror, whose specular must stay in [0, 1].
  function specularScale(t, max, hardMax) {
    return control({ label: 'spec. scale', min: 0, max, step: 0.01, digits: 3, hardMax, field: 'specular-scale',
      get: () => Math.max(...t.specular),
      set: materialSet((v) => {
        const m = Math.max(...t.specular);
        t.specular = m > 0 ? t.specular.map((c) => round(c / m * v, 4)) : [v, v, v];
      }),
      commit });
  }
  // A specular colour for a mirror: components in [0, 1], hue kept when scaled down.
  function mirrorSpecular(s) {
    if (!Array.isArray(s) || s.length !== 3 || !s.every((c) => isFinite(c))) return [1, 1, 1];
    const c = s.map((x) => Math.max(0, x));
    const m = Math.max(...c);
    return m > 1 ? c.map((x) => round(x / m, 4)) : c;
  }
  const hasContinuousNdf = () => state.material.ndf && state.material.ndf.kind !== 'deltas';
  // The mirror option of the transfer select: unavailable on a delta NDF, where a mirror facet
  // is a Dirac BRDF with no pointwise value (meso-core refuses the material).
  function syncMirrorOption() {
    const o = $('transfer-kind').querySelector('option[value="mirror"]');
    const ok = hasContinuousNdf();
    o.disabled = !ok;
    o.textContent = ok ? 'Mirror (perfect facet)' : 'Mirror — needs a continuous NDF';
    o.title = ok ? 'A perfect mirror facet scaled by specular: with the NDF, the classic microfacet BRDF'
      : 'A mirror facet on a delta NDF has no pointwise value: choose Phong peaks first';
  }
  function buildTransfer() {
    const box = $('transfer-controls'); box.textContent = '';
    const t = state.material.transfer;
    syncMirrorOption();
    $('transfer-kind').value = t.kind;
    if (t.kind === 'phong') {
      if (!t.specular) t.specular = [1, 1, 1];
      box.append(control({ label: 'exponent η', min: 1, max: 2000, log: true, digits: 1, hardMin: 0, hardMax: 1e7, field: 'transfer-exponent',
        get: () => t.exponent, set: materialSet((v) => { t.exponent = v; }), commit }));
      box.append(colorRow('specular', () => t.specular, (v) => { t.specular = v; }));
      box.append(specularScale(t, 4, 1e6));
      box.append(selectRow('variant', [['half', 'N·H (half vector)'], ['reflect', 'R·o (mirror direction)']],
        () => t.variant || 'half', (v) => { if (v === 'half') delete t.variant; else t.variant = v; }));
    } else if (t.kind === 'lambert') {
      if (!t.albedo) t.albedo = [0.8, 0.8, 0.8];
      box.append(colorRow('albedo', () => t.albedo, (v) => { t.albedo = v; }));
    } else if (t.kind === 'mirror') {
      if (!t.specular) t.specular = [1, 1, 1];
      box.append(colorRow('specular', () => t.specular, (v) => { t.specular = v; }));
      box.append(specularScale(t, 1, 1));
      fresnelRows(box, t);
      const note = document.createElement('p'); note.className = 'hint';
      note.textContent = 'specular in [0, 1] scales the mirror per channel. With form = microfacet this is the classic microfacet BRDF (reciprocal, never gains energy).';
      box.append(note);
    } else if (t.kind === 'microfacet') {
      if (t.alpha === undefined && t.alpha_x === undefined) t.alpha = 0.2;
      box.append(selectRow('distribution', [['ggx', 'GGX'], ['beckmann', 'Beckmann']], () => t.distribution || 'ggx', (v) => { t.distribution = v; }));
      box.append(control({ label: 'alpha α', min: 0.005, max: 1, log: true, digits: 4, hardMin: 1e-4, hardMax: 10, field: 'alpha',
        get: () => (t.alpha !== undefined ? t.alpha : t.alpha_x), set: materialSet((v) => { delete t.alpha_x; delete t.alpha_y; t.alpha = v; }), commit }));
      fresnelRows(box, t);
    }
  }
  function transferNote(text) {
    const p = document.createElement('p'); p.className = 'hint'; p.id = 'transfer-note'; p.textContent = text;
    $('transfer-controls').prepend(p);
  }
  $('transfer-kind').addEventListener('change', (e) => {
    const k = e.target.value;
    const old = state.material.transfer;
    if (k === 'mirror' && !hasContinuousNdf()) {
      // The option is disabled on a delta NDF; guard against scripted changes all the same.
      buildTransfer();
      transferNote('A mirror facet needs a continuous NDF (Phong peaks): on deltas it has no pointwise value.');
      return;
    }
    if (k === 'phong') state.material.transfer = { kind: 'phong', exponent: 50, specular: (old.specular || [1, 1, 1]) };
    if (k === 'lambert') state.material.transfer = { kind: 'lambert', albedo: old.albedo || [0.8, 0.8, 0.8] };
    if (k === 'mirror') state.material.transfer = Object.assign({ kind: 'mirror' }, fresnelOf(old), { specular: mirrorSpecular(old.specular) });
    if (k === 'microfacet') state.material.transfer = Object.assign({ kind: 'microfacet', distribution: 'ggx', alpha: 0.2 }, fresnelOf(old));
    buildTransfer(); syncClassicOffer(); changed(); commit();
  });

  // GGX / Beckmann: α (or α_x, α_y) instead of the lobe list, and the offer of the classic
  // microfacet BRDF while the facet is not a mirror in the microfacet form.
  const alphaRows = [];
  function buildNdfControls() {
    const analytic = isAnalytic();
    const n = state.material.ndf;
    $('lobe-section').hidden = !isLobeKind();
    $('analytic-section').hidden = !analytic;
    $('texture-section').hidden = !(isTexel(n) && state.texture);
    const other = !isLobeKind() && !analytic && !(isTexel(n) && state.texture);
    $('readonly-section').hidden = !other;
    if (other) {
      $('readonly-note').textContent = `This NDF (kind = "${n.kind}") is shown as loaded: the pictures, the preview and Save use it `
        + 'as it is; the editor edits Phong peaks, deltas, GGX and Beckmann (pick one above to start from a new NDF).';
    }
    const box = $('alpha-controls'); box.textContent = '';
    alphaRows.length = 0;
    if (!analytic) return;
    const aniso = n.alpha === undefined;
    $('ndf-aniso').checked = aniso;
    const row = (label, key, field) => {
      const r = control({ label, min: 0.005, max: 1, log: true, digits: 4, hardMin: 1e-4, hardMax: 10, field,
        get: () => n[key], set: materialSet((v) => { n[key] = v; }), commit });
      alphaRows.push(r); box.append(r);
    };
    if (aniso) { row('α_x', 'alpha_x', 'alpha-x'); row('α_y', 'alpha_y', 'alpha-y'); } else row('α', 'alpha', 'ndf-alpha');
    syncClassicOffer();
  }
  function syncClassicOffer() {
    const m = state.material;
    $('classic-offer').hidden = !isAnalytic() || (m.transfer.kind === 'mirror' && m.form === 'microfacet');
  }
  $('ndf-aniso').addEventListener('change', (e) => {
    const n = state.material.ndf;
    if (!isAnalytic(n.kind)) return;
    if (e.target.checked) {
      // The same surface to start with: α_x = α_y = α.
      const a = meanAlpha(n); delete n.alpha; n.alpha_x = a; n.alpha_y = a;
    } else {
      // Back to one α: the geometric mean keeps the area of the highlight.
      const a = round(meanAlpha(n), 4); delete n.alpha_x; delete n.alpha_y; n.alpha = a;
    }
    buildNdfControls(); changed(); commit();
  });
  $('btn-classic').addEventListener('click', () => {
    const m = state.material;
    const t = m.transfer;
    if (t.kind !== 'mirror') m.transfer = Object.assign({ kind: 'mirror' }, fresnelOf(t), { specular: mirrorSpecular(t.specular) });
    m.form = 'microfacet';
    buildAll(); changed(); commit();
  });

  function buildMaterialMisc() {
    const m = state.material;
    $('mat-name').value = m.name || '';
    // Kinds the editor shows but does not edit get an option of their own while loaded.
    const sel = $('ndf-kind');
    sel.querySelectorAll('option.loaded').forEach((o) => o.remove());
    const kind = isTexel(m.ndf) ? 'map' : m.ndf.kind;
    if (![...sel.options].some((o) => o.value === kind)) {
      const o = document.createElement('option');
      o.value = kind; o.className = 'loaded';
      o.textContent = kind === 'map' ? 'Texture texel (map)' : `${kind} (as loaded)`;
      sel.append(o);
    }
    sel.value = kind;
    $('form').value = m.form || 'multiple-surface';
    const d = m.diffuse && m.diffuse.albedo;
    $('diffuse-on').checked = !!d;
    $('diffuse-color').disabled = !d;
    $('diffuse-color').value = linToHex(d || [0.05, 0.05, 0.05]);
    $('diffuse-lin').textContent = d ? `linear ${d.map((x) => x.toFixed(3)).join(' ')}` : '';
  }
  $('mat-name').addEventListener('change', (e) => { state.material.name = e.target.value; commit(); });
  $('ndf-kind').addEventListener('change', (e) => {
    const k = e.target.value;
    const old = state.material.ndf;
    // Leaving a texture's texel closes the texture view.
    if (state.texture) closeTexture(false);
    // Remember what is left behind, for the way back (undo has it too: it is in the history).
    if (isAnalytic(old.kind)) ndfMemory.analytic = clone(old); else if (isLobeKind(old.kind)) ndfMemory.lobes = clone(old);
    if (isAnalytic(k)) {
      // GGX ↔ Beckmann keeps α; from lobes, the roughness last used (α = 0.2 the first time).
      const from = isAnalytic(old.kind) ? old : ndfMemory.analytic;
      state.material.ndf = Object.assign({ kind: k }, alphaFields(from));
    } else {
      // Between lobe kinds the lobes stay; from GGX/Beckmann, the lobes last used, or one peak
      // at the normal about as wide as the analytic NDF.
      const from = isLobeKind(old.kind) ? old.lobes
        : (ndfMemory.lobes && ndfMemory.lobes.lobes)
          || [{ axis: [0, 0], weight: 1, exponent: isAnalytic(old.kind) ? peakExponent(meanAlpha(old)) : 100 }];
      const ls = clone(from);
      for (const l of ls) {
        if (k === 'deltas') delete l.exponent; else if (l.exponent === undefined) l.exponent = 400;
      }
      state.material.ndf = { kind: k, lobes: ls };
      state.selected = clamp(state.selected, 0, ls.length - 1);
    }
    // A delta NDF under a mirror facet is degenerate (meso-core refuses it): fall back to Phong,
    // keeping the specular colour, and say so.
    const toPhong = k === 'deltas' && state.material.transfer.kind === 'mirror';
    if (toPhong) state.material.transfer = { kind: 'phong', exponent: 50, specular: mirrorSpecular(state.material.transfer.specular) };
    buildLobes(); buildNdfControls(); buildTransfer();
    if (toPhong) transferNote('A mirror facet needs a continuous NDF: the facet BRDF is now Phong (same specular colour).');
    changed(); commit();
  });
  $('form').addEventListener('change', (e) => {
    if (e.target.value === 'multiple-surface') delete state.material.form; else state.material.form = e.target.value;
    syncClassicOffer(); changed(); commit();
  });
  $('diffuse-on').addEventListener('change', (e) => {
    if (e.target.checked) state.material.diffuse = { albedo: hexToLin($('diffuse-color').value) };
    else delete state.material.diffuse;
    buildMaterialMisc(); changed(); commit();
  });
  $('diffuse-color').addEventListener('input', (e) => {
    state.material.diffuse = { albedo: hexToLin(e.target.value) };
    $('diffuse-lin').textContent = `linear ${state.material.diffuse.albedo.map((x) => x.toFixed(3)).join(' ')}`;
    changed();
  });
  $('diffuse-color').addEventListener('change', commit);

  // Lights and view.
  function buildLights() {
    const box = $('lights'); box.textContent = '';
    state.lights.forEach((l, i) => {
      const el = document.createElement('div'); el.className = 'light';
      const head = document.createElement('label'); head.className = 'light-head';
      const on = document.createElement('input'); on.type = 'checkbox'; on.checked = l.on; on.dataset.light = i;
      on.addEventListener('change', () => { l.on = on.checked; viewChanged(); });
      const dot = document.createElement('span'); dot.className = 'dot'; dot.style.background = l.dot;
      head.append(on, dot, l.name);
      el.append(head);
      const set = (f) => (v) => { f(v); viewChanged(); };
      el.append(control({ label: 'azimuth', unit: '°', min: -180, max: 180, step: 1, digits: 0, field: `light${i}-azimuth`, get: () => l.azimuth_deg, set: set((v) => { l.azimuth_deg = v; }) }));
      el.append(control({ label: 'elevation', unit: '°', min: -10, max: 90, step: 0.5, digits: 1, field: `light${i}-elevation`, get: () => l.elevation_deg, set: set((v) => { l.elevation_deg = v; }) }));
      el.append(control({ label: 'irradiance', unit: 'W/m²', min: 0, max: 12, step: 0.05, digits: 2, field: `light${i}-intensity`, get: () => l.intensity, set: set((v) => { l.intensity = v; }) }));
      box.append(el);
    });
  }
  function buildView() {
    const box = $('view-controls'); box.textContent = '';
    const v = state.view;
    const set = (f) => (x) => { f(x); viewChanged(); };
    box.append(control({ label: 'exposure', unit: 'EV', min: -6, max: 6, step: 0.1, digits: 1, field: 'exposure', get: () => v.exposure, set: set((x) => { v.exposure = x; }) }));
    box.append(control({ label: 'tangent', unit: '°', min: 0, max: 180, step: 1, digits: 0, field: 'tangent', get: () => v.tangent_deg, set: set((x) => { v.tangent_deg = x; }) }));
    const res = document.createElement('div'); res.className = 'row';
    res.innerHTML = '<span class="lbl">resolution</span>';
    const rs = document.createElement('select'); rs.id = 'resolution';
    for (const s of [256, 384, 512, 768]) { const o = document.createElement('option'); o.value = s; o.textContent = `${s} × ${s}`; rs.append(o); }
    rs.value = v.size;
    rs.addEventListener('change', () => { v.size = parseInt(rs.value, 10); lastFullMs = 0; viewChanged(); });
    const sp = document.createElement('select'); sp.id = 'spp';
    for (const s of [1, 4, 16]) { const o = document.createElement('option'); o.value = s; o.textContent = `${s} spp`; sp.append(o); }
    sp.value = v.spp;
    sp.addEventListener('change', () => { v.spp = parseInt(sp.value, 10); lastFullMs = 0; viewChanged(); });
    res.append(rs, sp);
    box.append(res);
    const note = document.createElement('p'); note.className = 'hint';
    note.textContent = 'Azimuth from the camera towards the right; elevation above the ground (the surface of the plane and cloth). 5–10° is grazing.';
    box.append(note);
  }
  document.querySelectorAll('#object-seg button').forEach((b) => b.addEventListener('click', () => {
    state.view.object = b.dataset.object;
    document.querySelectorAll('#object-seg button').forEach((x) => x.classList.toggle('on', x === b));
    lastFullMs = 0;
    viewChanged();
  }));

  // Pictures.
  $('ndf-scale').addEventListener('change', (e) => { state.ndfScale = e.target.value; picturePipe(); });
  $('slice-theta').addEventListener('input', (e) => {
    state.sliceTheta = parseInt(e.target.value, 10);
    $('slice-theta-val').textContent = `${state.sliceTheta}°`;
    picturePipe();
  });

  // ---------------------------------------------------------------- presets, open, save
  // Load a material. Every NDF kind the server validates loads: lobe lists and GGX/Beckmann are
  // edited, others (mixture, radial, …) shown as they are. A texel of a texture that is not open
  // (undo after closing it) is refused.
  function loadMaterial(m, label) {
    if (!m.ndf) m.ndf = { kind: 'deltas', lobes: [{ axis: [0, 0], weight: 1 }] };
    if (isTexel(m.ndf) && !(state.texture && state.texture.id === m.ndf.texture)) {
      showError(`${label || 'this material'}: its NDF is a texel of a texture that is not open; open the texture first`, 'file');
      return false;
    }
    if (state.texture && !isTexel(m.ndf)) closeTexture(false);
    state.material = clone(m);
    state.selected = 0;
    ndfMemory.lobes = null; ndfMemory.analytic = null;
    buildAll(); changed(); commit();
    return true;
  }
  $('preset').addEventListener('change', (e) => {
    const p = presets.find((x) => x.id === e.target.value);
    if (p && loadMaterial(p.material, p.label)) showError('', 'file');
  });
  $('btn-open').addEventListener('click', () => $('file-input').click());
  $('file-input').addEventListener('change', async (e) => {
    const f = e.target.files[0];
    if (!f) return;
    try {
      const text = await f.text();
      const r = await api('/api/parse', text);
      const m = await r.json();
      if (!m.name) m.name = f.name.replace(/\.toml$/i, '');
      if (m.ndf && (m.ndf.kind === 'heightmap' || m.ndf.kind === 'map') && !m.ndf.texture) {
        // The NDF lives in a file, which the server does not read: ask the browser for it.
        askForTexture(m, f.name);
      } else if (loadMaterial(m, f.name)) { $('preset').value = ''; showError('', 'file'); }
    } catch (err) {
      showError(`${f.name}: ${err.message}`, 'file');
    }
    e.target.value = '';
  });
  async function tomlText() {
    const r = await api('/api/toml', state.material);
    return r.text();
  }
  $('btn-save').addEventListener('click', async () => {
    try {
      const text = await tomlText();
      const blob = new Blob([text], { type: 'application/toml' });
      const a = document.createElement('a');
      a.href = URL.createObjectURL(blob);
      a.download = `${(state.material.name || 'material').replace(/[^\w.-]+/g, '_')}.toml`;
      document.body.append(a); a.click(); a.remove();
      setTimeout(() => URL.revokeObjectURL(a.href), 1000);
    } catch (err) {
      showError(`cannot save: ${err.message}`);
    }
  });
  $('btn-undo').addEventListener('click', undo);
  $('btn-redo').addEventListener('click', redo);
  $('btn-add').addEventListener('click', () => addLobe([0, 0]));
  $('btn-normalize').addEventListener('click', () => {
    const ls = lobes(); const t = ls.reduce((a, l) => a + l.weight, 0);
    if (t > 0) { ls.forEach((l) => { l.weight = round(l.weight / t, 4); }); buildLobes(); changed(); commit(); }
  });
  document.addEventListener('keydown', (e) => {
    const tag = (e.target && e.target.tagName) || '';
    if (tag === 'INPUT' && e.target.type !== 'range' && e.target.type !== 'checkbox') return;
    if ((e.ctrlKey || e.metaKey) && e.key.toLowerCase() === 'z') { e.preventDefault(); if (e.shiftKey) redo(); else undo(); }
    if ((e.ctrlKey || e.metaKey) && e.key.toLowerCase() === 'y') { e.preventDefault(); redo(); }
  });

  // Blend.
  function buildBlendOptions() {
    const s = $('blend-b'); s.textContent = '';
    for (const p of presets) { const o = document.createElement('option'); o.value = p.id; o.textContent = p.label; s.append(o); }
    s.value = 'velvet';
  }
  function blendB() { const p = presets.find((x) => x.id === $('blend-b').value); return p && p.material; }
  // Blending mixes lobe lists: A must be Phong peaks or deltas.
  function blendRefuses() {
    const refuse = !isLobeKind();
    const note = $('blend-note');
    note.hidden = !refuse;
    if (refuse) note.textContent = `Blending mixes lobe lists: A must be Phong peaks or deltas (this NDF is ${state.material.ndf.kind}).`;
    return refuse;
  }
  $('blend-set-a').addEventListener('click', () => {
    if (blendRefuses()) return;
    blend.a = clone(state.material);
    $('blend-a').textContent = blend.a.name || 'current material';
    $('blend-t').value = 0; $('blend-t-val').textContent = '0.00';
  });
  $('blend-t').addEventListener('input', (e) => {
    const t = parseFloat(e.target.value);
    $('blend-t-val').textContent = t.toFixed(2);
    if (!blend.a) {
      if (blendRefuses()) { e.target.value = 0; $('blend-t-val').textContent = '0.00'; return; }
      blend.a = clone(state.material); $('blend-a').textContent = blend.a.name || 'current material';
    }
    $('blend-note').hidden = true;
    const b = blendB();
    if (!b) return;
    const m = blendMaterials(blend.a, b, t);
    state.material = m;
    state.selected = Math.min(state.selected, m.ndf.lobes.length - 1);
    buildAll(false);
    changed();
  });
  $('blend-t').addEventListener('change', commit);
  $('blend-b').addEventListener('change', () => { $('blend-t').dispatchEvent(new Event('input')); commit(); });

  function buildAll() {
    buildMaterialMisc();
    buildLobes();
    buildNdfControls();
    buildTransfer();
    drawDisc();
    if (state.texture) drawTexture();
  }

  // ---------------------------------------------------------------- textures
  // Open texture… uploads a height map, normal map or map file (POST /api/texture; the server
  // never reads a path), then a level and texel are picked on the image (or by row and column):
  // the texel's lobes fill the table, its NDF becomes the material's (so the NDF and slice
  // pictures are the texel's), and the preview shows the object shaded through the texture's NDF
  // pyramid with the current facet BRDF (POST /api/texture/render).
  const texDialog = $('texture-dialog');
  let texFile = null;       // the file chosen for the dialog
  let texPending = null;    // a material (heightmap/map TOML) waiting for its file
  const IMAGE_EXT = /\.(png|jpe?g|tga|tiff?|exr)$/i;
  function kindOfFile(name) {
    if (/\.map$/i.test(name)) return 'map';
    return /(^|[^a-z])(normal|nrm|nor)([^a-z]|$)/i.test(name) ? 'normal' : 'height';
  }
  function syncTexDialog() {
    const k = $('tex-kind').value;
    texDialog.querySelectorAll('.tex-height').forEach((e) => { e.hidden = k !== 'height'; });
    texDialog.querySelectorAll('.tex-normal').forEach((e) => { e.hidden = k !== 'normal'; });
    texDialog.querySelectorAll('.tex-image').forEach((e) => { e.hidden = k === 'map'; });
  }
  $('tex-kind').addEventListener('change', syncTexDialog);
  function showTexDialog(file, why) {
    texFile = file;
    $('tex-file').textContent = file ? file.name : '';
    $('tex-why').hidden = !why; $('tex-why').textContent = why || '';
    $('tex-choose').hidden = !!file;
    $('tex-open').disabled = !file;
    syncTexDialog();
    if (!texDialog.open) texDialog.showModal();
  }
  // A heightmap/map material from Open…: its parameters preset, its file asked for.
  function askForTexture(m, label) {
    const n = m.ndf;
    texPending = { material: m, label };
    $('tex-kind').value = n.kind === 'map' ? 'map' : 'height';
    if (n.texel_size !== undefined) $('tex-texel-size').value = n.texel_size;
    if (n.height_scale !== undefined) $('tex-height-scale').value = n.height_scale;
    $('tex-max-lobes').value = n.max_lobes || 4;
    showTexDialog(null, `${label}: its NDF comes from "${n.file}", which the server does not read. Choose that file to open it here.`);
  }
  $('btn-texture').addEventListener('click', () => { texPending = null; $('texture-input').click(); });
  $('tex-choose').addEventListener('click', () => $('texture-input').click());
  $('texture-input').addEventListener('change', (e) => {
    const f = e.target.files[0];
    e.target.value = '';
    if (!f) return;
    if (!texPending) $('tex-kind').value = kindOfFile(f.name);
    showTexDialog(f, texPending ? $('tex-why').textContent : '');
  });
  $('tex-cancel').addEventListener('click', (e) => { e.preventDefault(); texDialog.close(); texPending = null; });
  $('tex-open').addEventListener('click', async (e) => {
    e.preventDefault();
    const f = texFile;
    if (!f) return;
    const k = $('tex-kind').value;
    const q = new URLSearchParams({ kind: k, name: f.name });
    if (k !== 'map') q.set('max_lobes', $('tex-max-lobes').value);
    if (k === 'height') { q.set('texel_size', $('tex-texel-size').value); q.set('height_scale', $('tex-height-scale').value); }
    if (k === 'normal') q.set('convention', $('tex-convention').value);
    const pend = texPending;
    if (pend && pend.material.ndf.normals) q.set('normals', pend.material.ndf.normals);
    if (pend && pend.material.ndf.border) q.set('border', pend.material.ndf.border);
    $('tex-open').disabled = true; $('tex-status').textContent = 'extracting the NDF pyramid…';
    try {
      const r = await fetch(`/api/texture?${q}`, { method: 'POST', body: f, headers: { 'content-type': 'application/octet-stream' } });
      const info = await r.json();
      if (!r.ok) throw new Error(info.error || String(r.status));
      texDialog.close();
      texPending = null;
      openTexture(info, f, pend);
      showError('', 'file');
    } catch (err) {
      showError(`${f.name}: ${err.message}`, 'file');
      texDialog.close();
    } finally {
      $('tex-open').disabled = false; $('tex-status').textContent = '';
    }
  });

  function openTexture(info, file, pend) {
    if (state.texture && state.texture.imageUrl) URL.revokeObjectURL(state.texture.imageUrl);
    const base = pend ? pend.material : state.material;
    const top = info.levels.length - 1;
    const n = pend ? pend.material.ndf : {};
    const level = Number.isInteger(n.level) ? clamp(n.level, 0, top) : top;
    const texel = Array.isArray(n.texel) ? n.texel : [0, 0];
    state.texture = { id: info.id, info, name: info.name, level, row: texel[0], col: texel[1], lobes: null, image: null, imageUrl: null,
      previousNdf: pend ? null : clone(state.material.ndf) };
    if (IMAGE_EXT.test(file.name)) {
      const url = URL.createObjectURL(file);
      const im = new Image();
      im.onload = () => { if (state.texture && state.texture.imageUrl === url) { state.texture.image = im; drawTexture(); } };
      im.src = url;
      state.texture.imageUrl = url;
    }
    const m = clone(base);
    if (pend && !m.name) m.name = pend.label.replace(/\.toml$/i, '');
    m.ndf = { kind: 'map', texture: info.id, level, texel: [state.texture.row, state.texture.col] };
    state.material = m;
    $('tex-name').textContent = info.name;
    const w = info.warnings.length ? ` · ⚠ ${info.warnings.join('; ')}` : '';
    $('tex-info').textContent = `${info.kind} · ${info.width}×${info.height} · ${info.levels.length} levels · `
      + `${info.max_lobes} lobes/texel max${info.horizon ? ' · horizon' : ''}${info.cached ? ' · from memory' : ` · ${Math.round(info.extract_ms)} ms`}${w}`;
    const sel = $('tex-level'); sel.textContent = '';
    info.levels.forEach((l) => {
      const o = document.createElement('option'); o.value = l.level;
      const res = l.residual.mean === null ? '—' : l.residual.mean.toFixed(3);
      o.textContent = `${l.level} · ${l.cols}×${l.rows} · ${l.lobes_per_texel.toFixed(2)} lobes · residual ${res}`;
      sel.append(o);
    });
    state.selected = 0;
    ndfMemory.lobes = null; ndfMemory.analytic = null;
    buildAll();
    pickTexel(level, state.texture.row, state.texture.col);
  }
  function closeTexture(restore) {
    const t = state.texture;
    if (!t) return;
    if (t.imageUrl) URL.revokeObjectURL(t.imageUrl);
    state.texture = null;
    if (restore && isTexel(state.material.ndf)) {
      state.material.ndf = t.previousNdf && !isTexel(t.previousNdf) ? t.previousNdf
        : { kind: 'phong-peaks', lobes: (t.lobes || [{ axis: [0, 0], weight: 1, exponent: 100 }]).map(clone) };
      buildAll(); changed(); commit();
    }
  }
  $('btn-texture-close').addEventListener('click', () => closeTexture(true));
  $('btn-texel-edit').addEventListener('click', () => {
    const t = state.texture;
    if (!t || !t.lobes) return;
    const ls = t.lobes.map((l) => ({ axis: l.axis.map((x) => round(x, 4)), weight: round(l.weight, 6), exponent: round(l.exponent, 4) }));
    closeTexture(false);
    state.material.ndf = { kind: 'phong-peaks', lobes: ls };
    state.material.name = `${state.material.name || 'texel'} (texel lobes)`;
    state.selected = 0;
    buildAll(); changed(); commit();
  });
  const levelInfo = () => state.texture.info.levels[state.texture.level];
  // Pick a texel: its lobes from GET /api/texture/{id}/texel, its NDF as the material's.
  async function pickTexel(level, row, col) {
    const t = state.texture;
    if (!t) return;
    const top = t.info.levels.length - 1;
    t.level = clamp(level | 0, 0, top);
    const li = levelInfo();
    t.row = clamp(row | 0, 0, li.rows - 1); t.col = clamp(col | 0, 0, li.cols - 1);
    $('tex-level').value = t.level; $('tex-row').value = t.row; $('tex-col').value = t.col;
    $('tex-row').max = li.rows - 1; $('tex-col').max = li.cols - 1;
    drawTexture();
    try {
      const r = await fetch(`/api/texture/${t.id}/texel?level=${t.level}&row=${t.row}&col=${t.col}`);
      const v = await r.json();
      if (!r.ok) throw new Error(v.error || String(r.status));
      if (state.texture !== t || v.level !== t.level || v.row !== t.row || v.col !== t.col) return;
      t.lobes = v.lobes;
      showTexelLobes(v);
      state.material.ndf = { kind: 'map', texture: t.id, level: t.level, texel: [t.row, t.col] };
      showError('', 'texture');
      changed(); commit();
    } catch (err) {
      showError(`texel: ${err.message}`, 'texture');
    }
  }
  function showTexelLobes(v) {
    const body = $('texel-lobes').querySelector('tbody'); body.textContent = '';
    v.lobes.forEach((l, i) => {
      const tr = document.createElement('tr');
      const sw = document.createElement('td');
      const dot = document.createElement('span'); dot.className = 'swatch'; dot.style.background = lobeColor(i);
      sw.append(dot, ` ${i + 1}`);
      tr.append(sw);
      const share = typeof l.share === 'number' ? `${(100 * l.share).toFixed(1)}%` : '';
      const horizon = l.horizon ? l.horizon.mean.map((a) => a.toFixed(0)).join(' ') : '—';
      for (const x of [l.axis[0].toFixed(2), l.axis[1].toFixed(2), l.weight.toFixed(4), l.exponent.toPrecision(4), share, horizon]) {
        const td = document.createElement('td'); td.textContent = x; tr.append(td);
      }
      body.append(tr);
    });
    $('texel-caption').textContent = `level ${v.level} texel [${v.row}, ${v.col}] · cells rows ${v.cells.rows[0]}–${v.cells.rows[1] - 1}, `
      + `cols ${v.cells.cols[0]}–${v.cells.cols[1] - 1} · ${v.lobes.length} lobe${v.lobes.length === 1 ? '' : 's'}`;
    $('texel-lobes').dataset.texel = `${v.level}/${v.row}/${v.col}`;
  }
  $('tex-level').addEventListener('change', (e) => {
    const t = state.texture; if (!t) return;
    // Keep the same place of the map: the texel of the new level over the old one's first cell.
    const from = levelInfo().span;
    const lv = parseInt(e.target.value, 10);
    const to = t.info.levels[lv].span;
    pickTexel(lv, Math.floor(t.row * from / to), Math.floor(t.col * from / to));
  });
  for (const id of ['tex-row', 'tex-col']) {
    $(id).addEventListener('change', () => {
      const t = state.texture; if (!t) return;
      pickTexel(t.level, parseInt($('tex-row').value, 10) || 0, parseInt($('tex-col').value, 10) || 0);
    });
  }
  // The texture canvas: the image (map row 0 is the image's bottom row, docs/heightmaps.md),
  // the level's texel grid when it is coarse enough to see, the picked texel outlined.
  const texCanvas = $('tex-canvas');
  const texCtx = texCanvas.getContext('2d');
  function texRect() {
    const t = state.texture; const l0 = t.info.levels[0];
    const W = 320; const aspect = l0.cols / l0.rows;
    const w = aspect >= 1 ? W : W * aspect; const h = aspect >= 1 ? W / aspect : W;
    return { x: (W - w) / 2, y: (W - h) / 2, w, h, cols: l0.cols, rows: l0.rows };
  }
  function drawTexture() {
    const t = state.texture;
    const dpr = Math.min(2, window.devicePixelRatio || 1);
    if (texCanvas.width !== 320 * dpr) { texCanvas.width = 320 * dpr; texCanvas.height = 320 * dpr; }
    texCtx.setTransform(dpr, 0, 0, dpr, 0, 0);
    texCtx.clearRect(0, 0, 320, 320);
    if (!t) return;
    const r = texRect();
    if (t.image) { texCtx.imageSmoothingEnabled = false; texCtx.drawImage(t.image, r.x, r.y, r.w, r.h); } else { texCtx.fillStyle = '#26282d'; texCtx.fillRect(r.x, r.y, r.w, r.h); }
    const li = levelInfo();
    const cw = r.w * li.span / r.cols; const ch = r.h * li.span / r.rows;
    if (cw >= 5 && ch >= 5) {
      texCtx.strokeStyle = 'rgba(255,255,255,0.18)'; texCtx.lineWidth = 1;
      texCtx.beginPath();
      for (let c = 1; c < li.cols; c++) { const x = r.x + c * cw; texCtx.moveTo(x, r.y); texCtx.lineTo(x, r.y + r.h); }
      for (let q = 1; q < li.rows; q++) { const y = r.y + r.h - q * ch; texCtx.moveTo(r.x, y); texCtx.lineTo(r.x + r.w, y); }
      texCtx.stroke();
    }
    const x0 = r.x + t.col * cw; const y1 = r.y + r.h - t.row * ch;
    const x1 = Math.min(r.x + r.w, x0 + cw); const y0 = Math.max(r.y, y1 - ch);
    texCtx.lineWidth = 2; texCtx.strokeStyle = '#000'; texCtx.strokeRect(x0 - 1, y0 - 1, x1 - x0 + 2, y1 - y0 + 2);
    texCtx.strokeStyle = PALETTE[0]; texCtx.strokeRect(x0, y0, x1 - x0, y1 - y0);
  }
  // Client position of the centre of a texel of a level (for tests), and the texel under a click.
  function texelCentre(level, row, col) {
    const t = state.texture; const r = texRect(); const span = t.info.levels[level].span;
    const cx = (Math.min((col + 0.5) * span, r.cols - 0.5)) / r.cols; const cy = (Math.min((row + 0.5) * span, r.rows - 0.5)) / r.rows;
    return [r.x + cx * r.w, r.y + r.h - cy * r.h];
  }
  texCanvas.addEventListener('click', (e) => {
    const t = state.texture; if (!t) return;
    const b = texCanvas.getBoundingClientRect();
    const x = (e.clientX - b.left) * 320 / b.width; const y = (e.clientY - b.top) * 320 / b.height;
    const r = texRect();
    const fx = (x - r.x) / r.w; const fy = (r.y + r.h - y) / r.h;
    if (fx < 0 || fx >= 1 || fy < 0 || fy >= 1) return;
    const span = levelInfo().span;
    pickTexel(t.level, Math.floor(Math.floor(fy * r.rows) / span), Math.floor(Math.floor(fx * r.cols) / span));
  });

  // Test and scripting hooks.
  window.mesoEditor = {
    state,
    texelClientPosition(level, row, col) {
      const [x, y] = texelCentre(level, row, col);
      const b = texCanvas.getBoundingClientRect();
      return { x: b.left + x * b.width / 320, y: b.top + y * b.height / 320 };
    },
    handleClientPosition(i) {
      const l = lobes()[i];
      const [x, y] = axisToXY(l.axis[0], l.axis[1]);
      const b = canvas.getBoundingClientRect();
      return { x: b.left + x * b.width / 320, y: b.top + y * b.height / 320 };
    },
    discClientPosition(thetaDeg, phiDeg) {
      const [x, y] = axisToXY(thetaDeg, phiDeg);
      const b = canvas.getBoundingClientRect();
      return { x: b.left + x * b.width / 320, y: b.top + y * b.height / 320 };
    },
    stats,
    tomlText,
    history,
  };

  // ---------------------------------------------------------------- start
  async function start() {
    setupCanvas();
    buildLights(); buildView(); buildAll();
    history.committed = snapshot();
    updateHistoryButtons();
    try {
      presets = await (await fetch('/api/presets')).json();
      const sel = $('preset');
      for (const p of presets) { const o = document.createElement('option'); o.value = p.id; o.textContent = p.label; o.title = p.description; sel.append(o); }
      buildBlendOptions();
      const first = presets.find((p) => p.id === 'silk') || presets[0];
      if (first) { sel.value = first.id; state.material = clone(first.material); buildAll(); history.committed = snapshot(); }
    } catch (e) {
      showError(`cannot load presets: ${e.message}`);
    }
    changed();
    document.body.dataset.ready = '1';
  }
  start();
})();
