// Reads the float OpenEXR files `meso render` writes (image-rs encoder, the exr crate): single part,
// scanlines or one-level tiles, uncompressed or RLE.
function unRle(src, size) {
  const t = Buffer.alloc(size); let i = 0, o = 0;
  while (i < src.length && o < size) {
    const n = src.readInt8(i++);
    if (n < 0) { src.copy(t, o, i, i - n); o -= n; i -= n; } else { t.fill(src[i++], o, o + n + 1); o += n + 1; }
  }
  for (let k = 1; k < size; k++) t[k] = (t[k - 1] + t[k] - 128) & 0xff;   // predictor
  const out = Buffer.alloc(size); const half = (size + 1) >> 1;           // de-interleave
  for (let k = 0; k < size; k++) out[k] = k & 1 ? t[half + (k >> 1)] : t[k >> 1];
  return out;
}
export function readExr(buf) {
  if (buf.readUInt32LE(0) !== 20000630) throw new Error('not an OpenEXR file');
  let p = 8;
  const attrs = {};
  const cstr = () => { const e = buf.indexOf(0, p); const s = buf.toString('latin1', p, e); p = e + 1; return s; };
  for (;;) {
    const name = cstr();
    if (name === '') break;
    const type = cstr();
    const size = buf.readInt32LE(p); p += 4;
    attrs[name] = { type, data: buf.subarray(p, p + size) };
    p += size;
  }
  const compression = attrs.compression.data[0];
  if (compression !== 0 && compression !== 1) throw new Error(`EXR compression ${compression} not supported (only none, RLE)`);
  // channels: sorted by name, each: name\0, int32 pixel type, uint8 pLinear, 3 reserved, int32 xs, ys
  const ch = []; let q = 0; const cd = attrs.channels.data;
  while (cd[q] !== 0) {
    const e = cd.indexOf(0, q); const name = cd.toString('latin1', q, e); q = e + 1;
    ch.push({ name, type: cd.readInt32LE(q) }); q += 16;
  }
  const dw = attrs.dataWindow.data;
  const x0 = dw.readInt32LE(0), y0 = dw.readInt32LE(4), x1 = dw.readInt32LE(8), y1 = dw.readInt32LE(12);
  const W = x1 - x0 + 1, H = y1 - y0 + 1;
  const bytes = ch.map((c) => (c.type === 1 ? 2 : 4));
  if (ch.some((c) => c.type !== 2)) throw new Error('only float channels supported');
  const tiled = (buf.readUInt32LE(4) & 0x200) !== 0;
  let tw = W, th = 1;
  if (tiled) {
    const td = attrs.tiles.data;
    tw = td.readUInt32LE(0); th = td.readUInt32LE(4);
    if ((td[8] & 0x0f) !== 0) throw new Error('only one-level tiled EXR supported');
  }
  const nx = Math.ceil(W / tw), ny = Math.ceil(H / th);
  const count = tiled ? nx * ny : H;
  const offsets = [];
  for (let i = 0; i < count; i++) { offsets.push(Number(buf.readBigUInt64LE(p))); p += 8; }
  const out = {}; for (const c of ch) out[c.name] = new Float32Array(W * H);
  const px = bytes.reduce((s, b) => s + b, 0);
  for (const off of offsets) {
    let q0 = off, xs, ys;
    if (tiled) { xs = buf.readInt32LE(q0) * tw; ys = buf.readInt32LE(q0 + 4) * th; q0 += 16; } else { xs = 0; ys = buf.readInt32LE(q0) - y0; q0 += 4; }
    const size = buf.readInt32LE(q0); q0 += 4;
    const w = Math.min(tw, W - xs), h = Math.min(th, H - ys);
    const raw = w * h * px;
    const data = compression === 0 || size >= raw ? buf.subarray(q0, q0 + raw) : unRle(buf.subarray(q0, q0 + size), raw);
    let r = 0;
    for (let yy = 0; yy < h; yy++) {
      for (let k = 0; k < ch.length; k++) {
        const a = out[ch[k].name];
        for (let x = 0; x < w; x++) { a[(ys + yy) * W + xs + x] = data.readFloatLE(r); r += bytes[k]; }
      }
    }
  }
  return { width: W, height: H, channels: out };
}
