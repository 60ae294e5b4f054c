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

