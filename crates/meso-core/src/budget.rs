//! The memory budget: how many bytes a command may plan to use, and the checks that refuse work
//! above it before anything big is allocated.
//!
//! Commands estimate their peak memory from what they know before decoding: image headers (width,
//! height, sample format), file sizes, the render's resolution. [`check`] compares an estimate
//! with the [`budget`] and returns a one-line [`BudgetError`] naming the file, the estimate and
//! the budget. The big buffers themselves are allocated with [`try_vec`] / [`try_reserve`], so an
//! allocation that fails anyway (another process took the memory, an address-space limit) is an
//! error ([`AllocError`]) instead of an abort.
//!
//! # The budget
//! In order of precedence:
//! 1. [`set_budget`] (the `meso --memory-budget SIZE` option);
//! 2. the environment variable [`ENV_VAR`] (`MESO_MEMORY_BUDGET=8G`);
//! 3. the default [`default_budget`]: [`DEFAULT_BUDGET_BYTES`] (4 GiB), lowered to ¾ of the
//!    physical memory and to ¾ of the address-space limit (`ulimit -v`, `prlimit --as`) when
//!    these are smaller.
//!
//! Sizes are written as a number of bytes with an optional binary suffix: `K`, `M`, `G`, `T`
//! (also `KiB`, `MB`, … — all powers of 1024), e.g. `512M`, `6G`, `1.5G`.

use std::fmt;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// The default budget in bytes (4 GiB), before the lowering to the machine's memory and the
/// address-space limit ([`default_budget`]).
pub const DEFAULT_BUDGET_BYTES: u64 = 4 << 30;

/// The environment variable that sets the budget (a size, see the module docs).
pub const ENV_VAR: &str = "MESO_MEMORY_BUDGET";

/// The budget set by [`set_budget`] (0: not set).
static OVERRIDE: AtomicU64 = AtomicU64::new(0);

/// Where the budget in force comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// [`set_budget`] (the `--memory-budget` option).
    Option,
    /// The environment variable [`ENV_VAR`].
    Env,
    /// [`default_budget`].
    Default,
}

/// The budget in force: bytes and where they come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    /// Bytes a command may plan to use.
    pub bytes: u64,
    /// Where the figure comes from.
    pub source: Source,
}

/// Set the budget for the rest of the process (the `--memory-budget` option), in bytes; it takes
/// precedence over [`ENV_VAR`]. A value of 0 removes the override.
pub fn set_budget(bytes: u64) {
    OVERRIDE.store(bytes, Ordering::Relaxed);
}

/// The budget in force (see the module docs for the precedence). An unparsable
/// [`ENV_VAR`] is ignored here; [`env_budget`] reports it.
#[must_use]
pub fn budget() -> Budget {
    let o = OVERRIDE.load(Ordering::Relaxed);
    if o > 0 {
        return Budget {
            bytes: o,
            source: Source::Option,
        };
    }
    if let Some(Ok(b)) = env_budget() {
        return Budget {
            bytes: b,
            source: Source::Env,
        };
    }
    Budget {
        bytes: default_budget(),
        source: Source::Default,
    }
}

/// The budget [`ENV_VAR`] asks for: `None` when it is not set, an error message when it is not a
/// size.
#[must_use]
pub fn env_budget() -> Option<Result<u64, String>> {
    let v = std::env::var_os(ENV_VAR)?;
    let s = v.to_string_lossy();
    Some(parse_size(&s).map_err(|e| format!("{ENV_VAR}={s:?}: {e}")))
}

/// [`DEFAULT_BUDGET_BYTES`], lowered to ¾ of the physical memory and ¾ of the process's
/// address-space limit where either is known and smaller (bytes).
#[must_use]
pub fn default_budget() -> u64 {
    let mut b = DEFAULT_BUDGET_BYTES;
    if let Some(m) = physical_memory() {
        b = b.min(m / 4 * 3);
    }
    if let Some(a) = address_space_limit() {
        b = b.min(a / 4 * 3);
    }
    b
}

/// Physical memory of the machine in bytes, where the system says.
#[must_use]
pub fn physical_memory() -> Option<u64> {
    #[cfg(unix)]
    {
        // SAFETY: sysconf has no preconditions.
        let (pages, size) = unsafe {
            (
                libc::sysconf(libc::_SC_PHYS_PAGES),
                libc::sysconf(libc::_SC_PAGESIZE),
            )
        };
        if pages > 0 && size > 0 {
            return Some((pages as u64).saturating_mul(size as u64));
        }
    }
    None
}

/// The process's address-space limit (`RLIMIT_AS`, the soft limit) in bytes, if there is one.
#[must_use]
pub fn address_space_limit() -> Option<u64> {
    #[cfg(unix)]
    {
        let mut r = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes into the struct we pass.
        if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut r) } == 0
            && r.rlim_cur != libc::RLIM_INFINITY
        {
            #[allow(clippy::unnecessary_cast)] // rlim_t is not u64 everywhere
            return Some(r.rlim_cur as u64);
        }
    }
    None
}

/// Parse a size: a number of bytes with an optional suffix `K`, `M`, `G`, `T` (optionally
/// followed by `B` or `iB`; all powers of 1024), e.g. `4G`, `512MiB`, `1.5G`, `1000000`.
///
/// # Errors
/// A message saying what is wrong (not a number, an unknown suffix, zero, too large).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let unit = unit.trim().to_ascii_lowercase();
    let mult: u64 = match unit.trim_end_matches("ib").trim_end_matches('b') {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => {
            return Err(format!(
                "not a size (a number of bytes with an optional K, M, G or T suffix): {s:?}"
            ))
        }
    };
    let x: f64 = num
        .parse()
        .map_err(|_| format!("not a size (e.g. 4G, 512M, 1000000): {s:?}"))?;
    let bytes = x * mult as f64;
    if bytes.is_nan() || bytes < 1.0 {
        return Err(format!(
            "a memory budget must be at least 1 byte, got {s:?}"
        ));
    }
    if bytes >= u64::MAX as f64 {
        return Err(format!("too large: {s:?}"));
    }
    Ok(bytes as u64)
}

/// A byte count for messages: `812 B`, `3.4 MiB`, `6.15 GiB`.
#[must_use]
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut x = bytes as f64;
    let mut u = 0;
    while x >= 1024.0 && u + 1 < UNITS.len() {
        x /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else if x < 10.0 {
        format!("{x:.2} {}", UNITS[u])
    } else {
        format!("{x:.1} {}", UNITS[u])
    }
}

/// Work refused because its estimated peak memory is above the budget.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BudgetError {
    /// The input whose processing was refused (a file name, or a description).
    pub what: String,
    /// The task (`extracting the NDF pyramid`, `rendering 16384×16384 pixels`).
    pub task: String,
    /// Estimated peak memory, bytes.
    pub estimate: u64,
    /// The budget, bytes.
    pub budget: Budget,
}

impl fmt::Display for BudgetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let from = match self.budget.source {
            Source::Option => "--memory-budget",
            Source::Env => ENV_VAR,
            Source::Default => "the default",
        };
        write!(
            f,
            "{}: {} needs about {} of memory, more than the memory budget of {} ({from}; \
             raise it with --memory-budget SIZE or {ENV_VAR}=SIZE)",
            self.what,
            self.task,
            human(self.estimate),
            human(self.budget.bytes)
        )
    }
}

impl std::error::Error for BudgetError {}

/// Refuse `task` on `what` when its estimated peak `estimate` (bytes) is above the [`budget`].
///
/// # Errors
/// [`BudgetError`] naming `what`, the task, the estimate and the budget.
pub fn check(what: &Path, task: &str, estimate: u64) -> Result<(), BudgetError> {
    check_named(&what.display().to_string(), task, estimate)
}

/// [`check`] for an input that is not a file (`what` is shown as given).
///
/// # Errors
/// [`BudgetError`] naming `what`, the task, the estimate and the budget.
pub fn check_named(what: &str, task: &str, estimate: u64) -> Result<(), BudgetError> {
    let b = budget();
    if estimate > b.bytes {
        return Err(BudgetError {
            what: what.to_owned(),
            task: task.to_owned(),
            estimate,
            budget: b,
        });
    }
    Ok(())
}

/// An allocation that failed: how many bytes were asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AllocError {
    /// Bytes requested.
    pub bytes: u64,
}

impl fmt::Display for AllocError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "out of memory: cannot allocate {} (the memory budget, {}, is more than this process \
             can get: free memory, or lower the budget to have such work refused up front)",
            human(self.bytes),
            human(budget().bytes)
        )
    }
}

impl std::error::Error for AllocError {}

thread_local! {
    /// Depth of [`fallible`] sections on this thread.
    static FALLIBLE: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

/// Run `f` as a fallible-allocation section: a process-wide allocator that turns allocation
/// failures into an exit (meso's binary does) lets allocations inside `f` fail normally instead,
/// so that `try_reserve` can report them as errors.
pub fn fallible<R>(f: impl FnOnce() -> R) -> R {
    struct Guard;
    impl Drop for Guard {
        fn drop(&mut self) {
            FALLIBLE.with(|c| c.set(c.get().saturating_sub(1)));
        }
    }
    FALLIBLE.with(|c| c.set(c.get() + 1));
    let _g = Guard;
    f()
}

/// Whether the current thread is inside a [`fallible`] section (for a global allocator).
#[must_use]
pub fn in_fallible_section() -> bool {
    FALLIBLE.try_with(std::cell::Cell::get).unwrap_or(0) > 0
}

/// Reserve room for `additional` more elements in `v`, as an error instead of an abort when the
/// memory is not there.
///
/// # Errors
/// [`AllocError`] with the bytes asked for.
pub fn try_reserve<T>(v: &mut Vec<T>, additional: usize) -> Result<(), AllocError> {
    fallible(|| v.try_reserve_exact(additional)).map_err(|_| AllocError {
        bytes: (additional as u64).saturating_mul(std::mem::size_of::<T>() as u64),
    })
}

/// An empty vector with room for `n` elements, or an [`AllocError`].
///
/// # Errors
/// [`AllocError`] when the memory is not there.
pub fn try_with_capacity<T>(n: usize) -> Result<Vec<T>, AllocError> {
    let mut v = Vec::new();
    try_reserve(&mut v, n)?;
    Ok(v)
}

/// `vec![value; n]`, or an [`AllocError`] when the memory is not there.
///
/// # Errors
/// [`AllocError`] when the memory is not there.
pub fn try_vec<T: Clone>(value: T, n: usize) -> Result<Vec<T>, AllocError> {
    let mut v = try_with_capacity(n)?;
    v.resize(n, value);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("512MiB"), Ok(512 << 20));
        assert_eq!(parse_size("1.5g"), Ok(3 << 29));
        assert_eq!(parse_size("1000"), Ok(1000));
        assert_eq!(parse_size(" 2 KB "), Ok(2048));
        assert!(parse_size("0").is_err());
        assert!(parse_size("-1G").is_err());
        assert!(parse_size("4X").is_err());
        assert!(parse_size("").is_err());
        assert!(parse_size("1e30T").is_err());
    }

    #[test]
    fn human_sizes() {
        assert_eq!(human(812), "812 B");
        assert_eq!(human(3 << 20), "3.00 MiB");
        assert_eq!(human(6_600_000_000), "6.15 GiB");
    }

    #[test]
    fn check_refuses_above_the_budget_and_try_vec_reports() {
        set_budget(1 << 20);
        let e = check(Path::new("big.png"), "decoding", 2 << 20).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.starts_with("big.png: decoding needs about 2.00 MiB"),
            "{msg}"
        );
        assert!(msg.contains("budget of 1.00 MiB (--memory-budget"), "{msg}");
        assert!(check(Path::new("small.png"), "decoding", 1 << 20).is_ok());
        set_budget(0);
        let e = try_vec(0u64, usize::MAX / 16).unwrap_err();
        assert!(
            e.to_string().starts_with("out of memory: cannot allocate"),
            "{e}"
        );
        assert_eq!(try_vec(1u8, 3).unwrap(), vec![1, 1, 1]);
        assert!(!in_fallible_section());
    }
}
