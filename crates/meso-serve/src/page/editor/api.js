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

