//! Reading image files for height and normal maps: the header without the pixels
//! ([`probe`], [`probe_bytes`], [`ImageHeader`] with the memory estimates of loading), the size
//! limits ([`MAX_DIMENSION`], [`MAX_TEXELS`]) and decoding with those limits checked from the
//! header before anything is decoded or allocated, and against the memory budget
//! (`meso_core::budget`) for files.
//!
//! # Conventions
//! * Errors name the file (or `<memory>` for maps built in memory).
//! * Bytes without a format the content says are read as the format `name`'s extension gives,
//!   PNG when it gives none.

use crate::error::{MapError, Result};
use std::path::Path;

/// Largest accepted width or height of an image, in samples.
pub const MAX_DIMENSION: u64 = 65_536;
/// Largest accepted number of samples (width × height) of an image: 4096² (textures, and
/// height and normal maps loaded whole for an extraction in memory).
pub const MAX_TEXELS: u64 = 16_777_216;
/// Largest accepted number of samples of a height or normal map for the streamed extraction
/// (`meso extract`, [`crate::input::load_streamed`], [`crate::extract_to_file`], which never
/// holds the pyramid), of a height map built from heights already in memory
/// ([`super::HeightMap::from_heights`]), and of the map files those write: 8192². Whatever
/// then loads a whole pyramid or map file checks its memory against the budget first
/// (`Pyramid::read`), refusing with the file and the bytes needed.
pub const MAX_STREAM_TEXELS: u64 = 67_108_864;

thread_local! {
    /// The sample limit of the image decoding on this thread ([`with_texel_limit`]).
    static TEXEL_LIMIT: std::cell::Cell<u64> = const { std::cell::Cell::new(MAX_TEXELS) };
}

/// Run `f` (which decodes images on this thread) with `limit` samples accepted instead of
/// [`MAX_TEXELS`].
pub(crate) fn with_texel_limit<R>(limit: u64, f: impl FnOnce() -> R) -> R {
    let old = TEXEL_LIMIT.with(|c| c.replace(limit));
    struct Restore(u64);
    impl Drop for Restore {
        fn drop(&mut self) {
            TEXEL_LIMIT.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(old);
    f()
}

fn texel_limit() -> u64 {
    TEXEL_LIMIT.with(std::cell::Cell::get)
}

pub(super) fn check_dims(path: &Path, w: u64, h: u64) -> Result<()> {
    check_dims_within(path, w, h, texel_limit())
}

/// [`check_dims`] against `max_texels` samples.
pub(super) fn check_dims_within(path: &Path, w: u64, h: u64, max_texels: u64) -> Result<()> {
    if w == 0 || h == 0 {
        return Err(MapError::Empty {
            path: path.to_path_buf(),
            width: w,
            height: h,
        });
    }
    if w > MAX_DIMENSION || h > MAX_DIMENSION || w.saturating_mul(h) > max_texels {
        return Err(MapError::TooLarge {
            path: path.to_path_buf(),
            width: w,
            height: h,
            max_dim: MAX_DIMENSION,
            max_texels,
        });
    }
    Ok(())
}

pub(super) fn decode_err(path: &Path, e: impl std::fmt::Display) -> MapError {
    MapError::Decode {
        path: path.to_path_buf(),
        message: tidy_message(&e.to_string()),
    }
}

/// A decoder's message for ours: trimmed (the JPEG decoder's end in a blank line), and a JPEG
/// cut off in its header (the decoder's "Not enough bytes" or "No more bytes") said to be
/// truncated, the decoder's words following in parentheses.
fn tidy_message(m: &str) -> String {
    let m = m.trim();
    if m.contains("Not enough bytes") || m.contains("No more bytes") {
        format!("truncated: the file ends before its image data does ({m})")
    } else {
        m.to_string()
    }
}

/// What an image file's header says, read without decoding the pixels: enough to budget the
/// memory of loading it ([`ImageHeader::height_map_bytes`], [`ImageHeader::normal_map_bytes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageHeader {
    /// Width in pixels.
    pub width: u64,
    /// Height in pixels.
    pub height: u64,
    /// Bytes per decoded pixel (1 for 8-bit grey, 6 for 16-bit RGB, 16 for float RGBA, …).
    pub bytes_per_pixel: u64,
    /// Whether the image has colour channels.
    pub color: bool,
    /// Whether the samples are 8-bit.
    pub eight_bit: bool,
    /// Size of the file in bytes.
    pub file_bytes: u64,
}

impl ImageHeader {
    /// Number of pixels.
    #[must_use]
    pub fn pixels(&self) -> u64 {
        self.width.saturating_mul(self.height)
    }

    /// Peak memory (bytes) of loading the image as a height map
    /// ([`HeightMap::load`](super::HeightMap::load)): the file, the decoded image, the codes and
    /// heights (f64), a colour image's float conversion, and the four buffers of 8-bit
    /// dequantisation.
    #[must_use]
    pub fn height_map_bytes(&self) -> u64 {
        let per_pixel = self.bytes_per_pixel
            + 16
            + if self.color { 12 } else { 0 }
            + if self.eight_bit { 32 } else { 0 };
        self.file_bytes + self.pixels().saturating_mul(per_pixel)
    }

    /// Peak memory (bytes) of loading the image as a height map and then doing `work` bytes of
    /// work with the map held: the larger of the load's peak ([`Self::height_map_bytes`]) and
    /// the loaded map (its heights, 8 bytes a sample; the file, the decoded image and the
    /// load's buffers are freed by then) plus `work`.
    #[must_use]
    pub fn height_map_then(&self, work: u64) -> u64 {
        self.height_map_bytes()
            .max(self.pixels().saturating_mul(8).saturating_add(work))
    }

    /// Peak memory (bytes) of loading the image as a normal map
    /// ([`NormalMap::load`](super::NormalMap::load)): the file, the decoded image, its float RGB
    /// conversion and two arrays of normals (f64).
    #[must_use]
    pub fn normal_map_bytes(&self) -> u64 {
        self.file_bytes + self.pixels().saturating_mul(self.bytes_per_pixel + 12 + 48)
    }
}

/// Read an image file's header (size, sample format) without decoding its pixels, and check the
/// size limits ([`MAX_DIMENSION`], [`MAX_TEXELS`]).
///
/// # Errors
/// The file cannot be read, is not an image meso reads, or is too large.
pub fn probe(path: &Path) -> Result<ImageHeader> {
    meso_core::io::note_input(path);
    let io = |e: std::io::Error| MapError::Io {
        path: path.to_path_buf(),
        source: e,
    };
    let file_bytes = std::fs::metadata(path).map_err(io)?.len();
    let mut r = image::ImageReader::open(path).map_err(io)?;
    if r.format().is_none() {
        r.set_format(image::ImageFormat::Png);
    }
    let r = r.with_guessed_format().map_err(io)?;
    if r.format().is_none() {
        return Err(decode_err(path, "unknown image format"));
    }
    if r.format() == Some(image::ImageFormat::OpenExr) {
        let file = std::fs::File::open(path).map_err(io)?;
        if let Some(h) = exr_grey_header(path, std::io::BufReader::new(file), file_bytes)? {
            return Ok(h);
        }
    }
    let d = r.into_decoder().map_err(|e| decode_err(path, e))?;
    header_of(path, &d, file_bytes)
}

/// The header of an EXR whose first layer lacks one of R, G and B (one grey channel: `Y`, `H`,
/// `Z`, …, or `R` alone), which the `image` crate does not read: one channel (`R`, else `Y`,
/// else the first by name) is decoded as a grey `Rgb32F` image ([`decode_exr_grey`]; 12 bytes
/// a pixel, and 4 for each channel the decoder reads). `None` for an EXR with all of R, G and B (the `image` crate reads those),
/// the sizes checked.
fn exr_grey_header(
    path: &Path,
    reader: impl std::io::Read,
    file_bytes: u64,
) -> Result<Option<ImageHeader>> {
    let meta =
        exr::meta::MetaData::read_from_buffered(reader, false).map_err(|e| decode_err(path, e))?;
    let Some(layer) = meta.headers.first() else {
        return Err(decode_err(path, "no layer in the EXR file"));
    };
    let names: Vec<String> = layer
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let rgb = ["R", "G", "B"].iter().all(|c| names.iter().any(|n| n == c));
    if layer.deep || names.is_empty() || rgb {
        return Ok(None);
    }
    let (w, h) = (layer.layer_size.0 as u64, layer.layer_size.1 as u64);
    check_dims(path, w, h)?;
    Ok(Some(ImageHeader {
        width: w,
        height: h,
        // The grey RGB image and every channel decoded (4 bytes a sample).
        bytes_per_pixel: 12 + 4 * names.len() as u64,
        color: false,
        eight_bit: false,
        file_bytes,
    }))
}

/// Decode one channel of an EXR that lacks one of R, G and B ([`exr_grey_header`] says which)
/// as a grey `Rgb32F` image (the channel's value in all three), its size checked before the
/// pixels are decoded. `None` for an EXR with R, G and B.
fn decode_exr_grey(path: &Path, bytes: &[u8]) -> Result<Option<image::DynamicImage>> {
    let Some(header) = exr_grey_header(path, bytes, bytes.len() as u64)? else {
        return Ok(None);
    };
    use exr::prelude::ReadChannels as _;
    use exr::prelude::ReadLayers as _;
    let read = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| decode_err(path, e))?;
    let layer = &read.layer_data;
    let (w, h) = (layer.size.0 as u32, layer.size.1 as u32);
    if (w as u64, h as u64) != (header.width, header.height) {
        return Err(decode_err(
            path,
            "the EXR's layer size changed while reading",
        ));
    }
    // Red where there is one (an `R`-only file), else luminance, else the first by name.
    let list = &layer.channel_data.list;
    let named = |c: &str| list.iter().find(|ch| ch.name.to_string() == c);
    let Some(channel) = named("R").or_else(|| named("Y")).or_else(|| list.first()) else {
        return Err(decode_err(path, "no channel in the EXR file"));
    };
    let n = (w as usize) * (h as usize);
    let mut rgb = meso_core::budget::try_with_capacity::<f32>(3 * n).map_err(|e| oom(path, e))?;
    for v in channel.sample_data.values_as_f32().take(n) {
        rgb.extend([v, v, v]);
    }
    if rgb.len() != 3 * n {
        return Err(decode_err(
            path,
            "the EXR channel holds fewer samples than its size",
        ));
    }
    let img = image::Rgb32FImage::from_raw(w, h, rgb)
        .ok_or_else(|| decode_err(path, "the EXR channel does not match its size"))?;
    Ok(Some(image::DynamicImage::ImageRgb32F(img)))
}

/// The [`ImageHeader`] of an opened decoder (the size limits checked), for [`probe`] and
/// [`probe_bytes`].
fn header_of(path: &Path, d: &impl image::ImageDecoder, file_bytes: u64) -> Result<ImageHeader> {
    let (w, h) = d.dimensions();
    check_dims(path, w as u64, h as u64)?;
    let ct = d.color_type();
    Ok(ImageHeader {
        width: w as u64,
        height: h as u64,
        bytes_per_pixel: ct.bytes_per_pixel() as u64,
        color: ct.has_color(),
        eight_bit: ct.bytes_per_pixel() / ct.channel_count().max(1) == 1,
        file_bytes,
    })
}

/// [`probe`] for the bytes of an image file (`name` chooses the format when the content does not
/// say, and names the source in errors): the header read without decoding the pixels, the size
/// limits checked.
///
/// # Errors
/// Empty bytes, an unknown or broken header, an image above the size limits.
pub fn probe_bytes(name: &Path, bytes: &[u8]) -> Result<ImageHeader> {
    if bytes.is_empty() {
        return Err(MapError::EmptyFile {
            path: name.to_path_buf(),
        });
    }
    let mut r = image::ImageReader::new(std::io::Cursor::new(bytes));
    r.set_format(image::ImageFormat::from_path(name).unwrap_or(image::ImageFormat::Png));
    let r = r.with_guessed_format().map_err(|e| decode_err(name, e))?;
    if r.format() == Some(image::ImageFormat::OpenExr) {
        if let Some(h) = exr_grey_header(name, bytes, bytes.len() as u64)? {
            return Ok(h);
        }
    }
    let d = r.into_decoder().map_err(|e| decode_err(name, e))?;
    header_of(name, &d, bytes.len() as u64)
}

/// An allocation error of loading `path`.
pub(super) fn oom(path: &Path, e: meso_core::budget::AllocError) -> MapError {
    MapError::OutOfMemory {
        what: path.display().to_string(),
        source: e,
    }
}

/// [`decode_bytes`] after checking the memory of loading the image (`estimate` from its header)
/// against the budget (`meso_core::budget`). A regular file is probed (its header read) before
/// it is read whole; a device or FIFO, whose bytes can be read only once, is read once into
/// memory with a limit from the budget ([`crate::read::read_whole`]), then probed and decoded
/// from those bytes.
pub(super) fn open_image_budgeted(
    path: &Path,
    task: &str,
    estimate: impl Fn(&ImageHeader) -> u64,
) -> Result<image::DynamicImage> {
    // A header the probe cannot read is left to the decoder, whose errors say more.
    if crate::read::is_regular_file(path) {
        if let Ok(header) = probe(path) {
            meso_core::budget::check(path, task, estimate(&header))?;
        }
        let bytes = crate::read::read_whole(path, 1)?;
        return decode_bytes(path, &bytes);
    }
    let bytes = crate::read::read_whole(path, 1)?;
    if crate::format::has_map_magic(&bytes) {
        return Err(MapError::MapFormat {
            path: path.to_path_buf(),
            message: "this is a meso map file (written by `meso extract`), not an image".into(),
        });
    }
    if let Ok(header) = probe_bytes(path, &bytes) {
        meso_core::budget::check(path, task, estimate(&header))?;
    }
    decode_bytes(path, &bytes)
}

/// A decoder's error for messages: a read past the end of the bytes (a TGA or TIFF cut off in
/// its pixel data: the reader's "failed to fill whole buffer") says that the file is
/// truncated; other messages as [`tidy_message`] makes them.
fn decode_message(e: image::ImageError) -> String {
    match &e {
        image::ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated: the file ends before its pixel data does".into()
        }
        _ => tidy_message(&e.to_string()),
    }
}

/// True when the JPEG `bytes` hold an end-of-image marker (`FF D9`) after the start of their
/// last scan (`FF DA`): a file cut off inside its entropy-coded data has none there (within a
/// scan a data byte `FF` is always followed by `00` or a restart marker, so `FF D9` is the end).
/// Markers inside an embedded thumbnail come before the main scan and do not count; bytes after
/// the end marker are allowed.
fn jpeg_has_end(bytes: &[u8]) -> bool {
    let last_scan = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    let Some(start) = last_scan else {
        return false;
    };
    bytes[start..].windows(2).any(|w| w == [0xFF, 0xD9])
}

/// Read and decode the image file `path` as every meso input is read: its memory (`estimate`
/// from the header, for `task`) checked against the budget first, then the size limits, the
/// decoder's own limits, and a JPEG cut off inside its data refused (the decoder would fill it
/// with grey).
///
/// # Errors
/// [`MapError`] naming `path`: unreadable, empty, too large, over the memory budget, not an
/// image, truncated, or corrupt.
pub fn decode_image(
    path: &Path,
    task: &str,
    estimate: impl Fn(&ImageHeader) -> u64,
) -> Result<image::DynamicImage> {
    open_image_budgeted(path, task, estimate)
}

pub(super) fn decode_bytes(path: &Path, bytes: &[u8]) -> Result<image::DynamicImage> {
    if bytes.is_empty() {
        return Err(MapError::EmptyFile {
            path: path.to_path_buf(),
        });
    }
    // PNG: the size is in the IHDR chunk at a fixed offset; check it before the decoder reads on.
    if bytes.len() >= 24 && bytes[..8] == [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A] {
        let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap_or([0; 4]));
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap_or([0; 4]));
        check_dims(path, w as u64, h as u64)?;
    }
    let reader = || {
        let mut r = image::ImageReader::new(std::io::Cursor::new(bytes));
        r.set_format(image::ImageFormat::from_path(path).unwrap_or(image::ImageFormat::Png));
        let r = r.with_guessed_format().map_err(|e| decode_err(path, e))?;
        if r.format().is_none() {
            return Err(decode_err(path, "unknown image format"));
        }
        Ok(r)
    };
    if reader()?.format() == Some(image::ImageFormat::OpenExr) {
        if let Some(img) = decode_exr_grey(path, bytes)? {
            return Ok(img);
        }
    }
    let (w, h) = reader()?
        .into_dimensions()
        .map_err(|e| decode_err(path, e))?;
    check_dims(path, w as u64, h as u64)?;
    let mut r = reader()?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_DIMENSION as u32);
    limits.max_image_height = Some(MAX_DIMENSION as u32);
    limits.max_alloc = Some(texel_limit() * 16 + (1 << 20));
    r.limits(limits);
    if r.format() == Some(image::ImageFormat::Jpeg) && !jpeg_has_end(bytes) {
        // The decoder fills a cut-off scan with grey and reports nothing.
        return Err(decode_err(
            path,
            "truncated JPEG: no end-of-image marker after its last scan (the file is cut off)",
        ));
    }
    let img = r
        .decode()
        .map_err(|e| decode_err(path, decode_message(e)))?;
    check_dims(path, img.width() as u64, img.height() as u64)?;
    Ok(img)
}

#[cfg(test)]
mod jpeg_tests {
    use super::jpeg_has_end;

    #[test]
    fn the_end_marker_must_follow_the_last_scan() {
        // SOI, an APP1 holding a thumbnail (its own SOS … EOI), the main scan, EOI.
        let thumb = [0xFF, 0xD8, 0xFF, 0xE1, 0xFF, 0xDA, 1, 2, 0xFF, 0xD9];
        let mut whole = thumb.to_vec();
        whole.extend([0xFF, 0xDA, 7, 0xFF, 0x00, 9, 0xFF, 0xD0, 4, 0xFF, 0xD9]);
        assert!(jpeg_has_end(&whole));
        // Padding after the end marker is allowed.
        let mut padded = whole.clone();
        padded.extend([0, 0, 0]);
        assert!(jpeg_has_end(&padded));
        // Cut inside the main scan: only the thumbnail's end marker remains, before it.
        assert!(!jpeg_has_end(&whole[..whole.len() - 3]));
        // No scan at all.
        assert!(!jpeg_has_end(&[0xFF, 0xD8, 0xFF, 0xD9]));
    }
}
