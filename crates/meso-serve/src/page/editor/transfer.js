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
