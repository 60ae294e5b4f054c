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

