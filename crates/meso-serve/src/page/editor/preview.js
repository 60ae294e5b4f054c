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

