// Minimal PNG writer (no dependencies): 16-bit grey and 8-bit RGB, zlib from node.
import zlib from 'node:zlib';

const CRC = new Uint32Array(256).map((_, n) => {
  let c = n;
  for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});
function crc32(buf) {
  let c = 0xffffffff;
  for (const b of buf) c = CRC[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}
function chunk(type, data) {
  const len = Buffer.alloc(4); len.writeUInt32BE(data.length);
  const td = Buffer.concat([Buffer.from(type, 'ascii'), data]);
  const crc = Buffer.alloc(4); crc.writeUInt32BE(crc32(td));
  return Buffer.concat([len, td, crc]);
}
function png(width, height, bitDepth, colorType, bytesPerPixel, fill) {
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0); ihdr.writeUInt32BE(height, 4);
  ihdr[8] = bitDepth; ihdr[9] = colorType; ihdr[10] = 0; ihdr[11] = 0; ihdr[12] = 0;
  const stride = width * bytesPerPixel + 1;
  const raw = Buffer.alloc(stride * height);
  for (let r = 0; r < height; r++) fill(raw, r * stride + 1, r);   // filter byte 0
  return Buffer.concat([
    Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]),
    chunk('IHDR', ihdr), chunk('IDAT', zlib.deflateSync(raw, { level: 9 })), chunk('IEND', Buffer.alloc(0)),
  ]);
}
/** 16-bit grey PNG from codes in [0, 65535], row 0 = top row of the image. */
export function grey16(width, height, codes) {
  return png(width, height, 16, 0, 2, (buf, off, r) => {
    for (let c = 0; c < width; c++) buf.writeUInt16BE(codes[r * width + c], off + 2 * c);
  });
}
/** 8-bit RGB PNG from linear grey values: v·2^stops, clamped, sRGB-encoded; row 0 = top. */
export function srgb8(width, height, values, stops = 0) {
  const s = Math.pow(2, stops);
  const enc = (x) => {
    x = Math.min(1, Math.max(0, x * s));
    const y = x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055;
    return Math.round(255 * y);
  };
  return png(width, height, 8, 2, 3, (buf, off, r) => {
    for (let c = 0; c < width; c++) { const v = enc(values[r * width + c]); buf[off + 3 * c] = v; buf[off + 3 * c + 1] = v; buf[off + 3 * c + 2] = v; }
  });
}
