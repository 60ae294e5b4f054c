//! Safe file input and output.
//!
//! Every file meso writes goes through [`write_atomic`] / [`write_atomic_with`] (or, for a
//! command with several outputs, [`stage_with`] and [`commit_all`]):
//!
//! * a **regular file** (or a path that does not exist yet) is written to a temporary file
//!   created exclusively (`O_EXCL`) in the target's directory, named
//!   `.NAME.meso-PID.XXXXXX.tmp` (see [`temp_file_pid`]: the target's name, the writer's process
//!   id and six random characters), flushed, synced and renamed over the target, so a failure
//!   never leaves a partial output and nobody can make meso write through a planted temporary
//!   name. An existing target keeps its permission bits (and, where the process may, its owner);
//!   a new one gets `0666 & !umask` like any other file. Before creating its temporary file, a
//!   write removes the temporary files of the same target left by runs that were killed (on
//!   Unix: regular files of this user, with exactly that name pattern, whose process no longer
//!   exists; see [`remove_stale_temp_files`]);
//! * a **symbolic link** is followed: the file it points at is replaced, the link stays;
//! * a **non-regular target** (character or block device, FIFO, socket, `/dev/stdout` and the
//!   other `/proc/self/fd/N` links) is written directly, in place: it is never replaced by a
//!   regular file. Such a write is not atomic (a failure part-way leaves what was written);
//! * a directory is refused.
//!
//! [`check_not_input`] refuses an output that is the same file as one of a command's inputs, and
//! [`read_limited`] reads a file with a limit on the bytes actually read (which also holds for
//! `/dev/zero`, FIFOs and `/proc` files, whose reported size is 0).
//!
//! **The input log.** A command's inputs are not only the files on its command line: a scene
//! names materials, a material a height map or map file, a texture an image, a scene an
//! environment map and meshes. With [`record_inputs`] on (the `meso` command line turns it on
//! at start; a library user may too), every file meso reads as an input is noted
//! ([`note_input`]: by [`read_limited`], the image and map readers of `meso-maps`, …), and
//! every write ([`write_atomic_with`], [`stage_with`]) refuses a target that is the same file
//! as a noted input — so no output can overwrite a file the command read, however it was named.
//! Off (the default), nothing is noted and nothing is kept.

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Write `bytes` to `path` atomically (see the [module documentation](self) for what happens to
/// symlinks, devices and existing files). On error nothing is left behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Like [`write_atomic`], with the content produced by a closure writing into a buffered file.
/// If the closure fails, the temporary file is removed and `path` is untouched. A non-regular
/// target (device, FIFO, `/dev/stdout`) receives the content as it is produced.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    check_not_recorded_input(path)?;
    if path.file_name().is_some() {
        if let Resolved::Direct(target) = resolve(path)? {
            let mut w = std::io::BufWriter::new(open_direct(&target)?);
            fill(&mut w)?;
            return w.flush();
        }
    }
    stage_with(path, fill)?.commit()
}

/// The mark between a temporary file's target name and the writer's process id:
/// `.NAME` + `.meso-` + `PID` + `.` + six random characters + [`TEMP_SUFFIX`].
pub const TEMP_MARK: &str = ".meso-";

/// The end of every temporary file's name.
pub const TEMP_SUFFIX: &str = ".tmp";

/// The number of random characters (`[A-Za-z0-9]`) in a temporary file's name.
pub const TEMP_RANDOM_CHARS: usize = 6;

/// The longest target name (bytes) a temporary file's name repeats; a longer one is cut there,
/// so that the temporary name stays within the usual 255-byte limit.
const TEMP_NAME_MAX: usize = 200;

/// The target's name as its temporary files repeat it (at most [`TEMP_NAME_MAX`] bytes).
fn temp_stem(name: &std::ffi::OsStr) -> std::ffi::OsString {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let b = name.as_bytes();
        std::ffi::OsStr::from_bytes(&b[..b.len().min(TEMP_NAME_MAX)]).to_os_string()
    }
    #[cfg(not(unix))]
    {
        let s: String = name.to_string_lossy().chars().take(TEMP_NAME_MAX).collect();
        std::ffi::OsString::from(s)
    }
}

/// `.NAME.meso-PID.`: the fixed start of the temporary files process `pid` creates for the
/// target named `name`.
fn temp_prefix(name: &std::ffi::OsStr, pid: u32) -> std::ffi::OsString {
    let mut p = std::ffi::OsString::from(".");
    p.push(temp_stem(name));
    p.push(TEMP_MARK);
    p.push(pid.to_string());
    p.push(".");
    p
}

/// If `file_name` is the name of a temporary file meso creates for the target named
/// `target_name` — exactly `.NAME.meso-PID.XXXXXX.tmp`, with a decimal PID (no sign, no leading
/// zero) and [`TEMP_RANDOM_CHARS`] characters `[A-Za-z0-9]` — the PID of the process that
/// created it.
#[must_use]
pub fn temp_file_pid(file_name: &std::ffi::OsStr, target_name: &std::ffi::OsStr) -> Option<u32> {
    let mut start = std::ffi::OsString::from(".");
    start.push(temp_stem(target_name));
    start.push(TEMP_MARK);
    let (name, start) = (os_bytes(file_name)?, os_bytes(&start)?);
    let rest = name.strip_prefix(start.as_slice())?;
    let rest = rest.strip_suffix(TEMP_SUFFIX.as_bytes())?;
    let dot = rest.iter().position(|&c| c == b'.')?;
    let (digits, random) = (&rest[..dot], &rest[dot + 1..]);
    if digits.is_empty()
        || digits.len() > 10
        || digits[0] == b'0'
        || !digits.iter().all(u8::is_ascii_digit)
        || random.len() != TEMP_RANDOM_CHARS
        || !random.iter().all(u8::is_ascii_alphanumeric)
    {
        return None;
    }
    std::str::from_utf8(digits).ok()?.parse().ok()
}

/// The bytes of a name (on Unix, any name; elsewhere, UTF-8 names).
fn os_bytes(s: &std::ffi::OsStr) -> Option<Vec<u8>> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Some(s.as_bytes().to_vec())
    }
    #[cfg(not(unix))]
    {
        s.to_str().map(|s| s.as_bytes().to_vec())
    }
}

/// Remove, from `dir`, the temporary files that killed runs left for the target named `name`.
///
/// On Unix, an entry is removed only when all of these hold: its name is exactly the pattern of
/// [`temp_file_pid`] for this target; the process id it carries is not this process's and no
/// process with that id exists (`kill(pid, 0)` fails with `ESRCH`; a process of another user
/// counts as alive); it is a regular file (symlinks are never followed: a symlink, directory or
/// anything else with such a name stays); and it belongs to this process's effective user.
/// Errors (an unreadable directory, a file removed meanwhile) are ignored. Elsewhere nothing is
/// removed. Returns the number of files removed.
pub fn remove_stale_temp_files(dir: &Path, name: &std::ffi::OsStr) -> usize {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let Ok(entries) = std::fs::read_dir(dir) else {
            return 0;
        };
        let me = std::process::id();
        // SAFETY: geteuid has no preconditions and cannot fail.
        let uid = unsafe { libc::geteuid() };
        let mut removed = 0;
        for e in entries.flatten() {
            let Some(pid) = temp_file_pid(&e.file_name(), name) else {
                continue;
            };
            if pid == me || process_exists(pid) {
                continue;
            }
            let path = e.path();
            let Ok(m) = std::fs::symlink_metadata(&path) else {
                continue;
            };
            if !m.file_type().is_file() || m.uid() != uid {
                continue;
            }
            if std::fs::remove_file(&path).is_ok() {
                removed += 1;
            }
        }
        removed
    }
    #[cfg(not(unix))]
    {
        let _ = (dir, name);
        0
    }
}

/// Whether a process with id `pid` may exist: anything but a definite "no such process".
#[cfg(unix)]
fn process_exists(pid: u32) -> bool {
    let Ok(p) = libc::pid_t::try_from(pid) else {
        return true;
    };
    if p <= 0 {
        return true;
    }
    // SAFETY: signal 0 only checks that the process exists; nothing is sent.
    if unsafe { libc::kill(p, 0) } == 0 {
        return true;
    }
    std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

/// An output written but not yet in place: a synced temporary file next to its target (or, for a
/// non-regular target, the bytes to write to it). [`Staged::commit`] or [`commit_all`] put it in
/// place; dropping it removes the temporary file and leaves the target untouched.
#[derive(Debug)]
pub struct Staged {
    path: PathBuf,
    inner: StagedInner,
}

#[derive(Debug)]
enum StagedInner {
    /// A temporary file to rename over `dest` (`existed`: `dest` was there before).
    Rename {
        tmp: tempfile::NamedTempFile,
        dest: PathBuf,
        existed: bool,
    },
    /// Bytes to write directly to a non-regular target.
    Direct {
        target: DirectTarget,
        bytes: Vec<u8>,
    },
}

/// A non-regular output: a path opened for writing, or a file descriptor of this process.
#[derive(Debug)]
enum DirectTarget {
    Path(PathBuf),
    Fd(i32),
}

/// What an output path resolves to.
enum Resolved {
    /// A regular file (symlinks followed), with its metadata.
    Regular(PathBuf, std::fs::Metadata),
    /// Nothing there yet (symlinks followed): a new file at this path.
    New(PathBuf),
    /// A device, FIFO, socket or `/proc` link: written in place.
    Direct(DirectTarget),
}

/// The file descriptor named by `/proc/self/fd/N`, `/dev/fd/N`, `/dev/stdout` or `/dev/stderr`.
fn own_fd(p: &Path) -> Option<i32> {
    match p.to_str()? {
        "/dev/stdout" => return Some(1),
        "/dev/stderr" => return Some(2),
        _ => {}
    }
    let s = p.to_str()?;
    let n = s
        .strip_prefix("/proc/self/fd/")
        .or_else(|| s.strip_prefix("/dev/fd/"))
        .or_else(|| s.strip_prefix("/proc/thread-self/fd/"))?;
    n.parse().ok()
}

fn resolve(path: &Path) -> std::io::Result<Resolved> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        if let Some(fd) = own_fd(&p) {
            return Ok(Resolved::Direct(DirectTarget::Fd(fd)));
        }
        let meta = match std::fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Resolved::New(p)),
            Err(e) => return Err(e),
        };
        let ft = meta.file_type();
        if ft.is_symlink() {
            if p.starts_with("/proc") {
                // A /proc "magic" link (another process's descriptor, …): open it as it is.
                return Ok(Resolved::Direct(DirectTarget::Path(p)));
            }
            let t = std::fs::read_link(&p)?;
            p = if t.is_absolute() {
                t
            } else {
                p.parent().unwrap_or(Path::new("")).join(t)
            };
            continue;
        }
        if ft.is_file() {
            return Ok(Resolved::Regular(p, meta));
        }
        if ft.is_dir() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::IsADirectory,
                "is a directory",
            ));
        }
        return Ok(Resolved::Direct(DirectTarget::Path(p)));
    }
    Err(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        "too many levels of symbolic links",
    ))
}

/// Write the content of an output without putting it in place yet (see [`Staged`]).
///
/// For a regular target the closure writes into the temporary file; for a non-regular one into
/// memory (the bytes go to the device at commit, so a failed command writes nothing to it).
pub fn stage_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<Staged> {
    check_not_recorded_input(path)?;
    if path.file_name().is_none() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a file name",
        ));
    }
    let (dest, meta) = match resolve(path)? {
        Resolved::Direct(target) => {
            let mut bytes = Vec::new();
            fill(&mut bytes)?;
            return Ok(Staged {
                path: path.to_path_buf(),
                inner: StagedInner::Direct { target, bytes },
            });
        }
        Resolved::Regular(p, m) => (p, Some(m)),
        Resolved::New(p) => (p, None),
    };
    let dir = match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = dest
        .file_name()
        .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file name"))?;
    remove_stale_temp_files(&dir, name);
    let prefix = temp_prefix(name, std::process::id());
    let mut builder = tempfile::Builder::new();
    builder
        .prefix(&prefix)
        .rand_bytes(TEMP_RANDOM_CHARS)
        .suffix(TEMP_SUFFIX);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Subject to the umask, as `File::create` is.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    // The error names the folder, not the temporary file's made-up name.
    if !dir.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("the directory {} does not exist", dir.display()),
        ));
    }
    let tmp = builder.tempfile_in(&dir).map_err(|e| {
        std::io::Error::new(
            e.kind(),
            format!("cannot create a file in {}: {}", dir.display(), e.kind()),
        )
    })?;
    let mut w = std::io::BufWriter::new(tmp);
    fill(&mut w)?;
    let tmp = w.into_inner().map_err(|e| e.into_error())?;
    if let Some(m) = &meta {
        tmp.as_file().set_permissions(m.permissions())?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let mine = tmp.as_file().metadata()?;
            if (mine.uid(), mine.gid()) != (m.uid(), m.gid()) {
                // Only a privileged process may give the file away; otherwise it is ours.
                let _ = std::os::unix::fs::fchown(tmp.as_file(), Some(m.uid()), Some(m.gid()));
                // fchown may clear set-id bits: restore the mode.
                tmp.as_file().set_permissions(m.permissions())?;
            }
        }
    }
    tmp.as_file().sync_all()?;
    Ok(Staged {
        path: path.to_path_buf(),
        inner: StagedInner::Rename {
            tmp,
            dest,
            existed: meta.is_some(),
        },
    })
}

impl Staged {
    /// Put the output in place: rename the temporary file over the target, or write the bytes to
    /// the non-regular target.
    pub fn commit(self) -> std::io::Result<()> {
        match self.inner {
            StagedInner::Rename { tmp, dest, .. } => {
                tmp.persist(&dest).map(drop).map_err(|e| e.error)
            }
            StagedInner::Direct { target, bytes } => {
                let mut f = open_direct(&target)?;
                f.write_all(&bytes)?;
                f.flush()
            }
        }
    }

    /// The path the output goes to (symlinks followed).
    fn created_path(&self) -> Option<&Path> {
        match &self.inner {
            StagedInner::Rename {
                dest,
                existed: false,
                ..
            } => Some(dest),
            _ => None,
        }
    }
}

fn open_direct(t: &DirectTarget) -> std::io::Result<File> {
    match t {
        DirectTarget::Path(p) => std::fs::OpenOptions::new().write(true).open(p),
        DirectTarget::Fd(fd) => dup_fd(*fd),
    }
}

#[cfg(unix)]
fn dup_fd(fd: i32) -> std::io::Result<File> {
    use std::os::fd::FromRawFd;
    // SAFETY: fcntl(F_DUPFD_CLOEXEC) returns a new descriptor we own, or -1.
    let new = unsafe { libc::fcntl(fd, libc::F_DUPFD_CLOEXEC, 0) };
    if new < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: `new` is a freshly duplicated descriptor owned by nobody else.
    Ok(unsafe { File::from_raw_fd(new) })
}

#[cfg(not(unix))]
fn dup_fd(_fd: i32) -> std::io::Result<File> {
    Err(std::io::Error::new(
        std::io::ErrorKind::Unsupported,
        "file descriptors are not supported here",
    ))
}

/// Put several staged outputs in place, in order. The outputs were all written before, so a
/// command that fails while producing them leaves none. If a rename fails here, the outputs of
/// this batch that did not exist before are removed again (a file that was replaced cannot be
/// restored). The error names the output that failed.
pub fn commit_all(staged: Vec<Staged>) -> Result<(), CommitError> {
    let mut created: Vec<PathBuf> = Vec::new();
    for s in staged {
        let new = s.created_path().map(Path::to_path_buf);
        let path = s.path.clone();
        if let Err(source) = s.commit() {
            for p in &created {
                let _ = std::fs::remove_file(p);
            }
            return Err(CommitError { path, source });
        }
        created.extend(new);
    }
    Ok(())
}

/// The failure of [`commit_all`]: which output could not be put in place, and why.
#[derive(Debug)]
pub struct CommitError {
    /// The output path, as given to [`stage_with`].
    pub path: PathBuf,
    /// The I/O error.
    pub source: std::io::Error,
}

impl std::fmt::Display for CommitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: cannot write: {}", self.path.display(), self.source)
    }
}

impl std::error::Error for CommitError {}

/// Refuse an output that is the same file as one of the inputs (same device and inode, symlinks
/// followed): writing it would destroy the input. Outputs that do not exist yet and non-regular
/// outputs (`/dev/null`, `/dev/stdout`, …) always pass. The error names both paths.
pub fn check_not_input(out: &Path, inputs: &[&Path]) -> std::io::Result<()> {
    let Ok(o) = std::fs::metadata(out) else {
        return Ok(());
    };
    if !o.is_file() {
        return Ok(());
    }
    for input in inputs {
        let Ok(i) = std::fs::metadata(input) else {
            continue;
        };
        if same_file(&o, &i) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{}: is the same file as the input {}; choose another output",
                    out.display(),
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// The files read as inputs since [`record_inputs`] (`None`: not recording).
static INPUT_LOG: std::sync::Mutex<Option<Vec<PathBuf>>> = std::sync::Mutex::new(None);

fn input_log() -> std::sync::MutexGuard<'static, Option<Vec<PathBuf>>> {
    INPUT_LOG
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Start noting the files this process reads as inputs (module docs, "The input log"); from
/// then on no write replaces one of them. Calling it again forgets what was noted.
pub fn record_inputs() {
    *input_log() = Some(Vec::new());
}

/// Note `path` as an input of the running command, when [`record_inputs`] is on (otherwise
/// nothing). Readers of input files call it before reading.
pub fn note_input(path: &Path) {
    if let Some(log) = input_log().as_mut() {
        if !log.iter().any(|p| p == path) {
            log.push(path.to_path_buf());
        }
    }
}

/// The inputs noted so far (empty when not recording).
#[must_use]
pub fn recorded_inputs() -> Vec<PathBuf> {
    input_log().clone().unwrap_or_default()
}

/// [`check_not_input`] against the noted inputs ([`record_inputs`]).
pub fn check_not_recorded_input(out: &Path) -> std::io::Result<()> {
    let inputs = recorded_inputs();
    let refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    check_not_input(out, &refs)
}

#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(_a: &std::fs::Metadata, _b: &std::fs::Metadata) -> bool {
    false
}

/// Read at most `limit` bytes of `path`, counting the bytes actually read (not the size the file
/// system reports, which is 0 for `/dev/zero`, FIFOs and `/proc` files). A longer file is an
/// error of kind [`std::io::ErrorKind::FileTooLarge`] whose message gives the limit.
pub fn read_limited(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    note_input(path);
    read_limited_unnoted(path, limit)
}

/// [`read_limited`] of a file that is not an input of the command (a cache entry, which the
/// command may write again): not noted in the input log.
pub fn read_limited_unnoted(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let f = File::open(path)?;
    if let Ok(m) = f.metadata() {
        if m.is_file() && m.len() > limit {
            return Err(too_large(limit));
        }
    }
    let mut bytes = Vec::new();
    f.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(limit));
    }
    Ok(bytes)
}

/// The error of a file longer than `limit` bytes (see [`read_limited`]).
pub fn too_large(limit: u64) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::FileTooLarge,
        format!("larger than the limit of {limit} bytes"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Long names are cut to the same stem on both sides.
    #[test]
    fn a_missing_folder_is_named_not_the_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("nodir/sub/x.map");
        let e = write_atomic(&target, b"bytes").unwrap_err();
        let msg = e.to_string();
        assert_eq!(e.kind(), std::io::ErrorKind::NotFound);
        assert!(msg.contains("does not exist"), "{msg}");
        assert!(msg.contains("nodir/sub"), "{msg}");
        assert!(!msg.contains(TEMP_MARK) && !msg.contains(".x.map"), "{msg}");
        assert!(!dir.path().join("nodir").exists());
    }

    #[test]
    fn long_names_give_the_same_stem_to_writer_and_cleaner() {
        let long = "x".repeat(250);
        let prefix = temp_prefix(long.as_ref(), 7);
        let name = format!("{}abcdef.tmp", prefix.to_string_lossy());
        assert!(name.len() < 255);
        assert_eq!(temp_file_pid(name.as_ref(), long.as_ref()), Some(7));
    }
}
