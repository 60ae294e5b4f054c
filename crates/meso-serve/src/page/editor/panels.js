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

