//! A level of a format-4 map file held by band ([`LazyLevel`]): the file stays mapped, each
//! band's place is recorded when the file is read (and every band checked then), and a band's
//! codes are inflated and decoded only when something first reads one of its lobes or texels,
//! under a small cache of decoded bands. What [`crate::Pyramid::read_lazy`] holds level 0 as
//! (¾ of a pyramid's lobes and texels): an 8192² height map's pyramid read for rendering takes
//! ≈ 1.6 GB rather than ≈ 4.2 GB (`docs/map-format.md`, "Rendering a map file").
//!
//! Reads go through [`crate::Lobes::Lazy`] and [`crate::Horizons::Lazy`] ([`LazyLevel::lobe`],
//! [`LazyLevel::horizon`]), which give the very values of [`crate::Lobes::Coded`] and
//! [`crate::Horizons::Coded`] (the same codes, decoded by the same code). Each thread keeps the
//! two bands it read last, so reading a band's lobes and texels one by one takes no lock;
//! another band is fetched from the shared cache (a lock), decoded on a miss (one band at a
//! time, the cache's oldest band dropped past its size).

use super::v3::TableEntry;
use super::v4::read_band;
use super::{Header, Reader};
use crate::compact::{HorizonCode, Horizons, LobeCode, Lobes};
use crate::horizon::HorizonStats;
use crate::pyramid::Residual;
use meso_core::ndf::PhongLobe;
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

/// A map file mapped read-only, with its open handle: the handle tells its length now (the
/// same file, even if its name has since been given to another by a rename).
pub(crate) struct MappedFile {
    /// The mapping.
    pub(crate) map: memmap2::Mmap,
    file: std::fs::File,
}

impl MappedFile {
    /// The mapping `map` of the open `file`.
    pub(crate) fn new(map: memmap2::Mmap, file: std::fs::File) -> MappedFile {
        MappedFile { map, file }
    }

    /// The file's length now when it is shorter than the mapping (cut by another program since
    /// it was mapped: reading the cut pages would fault), else `None`. One `fstat`; the file
    /// could still be cut between this and the read, a far narrower window than the whole
    /// render.
    pub(crate) fn cut(&self) -> Option<u64> {
        let len = self.file.metadata().map_or(0, |m| m.len());
        (len < self.map.len() as u64).then_some(len)
    }

    /// The message of a file [`Self::cut`] short since it was mapped (the one wording of the
    /// eager reader and the by-band levels), else `None`.
    pub(crate) fn cut_message(&self) -> Option<String> {
        self.cut().map(|len| {
            format!(
                "the file is {len} bytes, {} when it was opened: cut while being read",
                self.map.len()
            )
        })
    }
}

/// Where one band of a lazily held level lies in the mapped file.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BandEntry {
    /// Byte offset of the band's chunk (its `BAND` tag).
    pub(crate) at: usize,
    /// Its first row and rows.
    pub(crate) row0: usize,
    pub(crate) rows: usize,
    /// The level's index of its first lobe, and its lobes.
    pub(crate) lobe0: usize,
    pub(crate) lobes: usize,
}

/// One band decoded: its lobes' and texels' codes.
#[derive(Debug)]
struct Band {
    /// Index in [`LazyLevel::bands`].
    idx: usize,
    /// Texels `t0..t1` and lobes `l0..l1` of the level.
    t0: usize,
    t1: usize,
    l0: usize,
    l1: usize,
    lobes: Vec<LobeCode>,
    horizon: Vec<HorizonCode>,
}

/// The decoded bands held, most recently used last.
#[derive(Debug, Default)]
struct Cache {
    bands: Vec<Arc<Band>>,
}

/// Bands the shared cache keeps besides those its threads hold ([`cache_bands`]).
const CACHE_BANDS: usize = 8;
/// Bands each thread keeps (the last two it read: a texel's cell reads the next row, which
/// may be the next band's).
const THREAD_BANDS: usize = 2;

/// Bands the shared cache of a level keeps: [`CACHE_BANDS`], at least one more than the
/// threads that may read at once.
fn cache_bands() -> usize {
    CACHE_BANDS.max(rayon::current_num_threads() + 2)
}

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// A thread's last bands read, with their level's id, most recent first.
type Recent = [Option<(u64, Arc<Band>)>; THREAD_BANDS];

thread_local! {
    /// The bands this thread read last ([`Recent`]).
    static RECENT: RefCell<Recent> =
        const { RefCell::new([None, None]) };
}

/// A compact level of a mapped format-4 file held by band (module docs): its lobes and texels'
/// horizon statistics read as [`crate::Lobes::Coded`] and [`crate::Horizons::Coded`] would
/// give them, decoded from the file band by band when first read. Its lobe starts are held
/// whole by its [`crate::Level`] (4 bytes a texel).
pub struct LazyLevel {
    /// Tells this level's bands apart in the threads' recent bands.
    id: u64,
    map: Arc<MappedFile>,
    path: PathBuf,
    header: Header,
    level: usize,
    cols: usize,
    rows: usize,
    bands: Vec<BandEntry>,
    lobes: usize,
    /// The largest band's codes (bytes) and the largest memory of decoding one (bytes).
    band_codes: u64,
    band_work: u64,
    cache: Mutex<Cache>,
    /// Held while a band is decoded: one at a time.
    decoding: Mutex<()>,
    cache_bands: AtomicUsize,
    decoded: AtomicUsize,
    /// The first band that no longer decoded (the file changed in place while mapped): what
    /// was wrong ([`LazyLevel::check`]).
    failure: OnceLock<String>,
}

impl std::fmt::Debug for LazyLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LazyLevel")
            .field("path", &self.path)
            .field("level", &self.level)
            .field("cols", &self.cols)
            .field("rows", &self.rows)
            .field("bands", &self.bands.len())
            .field("lobes", &self.lobes)
            .finish_non_exhaustive()
    }
}

/// Two lazy levels are equal when they are the same one (the values are not compared).
impl PartialEq for LazyLevel {
    fn eq(&self, other: &Self) -> bool {
        self.id == other.id
    }
}

/// The most memory (bytes) a lazily held level takes besides its lobe starts: the bands its
/// cache and each thread keep (`band_codes` bytes each at most) and one band being decoded
/// (`band_work` bytes at most).
pub(crate) fn held_bytes_bound(band_codes: u64, band_work: u64) -> u64 {
    let bands = cache_bands() + THREAD_BANDS * rayon::current_num_threads();
    bands as u64 * band_codes + band_work
}

impl LazyLevel {
    /// The level `level` (`cols × rows` texels) of the mapped file `map` (named `path`, of
    /// header `header`), whose bands `bands` have been checked; `band_codes` the largest
    /// band's codes and `band_work` the largest memory of decoding one (bytes).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        map: Arc<MappedFile>,
        path: &Path,
        header: &Header,
        level: usize,
        (cols, rows): (usize, usize),
        bands: Vec<BandEntry>,
        band_codes: u64,
        band_work: u64,
    ) -> LazyLevel {
        let lobes = bands.last().map_or(0, |b| b.lobe0 + b.lobes);
        LazyLevel {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            map,
            path: path.to_path_buf(),
            header: header.clone(),
            level,
            cols,
            rows,
            bands,
            lobes,
            band_codes,
            band_work,
            cache: Mutex::new(Cache::default()),
            decoding: Mutex::new(()),
            cache_bands: AtomicUsize::new(cache_bands()),
            decoded: AtomicUsize::new(0),
            failure: OnceLock::new(),
        }
    }

    /// Number of lobes.
    #[must_use]
    pub fn lobes(&self) -> usize {
        self.lobes
    }

    /// Number of texels.
    #[must_use]
    pub fn texels(&self) -> usize {
        self.cols * self.rows
    }

    /// Number of bands.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands.len()
    }

    /// How many times a band has been decoded so far (each miss of the cache decodes one).
    #[must_use]
    pub fn decoded_bands(&self) -> usize {
        self.decoded.load(Ordering::Relaxed)
    }

    /// Keep at most `n` (≥ 1) decoded bands in the shared cache (default: 8, at least the
    /// threads + 2); the threads keep their last two besides. Bands held past it are dropped.
    pub fn set_cache_bands(&self, n: usize) {
        self.cache_bands.store(n.max(1), Ordering::Relaxed);
        let mut c = self.cache.lock().unwrap_or_else(PoisonError::into_inner);
        let over = c.bands.len().saturating_sub(n.max(1));
        c.bands.drain(..over);
    }

    /// Whether every band read so far decoded: `Err` naming the file when one no longer did
    /// (the file changed in place while mapped, after reading checked it), whose lobes then
    /// read as zero-weight ([`LazyLevel::lobe`]). What a reader of the level checks before it
    /// writes anything made from what it read (`meso render`, `meso export --lobes`, Python).
    ///
    /// # Errors
    /// [`crate::MapError::MapFormat`] naming the file, the level and the band.
    pub fn check(&self) -> crate::error::Result<()> {
        match self.failure.get() {
            None => Ok(()),
            Some(m) => Err(crate::MapError::MapFormat {
                path: self.path.clone(),
                message: m.clone(),
            }),
        }
    }

    /// The most memory (bytes) the level's decoded bands take (the cache's, each thread's
    /// last two and one being decoded), with this build's thread count.
    #[must_use]
    pub fn held_bytes_bound(&self) -> u64 {
        held_bytes_bound(self.band_codes, self.band_work)
    }

    /// Lobe `i` (as [`Lobes::Coded`] reads it).
    ///
    /// A band that no longer decodes though it was checked when the file was read (the file
    /// changed in place while mapped) reads as zero-weight lobes and zero-weight horizon
    /// statistics, and [`LazyLevel::check`] says so: check after reading.
    ///
    /// # Panics
    /// `i ≥ lobes()`.
    #[inline]
    #[must_use]
    pub fn lobe(&self, i: usize) -> PhongLobe {
        assert!(i < self.lobes, "lobe {i} of {}", self.lobes);
        self.with_lobe_band(i, |b| b.lobes[i - b.l0].to_phong())
    }

    /// The horizon statistics of texel `t` (as [`Horizons::Coded`] reads them).
    ///
    /// A band that no longer decodes reads as [`LazyLevel::lobe`] says.
    ///
    /// # Panics
    /// `t ≥ texels()`, or the file has no horizon statistics.
    #[inline]
    #[must_use]
    pub fn horizon(&self, t: usize) -> HorizonStats {
        assert!(
            t < self.texels() && self.header.has_h,
            "texel {t} of {} (horizon statistics: {})",
            self.texels(),
            self.header.has_h
        );
        self.with_texel_band(t, |b| b.horizon[t - b.t0].to_stats())
    }

    /// Lobes `a..b` (as [`Lobes::Coded`] reads them): a texel's lobes (at most
    /// [`crate::limits::MAX_LOBES`], in one band) copied from their band at once, longer
    /// ranges read one by one.
    ///
    /// # Panics
    /// `a > b` or `b > lobes()`.
    #[must_use]
    pub fn range(&self, a: usize, b: usize) -> LazyLobes<'_> {
        assert!(
            a <= b && b <= self.lobes,
            "lobes {a}..{b} of {}",
            self.lobes
        );
        let mut it = LazyLobes {
            level: self,
            buf: [LobeCode::default(); INLINE],
            start: a,
            next: a,
            end: b,
            inline: false,
        };
        if a < b && b - a <= INLINE {
            it.inline = self.with_lobe_band(a, |x| {
                if b > x.l1 {
                    return false;
                }
                it.buf[..b - a].copy_from_slice(&x.lobes[a - x.l0..b - x.l0]);
                true
            });
        }
        it
    }

    /// The codes of lobes `a..b` (a copy).
    pub(crate) fn lobe_codes(&self, a: usize, b: usize) -> Vec<LobeCode> {
        let mut out = Vec::with_capacity(b.saturating_sub(a));
        let mut i = a;
        while i < b {
            let n = self.with_lobe_band(i, |x| {
                let end = b.min(x.l1);
                out.extend_from_slice(&x.lobes[i - x.l0..end - x.l0]);
                end - i
            });
            i += n;
        }
        out
    }

    /// The horizon codes of texels `a..b` (a copy).
    pub(crate) fn horizon_codes(&self, a: usize, b: usize) -> Vec<HorizonCode> {
        let mut out = Vec::with_capacity(b.saturating_sub(a));
        let mut t = a;
        while t < b {
            let n = self.with_texel_band(t, |x| {
                let end = b.min(x.t1);
                out.extend_from_slice(&x.horizon[t - x.t0..end - x.t0]);
                end - t
            });
            t += n;
        }
        out
    }

    /// `f` of the band that holds lobe `i` ([`LazyLevel::with_band`]).
    #[inline]
    fn with_lobe_band<R>(&self, i: usize, f: impl FnOnce(&Band) -> R) -> R {
        self.with_band(
            |b| (b.l0..b.l1).contains(&i),
            || self.bands.partition_point(|b| b.lobe0 + b.lobes <= i),
            f,
        )
    }

    /// `f` of the band that holds texel `t` ([`LazyLevel::with_band`]).
    #[inline]
    fn with_texel_band<R>(&self, t: usize, f: impl FnOnce(&Band) -> R) -> R {
        let row = t / self.cols;
        self.with_band(
            |b| (b.t0..b.t1).contains(&t),
            || self.bands.partition_point(|b| b.row0 + b.rows <= row),
            f,
        )
    }

    /// `f` of the band that `holds` picks: one of this thread's last two if it holds it,
    /// else band `locate()` from the shared cache (decoded on a miss), then kept as this
    /// thread's last.
    #[inline]
    fn with_band<R>(
        &self,
        holds: impl Fn(&Band) -> bool,
        locate: impl FnOnce() -> usize,
        f: impl FnOnce(&Band) -> R,
    ) -> R {
        let mut f = Some(f);
        let hit = RECENT.with(|c| {
            let c = c.borrow();
            for (id, b) in c.iter().flatten() {
                if *id == self.id && holds(b) {
                    return f.take().map(|f| f(b));
                }
            }
            None
        });
        if let Some(r) = hit {
            return r;
        }
        let band = self.fetch(locate());
        RECENT.with(|c| {
            let mut c = c.borrow_mut();
            c.rotate_right(1);
            c[0] = Some((self.id, Arc::clone(&band)));
        });
        match f.take() {
            Some(f) => f(&band),
            None => unreachable!("f is taken once"),
        }
    }

    /// Band `idx`, from the shared cache or decoded into it.
    fn fetch(&self, idx: usize) -> Arc<Band> {
        let cached = |c: &mut Cache| {
            let at = c.bands.iter().position(|b| b.idx == idx)?;
            let b = c.bands.remove(at);
            c.bands.push(Arc::clone(&b));
            Some(b)
        };
        if let Some(b) = cached(&mut self.cache.lock().unwrap_or_else(PoisonError::into_inner)) {
            return b;
        }
        let _one = self.decoding.lock().unwrap_or_else(PoisonError::into_inner);
        // Another thread may have decoded it meanwhile.
        if let Some(b) = cached(&mut self.cache.lock().unwrap_or_else(PoisonError::into_inner)) {
            return b;
        }
        let band = match self.decode(idx) {
            Ok(b) => Arc::new(b),
            Err(e) => {
                let message = match e {
                    crate::MapError::MapFormat { message, .. } => message,
                    other => other.to_string(),
                };
                let e = self.bands[idx];
                self.failure.get_or_init(|| {
                    format!(
                        "level {}, band {idx} (rows {}..{}): {message} (the band was valid when \
                         the file was read: the file changed in place while it was in use; read \
                         it again)",
                        self.level,
                        e.row0,
                        e.row0 + e.rows
                    )
                });
                Arc::new(self.blank(idx))
            }
        };
        self.decoded.fetch_add(1, Ordering::Relaxed);
        let mut c = self.cache.lock().unwrap_or_else(PoisonError::into_inner);
        c.bands.push(Arc::clone(&band));
        let over = c
            .bands
            .len()
            .saturating_sub(self.cache_bands.load(Ordering::Relaxed));
        c.bands.drain(..over);
        band
    }

    /// Band `idx` blank: zero-weight lobes on the normal, as sharp as a lobe can be (so that
    /// what reads them takes its quick paths: a blank level 0 of an 8192² map is read as fast as
    /// a real one), and zero-weight horizon statistics: what a band that no longer decodes reads
    /// as ([`LazyLevel::check`]).
    fn blank(&self, idx: usize) -> Band {
        let e = self.bands[idx];
        let blank = LobeCode::from_phong(&PhongLobe {
            axis: glam::DVec3::Z,
            weight: 0.0,
            exponent: crate::fit::ETA_MAX,
        });
        let t0 = e.row0 * self.cols;
        let texels = e.rows * self.cols;
        Band {
            idx,
            t0,
            t1: t0 + texels,
            l0: e.lobe0,
            l1: e.lobe0 + e.lobes,
            lobes: vec![blank; e.lobes],
            horizon: if self.header.has_h {
                vec![HorizonCode::default(); texels]
            } else {
                Vec::new()
            },
        }
    }

    /// Inflate and decode band `idx` with every check of the reader, then hand its pages of
    /// the file back (they are read from the file again if it is decoded again).
    fn decode(&self, idx: usize) -> crate::error::Result<Band> {
        let e = self.bands[idx];
        if let Some(message) = self.map.cut_message() {
            return Err(crate::MapError::MapFormat {
                path: self.path.clone(),
                message,
            });
        }
        let mut r = Reader::new(&self.map.map, &self.path);
        r.pos = e.at;
        let entry = TableEntry {
            cols: self.cols,
            rows: self.rows,
            span: 1 << self.level,
            lobes: 0,
            residual: Residual::default(),
            t0: 0,
        };
        let band = read_band(&mut r, &self.header, self.level, &entry, e.row0, true)?;
        release(&self.map.map, e.at, r.pos);
        let lobes = match band.lobes {
            Lobes::Coded(v) if v.len() == e.lobes => v,
            _ => return Err(r.err(format!("level {}: band {idx} changed", self.level))),
        };
        let horizon = match band.horizon {
            Some(Horizons::Coded(v)) => v,
            None if !self.header.has_h => Vec::new(),
            _ => return Err(r.err(format!("level {}: band {idx} changed", self.level))),
        };
        let t0 = e.row0 * self.cols;
        Ok(Band {
            idx,
            t0,
            t1: t0 + e.rows * self.cols,
            l0: e.lobe0,
            l1: e.lobe0 + e.lobes,
            lobes,
            horizon,
        })
    }
}

/// The unit [`release`] hands pages back in (bytes): a multiple of every page size in use.
pub(crate) const RELEASE_PAGE: usize = 1 << 16;

/// Hand the whole pages of `map` within bytes `a..b` back to the system (unix; a no-op
/// elsewhere): read from the file again if read again.
pub(crate) fn release(map: &memmap2::Mmap, a: usize, b: usize) {
    #[cfg(unix)]
    {
        const PAGE: usize = RELEASE_PAGE;
        let (from, to) = (a.div_ceil(PAGE) * PAGE, b / PAGE * PAGE);
        if to > from {
            // SAFETY: a read-only private mapping of the file; dropping pages of it only makes
            // later reads fault them in from the file again, with the same bytes.
            let _ = unsafe {
                map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, from, to - from)
            };
        }
    }
    #[cfg(not(unix))]
    let _ = (map, a, b);
}

/// Lobes a range copies from its band at once ([`LazyLevel::range`]): a texel's most.
const INLINE: usize = crate::limits::MAX_LOBES;

/// The lobes of [`LazyLevel::range`] as [`PhongLobe`]s.
#[derive(Clone, Debug)]
pub struct LazyLobes<'a> {
    level: &'a LazyLevel,
    /// Lobes `start..end` copied (`buf[i - start]`) when `inline`.
    buf: [LobeCode; INLINE],
    start: usize,
    next: usize,
    end: usize,
    inline: bool,
}

impl Iterator for LazyLobes<'_> {
    type Item = PhongLobe;
    #[inline]
    fn next(&mut self) -> Option<PhongLobe> {
        if self.next >= self.end {
            return None;
        }
        let i = self.next;
        self.next += 1;
        Some(if self.inline {
            self.buf[i - self.start].to_phong()
        } else {
            self.level.lobe(i)
        })
    }
    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.end - self.next;
        (n, Some(n))
    }
}
