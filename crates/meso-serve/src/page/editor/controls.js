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

