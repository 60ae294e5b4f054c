//! A minimal KTX 2.0 container writer (and a reader for checking it): one 2-D texture, one
//! layer, one face, a full mip chain of 8-bit UNORM texels, no supercompression.
//!
//! Written by hand after the Khronos KTX 2.0 specification (no crates.io crate writes KTX2):
//! the 12-byte identifier, the header (`vkFormat`, `typeSize`, sizes, `levelCount`,
//! `supercompressionScheme = 0`), the index (DFD, key/value data, no supercompression global
//! data), the level index (level 0 first), a Basic Data Format Descriptor, the key/value pairs
//! `KTXorientation = "rd"` (rows top to bottom, texels left to right — image order, glTF's uv
//! (0, 0) at the first texel) and `KTXwriter`, then the level images from the **smallest**
//! level to the largest, each aligned to `lcm(texel block size, 4)` bytes. All integers are
//! little-endian.

use crate::ExportError;

/// The KTX 2.0 file identifier `«KTX 20»\r\n\x1A\n`.
pub const IDENTIFIER: [u8; 12] = [
    0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A,
];

/// The texel formats this writer supports (Vulkan `VkFormat` values).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `VK_FORMAT_R8_UNORM` (9): one linear channel.
    R8Unorm,
    /// `VK_FORMAT_R8G8B8A8_UNORM` (37): four linear channels (normal maps, metallicRoughness).
    Rgba8Unorm,
    /// `VK_FORMAT_R8G8B8A8_SRGB` (43): sRGB-encoded colour, linear alpha (base colour).
    Rgba8Srgb,
}

impl Format {
    /// The `VkFormat` enum value.
    #[must_use]
    pub fn vk_format(self) -> u32 {
        match self {
            Format::R8Unorm => 9,
            Format::Rgba8Unorm => 37,
            Format::Rgba8Srgb => 43,
        }
    }
    /// Bytes per texel (the texel block size).
    #[must_use]
    pub fn bytes_per_texel(self) -> usize {
        match self {
            Format::R8Unorm => 1,
            Format::Rgba8Unorm | Format::Rgba8Srgb => 4,
        }
    }
    /// The DFD transfer function: 1 = linear, 2 = sRGB.
    #[must_use]
    pub fn transfer(self) -> u8 {
        match self {
            Format::Rgba8Srgb => 2,
            _ => 1,
        }
    }
}

/// The format for a `VkFormat` value, if supported.
#[must_use]
pub fn format_from_vk(vk: u32) -> Option<Format> {
    [Format::R8Unorm, Format::Rgba8Unorm, Format::Rgba8Srgb]
        .into_iter()
        .find(|f| f.vk_format() == vk)
}

/// One mip level's texels in image order (top row first), `width × height × bytes_per_texel`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Level {
    /// Texels along x.
    pub width: u32,
    /// Texels along y.
    pub height: u32,
    /// Texel bytes, rows top to bottom.
    pub data: Vec<u8>,
}

/// A parsed texture: what [`write()`] takes and [`read`] gives back.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Texture {
    /// Texel format.
    pub format: Format,
    /// Levels, level 0 (largest) first.
    pub levels: Vec<Level>,
    /// Key/value pairs (string values, without their terminating NUL), sorted by key.
    pub key_values: Vec<(String, String)>,
}

fn align(n: usize, a: usize) -> usize {
    n.div_ceil(a) * a
}

/// The Basic Data Format Descriptor (with its leading `dfdTotalSize`) for `format`.
#[must_use]
pub fn dfd(format: Format) -> Vec<u8> {
    // RGBSDA channel ids; alpha is 15.
    let channels: &[u8] = match format {
        Format::R8Unorm => &[0],
        _ => &[0, 1, 2, 15],
    };
    let block_size = 24 + 16 * channels.len();
    let mut d = Vec::with_capacity(4 + block_size);
    d.extend_from_slice(&((4 + block_size) as u32).to_le_bytes());
    // vendorId = 0 (Khronos, 17 bits), descriptorType = 0 (basic).
    d.extend_from_slice(&0u32.to_le_bytes());
    d.extend_from_slice(&2u16.to_le_bytes()); // versionNumber (KDF 1.3)
    d.extend_from_slice(&(block_size as u16).to_le_bytes());
    // colorModel RGBSDA = 1, colorPrimaries BT.709 = 1, transferFunction, flags = 0 (straight α).
    d.extend_from_slice(&[1, 1, format.transfer(), 0]);
    d.extend_from_slice(&[0, 0, 0, 0]); // texelBlockDimension0..3 (size − 1)
    let mut planes = [0u8; 8];
    planes[0] = format.bytes_per_texel() as u8;
    d.extend_from_slice(&planes);
    for (k, &ch) in channels.iter().enumerate() {
        // Alpha of an sRGB format is linear: the LINEAR qualifier (0x10).
        let qual = if ch == 15 && format == Format::Rgba8Srgb {
            0x10
        } else {
            0
        };
        d.extend_from_slice(&((8 * k) as u16).to_le_bytes()); // bitOffset
        d.push(7); // bitLength − 1
        d.push(ch | qual);
        d.extend_from_slice(&[0, 0, 0, 0]); // samplePosition0..3
        d.extend_from_slice(&0u32.to_le_bytes()); // sampleLower
        d.extend_from_slice(&255u32.to_le_bytes()); // sampleUpper
    }
    d
}

/// Check that `levels` form a full or partial mip chain of `format` texels.
fn check_levels(format: Format, levels: &[Level]) -> Result<(), ExportError> {
    let Some(first) = levels.first() else {
        return Err(ExportError::Invalid("a KTX2 texture needs a level".into()));
    };
    if first.width == 0 || first.height == 0 {
        return Err(ExportError::Invalid(format!(
            "a {} × {} KTX2 texture is empty",
            first.width, first.height
        )));
    }
    for (k, l) in levels.iter().enumerate() {
        let (w, h) = ((first.width >> k).max(1), (first.height >> k).max(1));
        if (l.width, l.height) != (w, h) {
            return Err(ExportError::Invalid(format!(
                "KTX2 level {k} is {} × {}, expected {w} × {h}",
                l.width, l.height
            )));
        }
        if l.data.len() != w as usize * h as usize * format.bytes_per_texel() {
            return Err(ExportError::Invalid(format!(
                "KTX2 level {k} holds {} bytes, expected {}",
                l.data.len(),
                w as usize * h as usize * format.bytes_per_texel()
            )));
        }
    }
    Ok(())
}

/// Serialise a texture as a KTX 2.0 file (see the module docs for the layout).
///
/// # Errors
/// [`ExportError::Invalid`] when the levels are not a mip chain of `format` texels.
pub fn write(tex: &Texture) -> Result<Vec<u8>, ExportError> {
    check_levels(tex.format, &tex.levels)?;
    let n = tex.levels.len();
    let header_end = 12 + 9 * 4 + 4 * 4 + 2 * 8; // identifier + header + index = 80
    let level_index_end = header_end + 24 * n;
    let dfd = dfd(tex.format);
    let dfd_off = level_index_end; // already a multiple of 4
    let kvd_off = dfd_off + dfd.len();
    let mut keys = tex.key_values.clone();
    keys.sort_by(|a, b| a.0.as_bytes().cmp(b.0.as_bytes()));
    let mut kvd = Vec::new();
    for (k, v) in &keys {
        let len = k.len() + 1 + v.len() + 1;
        kvd.extend_from_slice(&(len as u32).to_le_bytes());
        kvd.extend_from_slice(k.as_bytes());
        kvd.push(0);
        kvd.extend_from_slice(v.as_bytes());
        kvd.push(0);
        kvd.resize(align(kvd.len(), 4), 0);
    }
    let align_level = lcm(tex.format.bytes_per_texel(), 4);
    let mut pos = kvd_off + kvd.len();
    // Levels are stored smallest first.
    let mut offsets = vec![0usize; n];
    for k in (0..n).rev() {
        pos = align(pos, align_level);
        offsets[k] = pos;
        pos += tex.levels[k].data.len();
    }
    let mut out = Vec::with_capacity(pos);
    out.extend_from_slice(&IDENTIFIER);
    let l0 = &tex.levels[0];
    for v in [
        tex.format.vk_format(),
        1, // typeSize: 8-bit components
        l0.width,
        l0.height,
        0, // pixelDepth
        0, // layerCount
        1, // faceCount
        n as u32,
        0, // supercompressionScheme: none
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(dfd_off as u32).to_le_bytes());
    out.extend_from_slice(&(dfd.len() as u32).to_le_bytes());
    let (ko, kl) = if kvd.is_empty() {
        (0, 0)
    } else {
        (kvd_off as u32, kvd.len() as u32)
    };
    out.extend_from_slice(&ko.to_le_bytes());
    out.extend_from_slice(&kl.to_le_bytes());
    out.extend_from_slice(&0u64.to_le_bytes()); // sgdByteOffset
    out.extend_from_slice(&0u64.to_le_bytes()); // sgdByteLength
    for (k, l) in tex.levels.iter().enumerate() {
        out.extend_from_slice(&(offsets[k] as u64).to_le_bytes());
        out.extend_from_slice(&(l.data.len() as u64).to_le_bytes());
        out.extend_from_slice(&(l.data.len() as u64).to_le_bytes());
    }
    out.extend_from_slice(&dfd);
    out.extend_from_slice(&kvd);
    for k in (0..n).rev() {
        out.resize(offsets[k], 0);
        out.extend_from_slice(&tex.levels[k].data);
    }
    Ok(out)
}

fn lcm(a: usize, b: usize) -> usize {
    let (mut x, mut y) = (a, b);
    while y != 0 {
        (x, y) = (y, x % y);
    }
    a / x * b
}

fn u32_at(b: &[u8], off: usize) -> Result<u32, ExportError> {
    b.get(off..off + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
        .ok_or_else(|| ExportError::Invalid(format!("KTX2: truncated at byte {off}")))
}

fn u64_at(b: &[u8], off: usize) -> Result<u64, ExportError> {
    let lo = u32_at(b, off)? as u64;
    let hi = u32_at(b, off + 4)? as u64;
    Ok(lo | hi << 32)
}

/// Parse a KTX 2.0 file written by [`write()`] (or any uncompressed single-face 2-D texture of a
/// supported format), checking the identifier, the header, the DFD's size and the level layout.
///
/// # Errors
/// [`ExportError::Invalid`] describing the first inconsistency.
pub fn read(bytes: &[u8]) -> Result<Texture, ExportError> {
    let bad = |m: String| ExportError::Invalid(format!("KTX2: {m}"));
    if bytes.len() < 80 || bytes[..12] != IDENTIFIER {
        return Err(bad("not a KTX 2.0 file (identifier)".into()));
    }
    let vk = u32_at(bytes, 12)?;
    let format = format_from_vk(vk).ok_or_else(|| bad(format!("unsupported vkFormat {vk}")))?;
    let (w, h) = (u32_at(bytes, 20)?, u32_at(bytes, 24)?);
    let (depth, layers, faces) = (u32_at(bytes, 28)?, u32_at(bytes, 32)?, u32_at(bytes, 36)?);
    let n = u32_at(bytes, 40)? as usize;
    let scheme = u32_at(bytes, 44)?;
    if u32_at(bytes, 16)? != 1 || depth != 0 || layers != 0 || faces != 1 || scheme != 0 {
        return Err(bad("not an uncompressed single 2-D texture".into()));
    }
    let (dfd_off, dfd_len) = (u32_at(bytes, 48)? as usize, u32_at(bytes, 52)? as usize);
    let (kvd_off, kvd_len) = (u32_at(bytes, 56)? as usize, u32_at(bytes, 60)? as usize);
    if u64_at(bytes, 72)? != 0 {
        return Err(bad("unexpected supercompression global data".into()));
    }
    let want = dfd(format);
    if dfd_off
        .checked_add(dfd_len)
        .and_then(|end| bytes.get(dfd_off..end))
        != Some(&want[..])
    {
        return Err(bad(
            "data format descriptor does not match the vkFormat".into()
        ));
    }
    let mut key_values = Vec::new();
    let kvd = kvd_off
        .checked_add(kvd_len)
        .and_then(|end| bytes.get(kvd_off..end))
        .ok_or_else(|| bad("key/value data out of range".into()))?;
    let mut p = 0;
    while p + 4 <= kvd.len() {
        let len = u32_at(kvd, p)? as usize;
        let kv = kvd
            .get(p + 4..p + 4 + len)
            .ok_or_else(|| bad("key/value pair out of range".into()))?;
        let nul = kv
            .iter()
            .position(|&c| c == 0)
            .ok_or_else(|| bad("key without NUL".into()))?;
        let key = String::from_utf8_lossy(&kv[..nul]).into_owned();
        let val = &kv[nul + 1..];
        let val = val.strip_suffix(&[0]).unwrap_or(val);
        key_values.push((key, String::from_utf8_lossy(val).into_owned()));
        p = align(p + 4 + len, 4);
    }
    // A 2-D texture of at most 2³² texels a side has at most 32 levels, and the level index
    // (24 bytes a level after the 80-byte header) must lie in the file: checked before anything
    // is allocated for the levels.
    if n == 0 || n > 32 || 80 + 24 * n > bytes.len() {
        return Err(bad(format!(
            "{n} mip levels do not fit a {w} × {h} texture in {} bytes",
            bytes.len()
        )));
    }
    let mut levels = Vec::with_capacity(n);
    for k in 0..n {
        let e = 80 + 24 * k;
        let (off, len, ulen) = (
            u64_at(bytes, e)? as usize,
            u64_at(bytes, e + 8)? as usize,
            u64_at(bytes, e + 16)? as usize,
        );
        if len != ulen || off % lcm(format.bytes_per_texel(), 4) != 0 {
            return Err(bad(format!("level {k}: misaligned or compressed")));
        }
        let data = off
            .checked_add(len)
            .and_then(|end| bytes.get(off..end))
            .ok_or_else(|| bad(format!("level {k} out of range")))?
            .to_vec();
        levels.push(Level {
            width: (w >> k).max(1),
            height: (h >> k).max(1),
            data,
        });
    }
    check_levels(format, &levels)?;
    Ok(Texture {
        format,
        levels,
        key_values,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain(format: Format, w: u32, h: u32) -> Texture {
        let bpt = format.bytes_per_texel();
        let mut levels = Vec::new();
        let (mut lw, mut lh) = (w, h);
        let mut seed = 7u32;
        loop {
            let data = (0..lw as usize * lh as usize * bpt)
                .map(|_| {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (seed >> 24) as u8
                })
                .collect();
            levels.push(Level {
                width: lw,
                height: lh,
                data,
            });
            if lw == 1 && lh == 1 {
                break;
            }
            (lw, lh) = ((lw / 2).max(1), (lh / 2).max(1));
        }
        Texture {
            format,
            levels,
            key_values: vec![
                ("KTXorientation".into(), "rd".into()),
                ("KTXwriter".into(), "meso test".into()),
            ],
        }
    }

    /// Byte layout by hand for a 2 × 1 R8 texture: header fields, DFD, KVD, levels smallest
    /// first at 4-byte alignment.
    #[test]
    fn byte_layout_by_hand() {
        let tex = Texture {
            format: Format::R8Unorm,
            levels: vec![
                Level {
                    width: 2,
                    height: 1,
                    data: vec![10, 20],
                },
                Level {
                    width: 1,
                    height: 1,
                    data: vec![30],
                },
            ],
            key_values: vec![("KTXorientation".into(), "rd".into())],
        };
        let b = write(&tex).unwrap();
        assert_eq!(&b[..12], &IDENTIFIER);
        let word = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
        assert_eq!(word(12), 9); // VK_FORMAT_R8_UNORM
        assert_eq!((word(20), word(24), word(40)), (2, 1, 2));
        // DFD right after the 2-entry level index: 80 + 48 = 128; 4 + 24 + 16 bytes.
        assert_eq!((word(48), word(52)), (128, 44));
        assert_eq!(word(128), 44);
        // KVD: 4 + "KTXorientation\0rd\0" (18) = 22, padded to 24.
        assert_eq!((word(56), word(60)), (172, 24));
        assert_eq!(word(172), 18);
        assert_eq!(&b[176..194], b"KTXorientation\0rd\0");
        // Level 1 (smallest) first at 196, then level 0 at 200.
        let l1 = u64::from_le_bytes(b[104..112].try_into().unwrap());
        let l0 = u64::from_le_bytes(b[80..88].try_into().unwrap());
        assert_eq!((l1, l0), (196, 200));
        assert_eq!(b[196], 30);
        assert_eq!(&b[200..202], &[10, 20]);
        assert_eq!(b.len(), 202);
    }

    #[test]
    fn round_trip_by_own_reader() {
        for (f, w, h) in [
            (Format::Rgba8Unorm, 16, 4),
            (Format::R8Unorm, 5, 3),
            (Format::Rgba8Srgb, 1, 1),
        ] {
            let tex = chain(f, w, h);
            let back = read(&write(&tex).unwrap()).unwrap();
            assert_eq!(back, tex);
        }
    }

    #[test]
    fn bad_chains_are_refused() {
        let mut tex = chain(Format::Rgba8Unorm, 4, 4);
        tex.levels[1].data.pop();
        assert!(write(&tex).is_err());
        let mut tex = chain(Format::Rgba8Unorm, 4, 4);
        tex.levels[1].width = 3;
        assert!(write(&tex).is_err());
        assert!(read(
            b"not a ktx file at all, not at all, no, not at all, no no no no no no no no no no"
        )
        .is_err());
    }
}

#[cfg(test)]
mod damaged {
    use super::*;

    /// A written texture cut at every length, and with a corrupt level count or level offsets:
    /// an error each time, never a panic or a huge allocation.
    #[test]
    fn truncated_and_corrupt_files_are_errors() {
        let tex = tests_chain();
        let b = write(&tex).unwrap();
        assert!(read(&b).is_ok());
        for cut in 0..b.len() {
            assert!(read(&b[..cut]).is_err(), "cut at {cut} of {}", b.len());
        }
        let set_u32 = |o: usize, v: u32| {
            let mut c = b.clone();
            c[o..o + 4].copy_from_slice(&v.to_le_bytes());
            c
        };
        for n in [0, 33, u32::MAX] {
            let e = read(&set_u32(40, n)).unwrap_err().to_string();
            assert!(e.contains("mip levels"), "{n}: {e}");
        }
        // A level whose offset + length overflows, and one past the end.
        let set_u64 = |o: usize, v: u64| {
            let mut c = b.clone();
            c[o..o + 8].copy_from_slice(&v.to_le_bytes());
            c
        };
        let mut c = set_u64(80, u64::MAX - 3);
        c[88..96].copy_from_slice(&8u64.to_le_bytes());
        c[96..104].copy_from_slice(&8u64.to_le_bytes());
        assert!(read(&c).is_err());
        assert!(read(&set_u64(80, b.len() as u64 + 4)).is_err());
        // DFD and key/value ranges that overflow.
        assert!(read(&set_u32(48, u32::MAX)).is_err());
        assert!(read(&set_u32(56, u32::MAX)).is_err());
    }

    /// An 8 × 4 RGBA8 chain with key/values (what `meso export` writes).
    fn tests_chain() -> Texture {
        let mut levels = Vec::new();
        let (mut w, mut h) = (8u32, 4u32);
        loop {
            levels.push(Level {
                width: w,
                height: h,
                data: (0..w * h * 4).map(|k| k as u8).collect(),
            });
            if w == 1 && h == 1 {
                break;
            }
            (w, h) = ((w / 2).max(1), (h / 2).max(1));
        }
        Texture {
            format: Format::Rgba8Unorm,
            levels,
            key_values: vec![("KTXorientation".into(), "rd".into())],
        }
    }
}
