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
    $('tex-max-lobes').value = n.max_lobes || '';
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
    // Empty: the server's default (4, or 6 on a map of faces and walls).
    if (k !== 'map' && $('tex-max-lobes').value !== '') q.set('max_lobes', $('tex-max-lobes').value);
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
      const sh = l.residual.shading_mean == null ? '' : ` · shading error ${(100 * l.residual.shading_mean).toFixed(2)} %`;
      o.textContent = `${l.level} · ${l.cols}×${l.rows} · ${l.lobes_per_texel.toFixed(2)} lobes · residual ${res}${sh}`;
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
      const horizon = l.horizon ? l.horizon.median.map((a) => a.toFixed(0)).join(' ') : '—';
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

