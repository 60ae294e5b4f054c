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

