//! The map file: a versioned little-endian binary serialisation of a [`Pyramid`]
//! (documented in `docs/map-format.md`). Every size is validated against the limits and the
//! file length before anything is allocated.

use crate::error::{MapError, Result};
use crate::facets::NormalMode;
use crate::fit::{ETA_MAX, MAX_LOBES};
use crate::heightmap::{Border, MAX_DIMENSION, MAX_STREAM_TEXELS};
use crate::horizon::HorizonStats;
use crate::pyramid::{level_count, Level, Pyramid, Residual};
use glam::DVec3;
use meso_core::ndf::PhongLobe;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The 8 magic bytes opening every map file.
pub const MAGIC: [u8; 8] = *b"MESOMAP\0";

/// Whether the file at `path` opens with [`MAGIC`]: a map file written by `meso extract`, given
/// where an image or a material is expected (the callers' messages say what to do instead).
/// Unreadable or shorter files are not map files, nor are non-regular files (a FIFO's bytes can
/// be read only once: whoever reads it whole checks them with [`has_map_magic`]).
#[must_use]
pub fn is_map_file(path: &std::path::Path) -> bool {
    use std::io::Read;
    if !crate::read::is_regular_file(path) {
        return false;
    }
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok_and(|()| magic == MAGIC)
}

/// Whether `bytes` open with [`MAGIC`] ([`is_map_file`] for bytes already read).
#[must_use]
pub fn has_map_magic(bytes: &[u8]) -> bool {
    bytes.starts_with(&MAGIC)
}
mod lazy;
mod v3;
mod v4;

pub use lazy::{LazyLevel, LazyLobes};
pub(crate) use v3::{
    angle_decode, angle_encode, eta_decode, eta_encode, oct_decode, oct_encode, MEAN_SPAN, SD_SPAN,
};
pub use v3::{MAX_DEFLATE_RATIO, SHADING_TAG};
pub(crate) use v4::{check_band, write_band, write_level_end};
pub use v4::{BAND_ROWS, VERSION_4, VERSION_5};

/// The format version written by this build: 5 ([`VERSION_5`], `docs/map-format.md`): version
/// 3's quantised, deflated streams per band of [`BAND_ROWS`] rows, then each level's end record
/// ([`Pyramid::write`], [`Pyramid::to_bytes`], the pyramid cache and the streamed extraction,
/// [`crate::pyramid::extract_to_file`], all write it), with the horizon statistics of eight
/// azimuths. Versions 2 (uncompressed `f32`), [`VERSION_3`] and [`VERSION_4`] (four azimuths:
/// the diagonals are filled in from the axes, [`crate::HorizonStats::from_axes`]) are read;
/// version 1 stored projected-area lobe weights and is refused.
pub const VERSION: u32 = VERSION_5;
/// Version 3 (quantised and compressed, one set of streams for the whole pyramid): read, no
/// longer written.
pub const VERSION_3: u32 = v3::VERSION_3;
/// Version 2 (uncompressed `f32`): read, no longer written.
pub const VERSION_2: u32 = 2;
const LOBE_BYTES: u64 = 20;
const HORIZON_BYTES: u64 = 36;
/// Bytes of a level's header (v2) or level-table entry (v3).
const LEVEL_HEADER_BYTES: u64 = 36;

fn put_u32(w: &mut dyn Write, v: u32) -> std::io::Result<()> {
    w.write_all(&v.to_le_bytes())
}
fn put_f64(w: &mut dyn Write, v: f64) -> std::io::Result<()> {
    w.write_all(&v.to_le_bytes())
}

/// The size of the file at `path` and, for a non-empty regular file, the file mapped read-only
/// (`None` for an empty file, a device or a FIFO, which are read as a stream instead).
///
/// # Errors
/// [`MapError::Io`] naming `path` when it cannot be opened, examined or mapped.
fn map_regular(path: &Path) -> Result<(u64, Option<lazy::MappedFile>)> {
    let io = |e| MapError::Io {
        path: path.to_path_buf(),
        source: e,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() || meta.len() == 0 {
        return Ok((meta.len(), None));
    }
    // SAFETY: a read-only mapping of the file. A file truncated by another process while
    // mapped would fault where its cut pages are read; map files are replaced by renaming
    // (`meso_core::io::write_atomic`), which leaves a mapped file whole, and a level read by
    // band later checks the file's length before it reads a band again
    // (`lazy::MappedFile::cut`).
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(io)?;
    Ok((meta.len(), Some(lazy::MappedFile::new(map, file))))
}

/// What reading a map file compactly will need ([`Pyramid::read_compact_bytes`]), from its
/// headers alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadNeed {
    /// The memory (bytes) [`Pyramid::read_compact`] checks against the budget.
    pub bytes: u64,
    /// The header's largest number of lobes per texel (`max_lobes` of the extraction).
    pub max_lobes: usize,
}

/// The estimated peak memory (bytes) of reading a map file of `file_bytes` bytes, before its
/// header is read: for version 2 the file itself and the pyramid, whose lobes (20 bytes in the
/// file, 40 in memory) and horizon statistics (36 and 72) take twice their file size: 3× the
/// file, measured 3.0× (`meso map info` on a 120 MB map: 359 MB peak RSS), estimated 4× for a
/// margin. A version-3 or version-4 file inflates to more than this; its exact need (pyramid
/// and streams, from the level table or the level end records) is checked against the budget
/// by [`Pyramid::from_bytes`] before any stream is inflated.
#[must_use]
pub fn read_bytes(file_bytes: u64) -> u64 {
    file_bytes.saturating_mul(4)
}

impl Pyramid {
    /// Serialise into a writer in the current format ([`VERSION`] 5, `docs/map-format.md`):
    /// lobes and horizon statistics quantised to 16 bits and deflated, per band of
    /// [`BAND_ROWS`] rows of each level, then the level's end record; the bytes the streamed
    /// extraction ([`crate::pyramid::extract_to_file`]) writes for the same pyramid.
    ///
    /// # Errors
    /// The writer's errors, and `InvalidData` naming the problem when the pyramid holds a value
    /// a map file cannot (non-finite or out-of-range lobes or horizon statistics).
    pub fn write_to(&self, w: &mut dyn Write) -> std::io::Result<()> {
        if let Some(why) = v3::unstorable(self) {
            return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, why));
        }
        Header {
            version: VERSION,
            width: self.width,
            height: self.height,
            cols: self.levels[0].cols,
            rows: self.levels[0].rows,
            texel_size: self.texel_size,
            border: self.border,
            normal_mode: self.normal_mode,
            has_h: self.levels[0].horizon.is_some(),
            max_lobes: self.max_lobes,
            nlev: self.levels.len(),
        }
        .write(w)?;
        v4::write_levels(self, w)
    }

    /// The map file as bytes ([`Pyramid::write_to`]); empty when the pyramid holds a value a
    /// map file cannot, which every reader refuses.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        if self.write_to(&mut v).is_err() {
            v.clear();
        }
        v
    }

    /// Write the map file ([`Pyramid::write_to`]: the bytes `meso extract` writes for the same
    /// pyramid) atomically (`meso_core::io::write_atomic`): on error no partial file is left.
    /// The pyramid is checked first and the bytes are validated by the reader
    /// ([`Pyramid::check_bytes`]), so a written map always reads back (a pyramid with NaN lobes,
    /// say from an extreme height scale, is refused here rather than written).
    ///
    /// # Errors
    /// `MapError::MapFormat` ("not written: …") for a pyramid a map file cannot hold, and
    /// `MapError::Write` when the file cannot be written.
    pub fn write(&self, path: &Path) -> Result<()> {
        let invalid = |why: String| MapError::MapFormat {
            path: path.to_path_buf(),
            message: format!("not written: the map would be invalid ({why})"),
        };
        // `write_to` checks the pyramid first (`InvalidData` naming the value).
        let mut bytes = Vec::new();
        let wrote = self.write_to(&mut bytes);
        // A level held by band whose file changed in place meanwhile: not its values (said
        // first: the blank band read instead may also fail the checks below).
        self.check_mapped()?;
        wrote.map_err(|e| invalid(e.to_string()))?;
        if let Err(e) = Pyramid::check_bytes(path, &bytes) {
            return Err(invalid(match e {
                MapError::MapFormat { message, .. } => message,
                e => e.to_string(),
            }));
        }
        meso_core::io::write_atomic(path, &bytes).map_err(|e| MapError::Write {
            path: path.to_path_buf(),
            source: e,
        })
    }

    /// Read a map file, validating magic, version, sizes (before allocating) and every value.
    /// A regular file's memory ([`read_bytes`] of its size) is checked against the budget before
    /// it is read; a device or FIFO is read once with a limit from the budget
    /// ([`crate::read::read_whole`]).
    ///
    /// # Errors
    /// [`MapError`] naming `path`: unreadable, over the memory budget, or not a valid map file.
    pub fn read(path: &Path) -> Result<Pyramid> {
        meso_core::io::note_input(path);
        if let Ok(m) = std::fs::metadata(path) {
            if m.is_file() {
                meso_core::budget::check(path, "reading the map file", read_bytes(m.len()))?;
            }
        }
        let bytes = crate::read::read_whole(path, read_bytes(1))?;
        Pyramid::from_bytes(path, &bytes)
    }

    /// [`Pyramid::read`] keeping the compact levels (those of at least
    /// [`crate::COMPACT_TEXELS`] texels) of a format-4 file as the file codes them
    /// ([`crate::Lobes::Coded`], 11 bytes a lobe; [`crate::Horizons::Coded`], 16 bytes a texel,
    /// against 20 and 36 in `f32`), which read back as the very values [`Pyramid::read`] gives
    /// (each `Lobes::get` and `Horizons::get` decodes one). On unix the file is mapped and its
    /// pages handed back band by band as they are read, so the memory is the coded pyramid and
    /// one band (a 4096² height map: 1.04 GB, where [`Pyramid::read`] holds 1.97 GB and the
    /// 0.5 GB file); checked against the budget before anything is inflated. Other versions
    /// are read as [`Pyramid::read`] does. How `meso render` holds a map file's pyramid when
    /// it takes at most half the budget ([`Pyramid::read_compact`]).
    ///
    /// # Errors
    /// As [`Pyramid::read`].
    pub fn read_coded(path: &Path) -> Result<Pyramid> {
        Pyramid::read_mapped(path, v4::Mode::Coded, &mut |_| {})
    }

    /// [`Pyramid::read_coded`] with level 0, when compact (at least
    /// [`crate::COMPACT_TEXELS`] texels), held by band in the mapped file
    /// ([`crate::Lobes::Lazy`], [`crate::Horizons::Lazy`], [`LazyLevel`]): every band is
    /// inflated, decoded and checked when the file is read, as [`Pyramid::read_coded`] does,
    /// then dropped, its place kept; a band is decoded again when something first reads one of
    /// its lobes or texels, under a small cache of decoded bands (8, at least the threads + 2,
    /// and each thread's last two). The values read are [`Pyramid::read_coded`]'s, bit for bit.
    /// The memory is level 0's lobe starts (4 bytes a texel), the cached bands and the other
    /// levels coded (an 8192² height map: ≈ 1.6 GB, where [`Pyramid::read_coded`] holds
    /// ≈ 4.2 GB); checked against the budget before anything is inflated. How `meso render`
    /// holds a map file's pyramid when the coded one would take more than half the budget
    /// ([`Pyramid::read_compact`]). Other versions are read as [`Pyramid::read`] does.
    ///
    /// # Errors
    /// As [`Pyramid::read`]; a corrupt band is found when the file is read, not when the band
    /// is first read again.
    pub fn read_lazy(path: &Path) -> Result<Pyramid> {
        Pyramid::read_mapped(path, v4::Mode::Lazy, &mut |_| {})
    }

    /// Whether every band of a level held by band ([`Pyramid::read_lazy`]) has decoded again
    /// when read: `Err` naming the file when one did not (the file changed in place while in
    /// use, after reading checked it; its lobes read as zero-weight, [`LazyLevel::check`]).
    /// Always `Ok` for a pyramid held in memory. What a reader of such a pyramid checks
    /// before it writes anything made from it.
    ///
    /// # Errors
    /// [`MapError::MapFormat`] naming the file, the level and the band.
    pub fn check_mapped(&self) -> Result<()> {
        for l in &self.levels {
            if let crate::Lobes::Lazy(z) = &l.lobes {
                z.check()?;
            }
            if let Some(crate::Horizons::Lazy(z)) = &l.horizon {
                z.check()?;
            }
        }
        Ok(())
    }

    /// The pyramid held as compactly as the memory budget asks: [`Pyramid::read_coded`], or
    /// [`Pyramid::read_lazy`] when the coded pyramid would take more than half the memory
    /// budget ([`meso_core::budget`]; the other half is left to what is built from it, e.g.
    /// `meso render`'s tables) and holding level 0 by band needs less (on a small map its cache
    /// of decoded bands can be all of level 0 and more). Level 0 held by band costs CPU
    /// where a view reads much of it (measured, far view of a 4096² map: 41.6 s user CPU
    /// against 32.4 s coded; docs/benchmarks.md), so it is taken only where the memory asks
    /// for it: under the default budget (4 GiB) a 4096² map is read coded (1.02 GiB peak) and
    /// an 8192² map lazily (2.05 GiB). What `meso render` and `meso map info` read a map file
    /// with.
    ///
    /// # Errors
    /// As [`Pyramid::read`].
    pub fn read_compact(path: &Path) -> Result<Pyramid> {
        Pyramid::read_mapped(path, v4::Mode::Auto, &mut |_| {})
    }

    /// What [`Pyramid::read_compact`] of the file at `path` will need, found without reading
    /// the levels ([`ReadNeed`]): the memory it checks against the budget before it inflates
    /// anything (for a format-4 file from its chunks' headers: the pyramid coded, or level 0
    /// by band where the budget asks for it, and one band being decoded; for an older version,
    /// an empty file or one that is not a regular file, [`read_bytes`] of its size) and the
    /// header's largest number of lobes per texel. What a command that reads a map file
    /// besides its own work (`meso export --lobes`) adds to its estimate before it starts. A
    /// file whose header or chunks cannot be read gets [`read_bytes`] of its size and
    /// [`crate::fit::MAX_LOBES`]: reading it reports the problem.
    ///
    /// # Errors
    /// [`MapError::Io`] when the file cannot be opened or mapped.
    pub fn read_compact_bytes(path: &Path) -> Result<ReadNeed> {
        let (size, map) = map_regular(path)?;
        let fallback = ReadNeed {
            bytes: read_bytes(size),
            max_lobes: crate::fit::MAX_LOBES,
        };
        let Some(map) = map else {
            return Ok(fallback);
        };
        let mut r = Reader::new(&map.map, path);
        r.mapped = Some(&map);
        let Ok(h) = read_header(&mut r) else {
            return Ok(fallback);
        };
        let bytes = if h.version >= VERSION_4 {
            v4::auto_need(&mut r, &h).unwrap_or(fallback.bytes)
        } else {
            fallback.bytes
        };
        Ok(ReadNeed {
            bytes,
            max_lobes: h.max_lobes.clamp(1, crate::fit::MAX_LOBES),
        })
    }

    /// [`Pyramid::read_compact`], reporting to `report` as it reads a format-4 file
    /// ([`crate::ProgressTask::Read`]: before the first band, after each band and each level;
    /// `work_done` counts bytes of the levels read and checked, up to `work_total`). Files of
    /// other versions are read without reports. Reading an 8192² map file takes ≈ 20 s.
    ///
    /// # Errors
    /// As [`Pyramid::read`].
    pub fn read_compact_reporting(
        path: &Path,
        report: &mut dyn FnMut(crate::pyramid::Progress),
    ) -> Result<Pyramid> {
        Pyramid::read_mapped(path, v4::Mode::Auto, report)
    }

    /// [`Pyramid::read_coded`] (`mode` [`v4::Mode::Coded`]), [`Pyramid::read_lazy`]
    /// ([`v4::Mode::Lazy`]) or [`Pyramid::read_compact`] ([`v4::Mode::Auto`]), reporting the
    /// reading of a format-4 file's levels to `report`.
    fn read_mapped(
        path: &Path,
        mode: v4::Mode,
        report: &mut dyn FnMut(crate::pyramid::Progress),
    ) -> Result<Pyramid> {
        meso_core::io::note_input(path);
        let Some(map) = map_regular(path)?.1 else {
            // Its error for an empty file; a device or FIFO read once, with a limit.
            return Pyramid::read(path);
        };
        let map = std::sync::Arc::new(map);
        let mut r = Reader::new(&map.map, path);
        r.mapped = Some(&map);
        let h = read_header(&mut r)?;
        if h.version < VERSION_4 {
            return Pyramid::read(path);
        }
        let levels = v4::read_levels(&mut r, &h, mode, Some(&map), report)?;
        if r.pos != r.b.len() {
            return Err(r.err(format!("{} unexpected trailing bytes", r.b.len() - r.pos)));
        }
        Ok(h.into_pyramid(levels))
    }

    /// Parse a map file from bytes; `path` only names the source in errors.
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Pyramid> {
        let mut r = Reader::new(bytes, path);
        let h = read_header(&mut r)?;
        let levels = if h.version >= VERSION_4 {
            v4::read_levels(&mut r, &h, v4::Mode::Full, None, &mut |_| {})?
        } else if h.version == VERSION_3 {
            let mut levels = v3::read_levels(&mut r, &h)?;
            if let Some(sh) = v3::read_shading(&mut r, h.nlev)? {
                for (l, (m, x)) in levels.iter_mut().zip(sh) {
                    l.residual.shading_mean = Some(m);
                    l.residual.shading_max = Some(x);
                }
            }
            levels
        } else {
            read_levels_v2(&mut r, &h)?
        };
        if r.pos != r.b.len() {
            return Err(r.err(format!("{} unexpected trailing bytes", r.b.len() - r.pos)));
        }
        Ok(h.into_pyramid(levels))
    }

    /// Check a map file's bytes as [`Pyramid::from_bytes`] does — every check, the same
    /// errors — without building the pyramid: a format-3 or format-4 file's streams are inflated
    /// and decoded one at a time (format 4: one band at a time) and dropped (what
    /// [`Pyramid::write`] runs on the bytes it is about to write, at a fraction of a second
    /// pyramid's memory).
    ///
    /// # Errors
    /// As [`Pyramid::from_bytes`].
    pub fn check_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
        let mut r = Reader::new(bytes, path);
        let h = read_header(&mut r)?;
        if h.version >= VERSION_4 {
            v4::read_levels(&mut r, &h, v4::Mode::Check, None, &mut |_| {})?;
        } else if h.version == VERSION_3 {
            v3::check_levels(&mut r, &h)?;
            v3::read_shading(&mut r, h.nlev)?;
        } else {
            read_levels_v2(&mut r, &h)?;
        }
        if r.pos != r.b.len() {
            return Err(r.err(format!("{} unexpected trailing bytes", r.b.len() - r.pos)));
        }
        Ok(())
    }
}

/// The common header of every version, checked when read.
#[derive(Clone, Debug)]
pub(crate) struct Header {
    pub(crate) version: u32,
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) cols: usize,
    pub(crate) rows: usize,
    pub(crate) texel_size: f64,
    pub(crate) border: Border,
    pub(crate) normal_mode: NormalMode,
    pub(crate) has_h: bool,
    pub(crate) max_lobes: usize,
    pub(crate) nlev: usize,
}

impl Header {
    /// The pyramid of these dimensions and settings with `levels`.
    pub(crate) fn into_pyramid(self, levels: Vec<Level>) -> Pyramid {
        Pyramid {
            width: self.width,
            height: self.height,
            texel_size: self.texel_size,
            border: self.border,
            normal_mode: self.normal_mode,
            max_lobes: self.max_lobes,
            levels,
        }
    }

    /// The 48 bytes of the header.
    pub(crate) fn write(&self, w: &mut dyn Write) -> std::io::Result<()> {
        w.write_all(&MAGIC)?;
        put_u32(w, self.version)?;
        put_u32(w, self.width as u32)?;
        put_u32(w, self.height as u32)?;
        put_u32(w, self.cols as u32)?;
        put_u32(w, self.rows as u32)?;
        put_f64(w, self.texel_size)?;
        w.write_all(&[
            match self.border {
                Border::Wrap => 0,
                Border::Clamp => 1,
            },
            match self.normal_mode {
                NormalMode::Triangles => 0,
                NormalMode::CentralDifferences => 1,
            },
            u8::from(self.has_h),
            0,
        ])?;
        put_u32(w, self.max_lobes as u32)?;
        put_u32(w, self.nlev as u32)
    }
}

/// Read and check the common header (magic, version, sizes, flags, `max_lobes`, level count).
/// The sizes `(width, height, cols, rows)` that a map file's header declares: samples of the
/// height map and level-0 cells, read from the file's first 28 bytes and checked as when the
/// file is read (magic, version, limits), without reading its levels. A map given where only
/// its grid matters (`meso export --lobes`) is checked by it before any work.
///
/// # Errors
/// [`MapError::Io`] when the file cannot be read; [`MapError::MapFormat`] /
/// [`MapError::MapVersion`] as [`Pyramid::read`] gives them for its header.
pub fn peek_sizes(path: &Path) -> Result<(usize, usize, usize, usize)> {
    use std::io::Read;
    meso_core::io::note_input(path);
    let mut bytes = Vec::with_capacity(28);
    std::fs::File::open(path)
        .and_then(|f| f.take(28).read_to_end(&mut bytes))
        .map_err(|e| MapError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
    let mut r = Reader::new(&bytes, path);
    let (_, width, height, cols, rows) = read_sizes(&mut r)?;
    Ok((width, height, cols, rows))
}

/// The header's first fields, checked: magic, version, then samples `width × height` and
/// level-0 cells `cols × rows`.
fn read_sizes(r: &mut Reader<'_>) -> Result<(u32, usize, usize, usize, usize)> {
    let magic = r.take(8, "magic")?;
    if magic != MAGIC {
        return Err(r.err("not a meso map file (bad magic bytes)".into()));
    }
    let version = r.u32("version")?;
    if ![VERSION_2, VERSION_3, VERSION_4, VERSION_5].contains(&version) {
        return Err(MapError::MapVersion {
            path: r.path.clone(),
            found: version,
            expected: VERSION,
        });
    }
    let width = r.u32("width")? as usize;
    let height = r.u32("height")? as usize;
    let cols = r.u32("cols")? as usize;
    let rows = r.u32("rows")? as usize;
    for (name, v) in [
        ("width", width),
        ("height", height),
        ("cols", cols),
        ("rows", rows),
    ] {
        if v == 0 || v as u64 > MAX_DIMENSION {
            return Err(r.err(format!("{name} = {v} outside 1..={MAX_DIMENSION}")));
        }
    }
    if (width as u64) * (height as u64) > MAX_STREAM_TEXELS || cols > width || rows > height {
        return Err(r.err(format!(
            "sizes {width}x{height} samples / {cols}x{rows} cells exceed the limits"
        )));
    }
    Ok((version, width, height, cols, rows))
}

fn read_header(r: &mut Reader<'_>) -> Result<Header> {
    let (version, width, height, cols, rows) = read_sizes(r)?;
    let texel_size = r.f64("texel_size")?;
    if !(texel_size.is_finite() && texel_size > 0.0) {
        return Err(r.err(format!("texel_size {texel_size} is not > 0")));
    }
    let flags = r.take(4, "flags")?;
    let border = match flags[0] {
        0 => Border::Wrap,
        1 => Border::Clamp,
        b => return Err(r.err(format!("unknown border code {b}"))),
    };
    let normal_mode = match flags[1] {
        0 => NormalMode::Triangles,
        1 => NormalMode::CentralDifferences,
        b => return Err(r.err(format!("unknown normal mode code {b}"))),
    };
    let has_h = match flags[2] {
        0 => false,
        1 => true,
        b => return Err(r.err(format!("bad horizon flag {b}"))),
    };
    let max_lobes = r.u32("max_lobes")? as usize;
    if max_lobes == 0 || max_lobes > MAX_LOBES {
        return Err(r.err(format!("max_lobes {max_lobes} outside 1..={MAX_LOBES}")));
    }
    let nlev = r.u32("level count")? as usize;
    let expect = level_count(cols, rows);
    if nlev != expect {
        return Err(r.err(format!(
            "{nlev} levels, but a {cols}x{rows} grid has {expect}"
        )));
    }
    Ok(Header {
        version,
        width,
        height,
        cols,
        rows,
        texel_size,
        border,
        normal_mode,
        has_h,
        max_lobes,
        nlev,
    })
}

/// The levels of a version-2 file, after the common header `h`.
fn read_levels_v2(r: &mut Reader<'_>, h: &Header) -> Result<Vec<Level>> {
    let (cols, rows, nlev, max_lobes, has_h) = (h.cols, h.rows, h.nlev, h.max_lobes, h.has_h);
    let mut levels = Vec::with_capacity(nlev);
    let (mut ec, mut er) = (cols, rows);
    for k in 0..nlev {
        let nl = r.level_header(k, ec, er, max_lobes)?;
        let (lc, lr, span) = (ec, er, 1usize << k);
        let texels = lc * lr;
        let need = texels as u64
            + nl as u64 * LOBE_BYTES
            + if has_h {
                texels as u64 * HORIZON_BYTES
            } else {
                0
            }
            + LEVEL_HEADER_BYTES
            - 16;
        if ((r.b.len() - r.pos) as u64) < need {
            return Err(r.err(format!("truncated in level {k}")));
        }
        let residual = r.residual()?;
        let counts = r.take(texels, "lobe counts")?;
        let mut lobe_start = Vec::with_capacity(texels + 1);
        lobe_start.push(0u32);
        let mut sum = 0usize;
        for &c in counts {
            if c as usize > max_lobes {
                return Err(r.err(format!("level {k}: a texel has {c} lobes")));
            }
            sum += c as usize;
            lobe_start.push(sum as u32);
        }
        if sum != nl {
            return Err(r.err(format!(
                "level {k}: lobe counts add to {sum}, header says {nl}"
            )));
        }
        let compact = texels >= crate::compact::COMPACT_TEXELS;
        let mut lobes = crate::compact::Lobes::new(Vec::with_capacity(nl), compact);
        for _ in 0..nl {
            let a = DVec3::new(r.f32("axis")?, r.f32("axis")?, r.f32("axis")?);
            let weight = r.f32("weight")?;
            let exponent = r.f32("exponent")?;
            if !a.is_finite() || (a.length() - 1.0).abs() > 1e-3 {
                return Err(r.err(format!("level {k}: lobe axis {a} is not a unit vector")));
            }
            if !(weight.is_finite() && weight >= 0.0) {
                return Err(r.err(format!("level {k}: lobe weight {weight}")));
            }
            if !(exponent.is_finite() && (0.0..=ETA_MAX * 1.0001).contains(&exponent)) {
                return Err(r.err(format!("level {k}: lobe exponent {exponent}")));
            }
            lobes.push(PhongLobe {
                axis: a.normalize(),
                weight,
                exponent,
            });
        }
        let horizon = if has_h {
            let mut h = Vec::with_capacity(texels);
            for _ in 0..texels {
                let weight = r.f32("horizon")?;
                let mean = [r.f32("h")?, r.f32("h")?, r.f32("h")?, r.f32("h")?];
                let var = [r.f32("h")?, r.f32("h")?, r.f32("h")?, r.f32("h")?];
                if !(weight.is_finite()
                    && weight >= 0.0
                    && mean.iter().chain(&var).all(|v| v.is_finite()))
                {
                    return Err(r.err(format!("level {k}: bad horizon statistics")));
                }
                if var.iter().any(|v| *v < 0.0) {
                    return Err(r.err(format!("level {k}: negative horizon variance {:?}", var)));
                }
                h.push(HorizonStats::from_axes(weight, mean, var));
            }
            Some(crate::compact::Horizons::new(h, compact))
        } else {
            None
        };
        levels.push(Level {
            cols: lc,
            rows: lr,
            span,
            lobe_start,
            lobes,
            horizon,
            residual,
        });
        ec = ec.div_ceil(2);
        er = er.div_ceil(2);
    }
    Ok(levels)
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    path: PathBuf,
    /// The mapped file `b` is, whose pages [`Reader::release`] hands back and whose length
    /// [`Reader::check_cut`] checks.
    mapped: Option<&'a lazy::MappedFile>,
    /// The bytes before this (a page boundary) are released.
    released: usize,
}

impl<'a> Reader<'a> {
    /// A reader of `b` from its start; `path` names it in errors.
    fn new(b: &'a [u8], path: &Path) -> Reader<'a> {
        Reader {
            b,
            pos: 0,
            path: path.to_path_buf(),
            mapped: None,
            released: 0,
        }
    }

    /// Whether the bytes read are released as they are read (a mapped file).
    fn releases(&self) -> bool {
        self.mapped.is_some()
    }

    /// `Err` naming the file when the mapped file the reader holds has been cut short since it
    /// was mapped (reading its cut pages would fault): checked before each band (one `fstat`).
    fn check_cut(&self) -> Result<()> {
        match self.mapped.and_then(lazy::MappedFile::cut_message) {
            Some(m) => Err(self.err(m)),
            None => Ok(()),
        }
    }

    /// Hand the whole pages before the reader's position back to the system when the reader
    /// holds a mapped file (they are read again from the file if read again): the file then
    /// takes no more of the process's memory than the pages between two calls.
    fn release(&mut self) {
        if let Some(m) = self.mapped {
            let to = self.pos / lazy::RELEASE_PAGE * lazy::RELEASE_PAGE;
            if to > self.released {
                lazy::release(&m.map, self.released, to);
                self.released = to;
            }
        }
    }

    /// The header of level `k` (texels along x and y, span, lobe count), checked against the
    /// expected `ec × er` texels, span `2^k` and at most `max_lobes` per texel (both formats);
    /// returns the lobe count.
    fn level_header(&mut self, k: usize, ec: usize, er: usize, max_lobes: usize) -> Result<usize> {
        let lc = self.u32("level cols")? as usize;
        let lr = self.u32("level rows")? as usize;
        let span = self.u32("level span")? as usize;
        let nl = self.u32("level lobe count")? as usize;
        if lc != ec || lr != er || span != 1 << k {
            return Err(self.err(format!(
                "level {k} is {lc}x{lr} span {span}; expected {ec}x{er} span {}",
                1u64 << k
            )));
        }
        if nl > lc * lr * max_lobes {
            return Err(self.err(format!(
                "level {k} claims {nl} lobes for {} texels",
                lc * lr
            )));
        }
        Ok(nl)
    }

    /// A level's residual as both formats store it after the level header: mean, max (`f64`)
    /// and the texels it was sampled over (`u32`); the shading errors come from format 3's
    /// trailer, if at all.
    fn residual(&mut self) -> Result<Residual> {
        Ok(Residual {
            mean: self.f64("residual")?,
            max: self.f64("residual")?,
            texels: self.u32("residual texels")?,
            shading_mean: None,
            shading_max: None,
        })
    }

    fn err(&self, message: String) -> MapError {
        MapError::MapFormat {
            path: self.path.clone(),
            message,
        }
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.b.len() - self.pos < n {
            return Err(self.err(format!(
                "truncated while reading {what} at byte {}",
                self.pos
            )));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn f32(&mut self, what: &str) -> Result<f64> {
        Ok(f32::from_le_bytes(self.take(4, what)?.try_into().unwrap()) as f64)
    }
}
