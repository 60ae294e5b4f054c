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
