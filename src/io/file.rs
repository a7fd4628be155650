//! Safe file output, with the semantics of `install`/`tempfile`'s persist:
//!
//! - a regular file (or a path that does not exist yet) is written to a temporary file in the
//!   target's own directory — an anonymous `O_TMPFILE` where the filesystem supports it, so a
//!   killed run leaves nothing behind — given the target's permissions, synced, and renamed over
//!   the target: readers see the old file or the new one, never a part;
//! - a symlink's target is what gets written (atomically, in the target's directory); the link
//!   stays;
//! - a device, FIFO, socket, `/dev/stdout` or anything reached through `/dev` or `/proc` is
//!   written directly, never renamed over; `-` is stdout;
//! - temporary names carry the writer's PID (`.NAME.biasctl-PID-N.tmp`,
//!   `.DIR.biasctl-partial-PID-N`); every later write into the same directory removes those
//!   whose process is gone ([`sweep_stale`]).

use super::OutputError;
use super::fault::Faulty;
use super::stdout::{map_stdout_error, stdout_sink};
use std::fmt::Display;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes temporary names made by one process (several threads may write at once).
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Marker in every temporary name biasctl makes; [`sweep_stale`] removes only such names.
const MARK: &str = ".biasctl-";

/// Where a [`Sink`]'s bytes go.
enum Dest {
    File(File),
    Stdout(io::Stdout),
}

impl Write for Dest {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Dest::File(f) => f.write(buf),
            Dest::Stdout(s) => s.write(buf),
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        match self {
            Dest::File(f) => f.flush(),
            Dest::Stdout(s) => s.flush(),
        }
    }
}

/// The writer a producer of [`write_atomic`] fills: buffered; refusing a non-finite number
/// (a whole word `NaN` or `inf`, as Rust formats them, across write calls) with an
/// `InvalidData` error; failing at the injected byte when a fault is armed
/// (`with_write_fault`).
pub struct Sink {
    inner: BufWriter<Faulty<Dest>>,
    words: WordGuard,
}

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.words.scan(buf)?;
        self.inner.write_all(buf)?;
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        self.words.end()?;
        self.inner.flush()
    }
}

impl Sink {
    fn new(dest: Dest) -> Self {
        Sink {
            inner: BufWriter::new(Faulty::armed(dest)),
            words: WordGuard::default(),
        }
    }
}

/// Finds the words `NaN` and `inf` in a byte stream cut into arbitrary pieces.
#[derive(Default)]
pub(crate) struct WordGuard {
    /// The current word's first bytes (only words of 3 bytes matter).
    word: [u8; 3],
    /// The current word's length so far.
    len: usize,
}

impl WordGuard {
    /// Scans the next piece of the stream.
    pub(crate) fn scan(&mut self, buf: &[u8]) -> io::Result<()> {
        // Fast path: a bad word starts with `N` or `i`. When the piece holds neither byte and
        // the word carried in does not start with one, no bad word ends in this piece; only the
        // word the piece ends in is carried on (its first bytes, and its length).
        let carried_may_be_bad = self.len > 0 && matches!(self.word[0], b'N' | b'i');
        if !carried_may_be_bad && memchr::memchr2(b'N', b'i', buf).is_none() {
            let is_word = |b: &u8| b.is_ascii_alphanumeric() || *b == b'_';
            let tail = buf.iter().rev().take_while(|b| is_word(b)).count();
            if tail < buf.len() {
                self.len = 0;
            }
            for &b in &buf[buf.len() - tail..] {
                if self.len < 3 {
                    self.word[self.len] = b;
                }
                self.len += 1;
            }
            return Ok(());
        }
        self.scan_slow(buf)
    }

    /// [`WordGuard::scan`] byte by byte (the reference the fast path is tested against).
    fn scan_slow(&mut self, buf: &[u8]) -> io::Result<()> {
        for &b in buf {
            if b.is_ascii_alphanumeric() || b == b'_' {
                if self.len < 3 {
                    self.word[self.len] = b;
                }
                self.len += 1;
            } else {
                self.end()?;
            }
        }
        Ok(())
    }

    /// Ends the current word (at a separator or the end of the stream).
    pub(crate) fn end(&mut self) -> io::Result<()> {
        let bad = self.len == 3 && matches!(&self.word, b"NaN" | b"inf");
        self.len = 0;
        if bad {
            let value = if self.word[0] == b'N' {
                f64::NAN
            } else {
                f64::INFINITY
            };
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                super::NonFinite {
                    what: "a number in the output".to_string(),
                    value,
                },
            ));
        }
        Ok(())
    }
}

/// Writes `path` safely (see the module docs): `produce` writes into a buffered [`Sink`]; the
/// result replaces `path` only if `produce`, the flush and the sync succeed. On any error no
/// temporary file remains and a regular `path` is left as it was.
///
/// The producer returns `Result<(), E>` with any error type that converts to a message, so that a
/// domain error inside the producer also aborts the write.
pub fn write_atomic<E, F>(path: &Path, produce: F) -> Result<(), OutputError>
where
    E: Display,
    F: FnOnce(&mut Sink) -> Result<(), E>,
{
    let io_err = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    if path.as_os_str() == "-" {
        return write_direct(path, Dest::Stdout(stdout_sink()), produce);
    }
    refuse_protected("the output", path)?;
    let (target, special) = resolve(path).map_err(io_err)?;
    if special && is_own_stdout(&target) {
        return write_direct(path, Dest::Stdout(stdout_sink()), produce);
    }
    match fs::metadata(&target) {
        Ok(m) if m.is_dir() => Err(io_err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a folder; give a file name",
        ))),
        Ok(m) if !m.is_file() || special => {
            let file = OpenOptions::new()
                .write(true)
                .truncate(m.is_file())
                .open(&target)
                .map_err(io_err)?;
            write_direct(path, Dest::File(file), produce)
        }
        Ok(m) => replace(path, &target, Some(m.permissions()), produce),
        Err(e) if e.kind() == io::ErrorKind::NotFound => replace(path, &target, None, produce),
        Err(e) => Err(io_err(e)),
    }
}

/// Writes a whole string safely (see [`write_atomic`]).
pub fn write_string_atomic(path: &Path, text: &str) -> Result<(), OutputError> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// Follows the symlinks of `path` (at most 40, as the kernel does) to the file that would be
/// written; `special` is whether the path or a link on the way lies in `/dev` or `/proc`.
fn resolve(path: &Path) -> io::Result<(PathBuf, bool)> {
    let mut p = path.to_path_buf();
    let mut special = false;
    for _ in 0..40 {
        special |= p.starts_with("/dev") || p.starts_with("/proc");
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = fs::read_link(&p)?;
                p = if link.is_absolute() {
                    link
                } else {
                    parent_of(&p).join(link)
                };
            }
            _ => return Ok((p, special)),
        }
    }
    Err(io::Error::other("too many levels of symbolic links"))
}

/// Whether `target` is this process's own stdout (`/dev/stdout`, `/proc/self/fd/1`, or a link
/// chain that ends at the same open file).
fn is_own_stdout(target: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let (Ok(t), Ok(o)) = (fs::metadata(target), fs::metadata("/proc/self/fd/1")) else {
            return target == Path::new("/dev/stdout");
        };
        (t.dev(), t.ino()) == (o.dev(), o.ino())
    }
    #[cfg(not(unix))]
    {
        target == Path::new("/dev/stdout")
    }
}

/// The directory holding `p` (`.` for a bare name).
fn parent_of(p: &Path) -> PathBuf {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Writes into a device, FIFO or stdout: no temporary file, no rename.
fn write_direct<E, F>(path: &Path, dest: Dest, produce: F) -> Result<(), OutputError>
where
    E: Display,
    F: FnOnce(&mut Sink) -> Result<(), E>,
{
    let to_stdout = matches!(dest, Dest::Stdout(_));
    let io_err = |source: io::Error| {
        if to_stdout {
            map_stdout_error(source)
        } else {
            OutputError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    };
    let mut sink = Sink::new(dest);
    if let Err(e) = produce(&mut sink) {
        // An I/O error surfaced inside the producer is still a write error of this target.
        let message = e.to_string();
        if to_stdout && message.contains("Broken pipe") {
            return Err(OutputError::BrokenPipe);
        }
        return Err(OutputError::Producer {
            path: path.to_path_buf(),
            message,
        });
    }
    sink.flush().map_err(io_err)
}

/// A temporary file in `dir` that becomes `target` by [`Temp::persist`].
struct Temp {
    file: File,
    /// The temporary name, once the file has one (always for the named fallback).
    named: Option<PathBuf>,
    dir: PathBuf,
    stem: String,
}

impl Temp {
    /// An anonymous `O_TMPFILE` in `dir` where supported, else a new uniquely named file.
    fn create(dir: &Path, stem: &str) -> io::Result<Temp> {
        #[cfg(target_os = "linux")]
        {
            use std::os::unix::fs::OpenOptionsExt;
            match OpenOptions::new()
                .write(true)
                .read(true)
                .custom_flags(libc::O_TMPFILE)
                .mode(0o666)
                .open(dir)
            {
                Ok(file) => {
                    return Ok(Temp {
                        file,
                        named: None,
                        dir: dir.to_path_buf(),
                        stem: stem.to_string(),
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::PermissionDenied => return Err(e),
                Err(_) => {} // not supported here: fall back to a named file
            }
        }
        let name = temp_name(dir, stem, "tmp");
        let file = new_file(&name)?;
        Ok(Temp {
            file,
            named: Some(name),
            dir: dir.to_path_buf(),
            stem: stem.to_string(),
        })
    }

    /// Gives the temporary file a name (if anonymous) and renames it over `target`.
    fn persist(mut self, target: &Path) -> io::Result<()> {
        if self.named.is_none() {
            let name = temp_name(&self.dir, &self.stem, "tmp");
            link_anonymous(&self.file, &name).or_else(|_| {
                // No /proc to link through: copy into a named file instead.
                use std::io::Seek;
                let mut copy = new_file(&name)?;
                self.file.seek(io::SeekFrom::Start(0))?;
                io::copy(&mut self.file, &mut copy)?;
                copy.set_permissions(self.file.metadata()?.permissions())?;
                copy.sync_all()
            })?;
            self.named = Some(name);
        }
        let name = self.named.take().unwrap_or_default();
        fs::rename(&name, target).inspect_err(|_| {
            let _ = fs::remove_file(&name);
        })?;
        // Best effort: make the rename itself durable.
        if let Ok(d) = File::open(&self.dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        if let Some(name) = &self.named {
            let _ = fs::remove_file(name);
        }
    }
}

/// Links an `O_TMPFILE` into the filesystem at `name`.
#[cfg(target_os = "linux")]
fn link_anonymous(file: &File, name: &Path) -> io::Result<()> {
    use std::os::unix::ffi::OsStrExt;
    use std::os::unix::io::AsRawFd;
    let from = std::ffi::CString::new(format!("/proc/self/fd/{}", file.as_raw_fd()))
        .map_err(io::Error::other)?;
    let to = std::ffi::CString::new(name.as_os_str().as_bytes()).map_err(io::Error::other)?;
    // SAFETY: both are valid NUL-terminated paths; AT_FDCWD and AT_SYMLINK_FOLLOW are valid
    // arguments of linkat(2).
    let rc = unsafe {
        libc::linkat(
            libc::AT_FDCWD,
            from.as_ptr(),
            libc::AT_FDCWD,
            to.as_ptr(),
            libc::AT_SYMLINK_FOLLOW,
        )
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

#[cfg(not(target_os = "linux"))]
fn link_anonymous(_file: &File, _name: &Path) -> io::Result<()> {
    Err(io::Error::other("no O_TMPFILE"))
}

/// A new file at `name` (it must not exist), mode 0666 less the umask.
fn new_file(name: &Path) -> io::Result<File> {
    OpenOptions::new()
        .write(true)
        .read(true)
        .create_new(true)
        .open(name)
}

/// `.STEM.biasctl-PID-N.EXT` in `dir`.
fn temp_name(dir: &Path, stem: &str, ext: &str) -> PathBuf {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    dir.join(format!(".{stem}{MARK}{}-{n}.{ext}", std::process::id()))
}

/// Writes a regular file (or a new one) by a temporary file in its directory and a rename.
fn replace<E, F>(
    path: &Path,
    target: &Path,
    perms: Option<fs::Permissions>,
    produce: F,
) -> Result<(), OutputError>
where
    E: Display,
    F: FnOnce(&mut Sink) -> Result<(), E>,
{
    let io_err = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = parent_of(target);
    sweep_stale(&dir);
    let stem = stem_of(target);
    let temp = Temp::create(&dir, &stem).map_err(io_err)?;
    let mut sink = Sink::new(Dest::File(temp.file.try_clone().map_err(io_err)?));
    if let Err(e) = produce(&mut sink) {
        return Err(OutputError::Producer {
            path: path.to_path_buf(),
            message: e.to_string(),
        });
    }
    sink.flush().map_err(io_err)?;
    drop(sink);
    if let Some(p) = perms {
        temp.file.set_permissions(p).map_err(io_err)?;
    }
    temp.file.sync_all().map_err(io_err)?;
    temp.persist(target).map_err(io_err)
}

/// The file name of `p` for temporary names (`output` if it has none).
fn stem_of(p: &Path) -> String {
    p.file_name()
        .map_or("output".into(), |n| n.to_string_lossy().into_owned())
}

/// Removes, in `dir`, the temporary files and staging folders biasctl made
/// (`.NAME.biasctl-PID-N.tmp`, `.NAME.biasctl-partial-PID-N`) whose process no longer runs:
/// what a killed run left behind. Best effort; names of running processes are kept.
pub(crate) fn sweep_stale(dir: &Path) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = stale_pid(&name.to_string_lossy()) else {
            continue;
        };
        if pid == std::process::id() || process_alive(pid) {
            continue;
        }
        let p = entry.path();
        let _ = match entry.file_type() {
            Ok(t) if t.is_dir() => fs::remove_dir_all(&p),
            _ => fs::remove_file(&p),
        };
    }
}

/// The PID in a temporary name biasctl made, if `name` is one.
fn stale_pid(name: &str) -> Option<u32> {
    if !name.starts_with('.') {
        return None;
    }
    let at = name.rfind(MARK)?;
    let rest = &name[at + MARK.len()..];
    let rest = rest.strip_prefix("partial-").unwrap_or(rest);
    let rest = rest.strip_suffix(".tmp").unwrap_or(rest);
    let (pid, n) = rest.split_once('-')?;
    if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Whether a process with this PID exists.
fn process_alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else {
            return false;
        };
        // SAFETY: kill with signal 0 only checks for existence and permission.
        let rc = unsafe { libc::kill(pid, 0) };
        rc == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// A multi-file output (a report folder, `diagnose --out`): files are written into a staging
/// folder beside `dir` (`.NAME.biasctl-partial-PID-N`) and moved into `dir` by
/// [`StagedDir::commit`] only when the whole run succeeded — `dir` is created by renaming the
/// staging folder if it did not exist, else each file replaces its namesake and other files are
/// left alone. Dropped uncommitted, the staging folder is removed.
pub(crate) struct StagedDir {
    dir: PathBuf,
    stage: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Creates the staging folder for `dir`; refuses a `dir` that is a file.
    pub(crate) fn create(dir: &Path) -> Result<StagedDir, OutputError> {
        let io_err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| OutputError::Io { path, source }
        };
        if dir.exists() && !dir.is_dir() {
            return Err(OutputError::Io {
                path: dir.to_path_buf(),
                source: io::Error::new(
                    io::ErrorKind::AlreadyExists,
                    "is a file; this output needs a folder",
                ),
            });
        }
        let parent = parent_of(dir);
        fs::create_dir_all(&parent).map_err(io_err(&parent))?;
        sweep_stale(&parent);
        let stage = parent.join(format!(
            ".{}{MARK}partial-{}-{}",
            stem_of(dir),
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        fs::create_dir(&stage).map_err(io_err(&stage))?;
        Ok(StagedDir {
            dir: dir.to_path_buf(),
            stage,
            committed: false,
        })
    }

    /// Where a file of the output is written now (inside the staging folder).
    pub(crate) fn path(&self, name: &str) -> PathBuf {
        self.stage.join(name)
    }

    /// The staging folder files are written into until [`StagedDir::commit`].
    pub(crate) fn stage(&self) -> &Path {
        &self.stage
    }

    /// Moves every staged file into the final folder and removes the staging folder. Every
    /// destination is checked before anything moves, so a blocked one leaves `dir` as it was.
    pub(crate) fn commit(mut self) -> Result<(), OutputError> {
        let io_err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| OutputError::Io { path, source }
        };
        if !self.dir.exists() && fs::rename(&self.stage, &self.dir).is_ok() {
            self.committed = true;
            return Ok(());
        }
        fs::create_dir_all(&self.dir).map_err(io_err(&self.dir))?;
        let mut moves = Vec::new();
        for entry in fs::read_dir(&self.stage).map_err(io_err(&self.stage))? {
            let from = entry.map_err(io_err(&self.stage))?.path();
            if let Some(name) = from.file_name() {
                moves.push((from.clone(), self.dir.join(name)));
            }
        }
        if let Some((_, to)) = moves.iter().find(|(_, to)| to.is_dir()) {
            return Err(OutputError::Io {
                path: to.clone(),
                source: io::Error::new(
                    io::ErrorKind::AlreadyExists,
                    "a folder of that name is in the way; nothing was written",
                ),
            });
        }
        for (_, to) in &moves {
            refuse_protected(&format!("a file of {}", self.dir.display()), to)?;
        }
        for (from, to) in &moves {
            fs::rename(from, to).map_err(io_err(to))?;
        }
        fs::remove_dir(&self.stage).map_err(io_err(&self.stage))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.stage);
        }
    }
}

/// The inputs of this run ([`protect_inputs`]): no write may replace one of them.
static PROTECTED: std::sync::Mutex<Vec<(String, PathBuf)>> = std::sync::Mutex::new(Vec::new());

/// Registers the input files of this run (each with its role, e.g. the flag `--data`): from
/// then on [`write_atomic`] and [`StagedDir::commit`] refuse to replace any of them with
/// [`OutputError::SamePath`], nothing written. This covers outputs whose names are known only
/// after the run (a report's or `diagnose --out`'s files inside a folder); outputs known before
/// the run are compared up front by [`check_paths`], which registers its inputs too.
#[cfg_attr(not(feature = "cli"), allow(dead_code))] // used by the CLI only
pub(crate) fn protect_inputs(inputs: &[(&str, &Path)]) {
    if let Ok(mut list) = PROTECTED.lock() {
        list.extend(inputs.iter().map(|(r, p)| (r.to_string(), p.to_path_buf())));
    }
}

/// [`OutputError::SamePath`] if `path` names a file registered by [`protect_inputs`].
fn refuse_protected(role: &str, path: &Path) -> Result<(), OutputError> {
    let Some(id) = identity(path, true) else {
        return Ok(());
    };
    let list = PROTECTED.lock().map_err(|_| OutputError::Io {
        path: path.to_path_buf(),
        source: io::Error::other("the list of inputs is poisoned"),
    })?;
    // Identities are taken now, not when registered: a deleted input's inode may be reused.
    match list
        .iter()
        .find(|(_, input)| identity(input, false).as_ref() == Some(&id))
    {
        Some((in_role, _)) => Err(OutputError::SamePath {
            first: in_role.clone(),
            second: role.to_string(),
            path: path.to_path_buf(),
            why: "the output would replace the input; write to another file",
        }),
        None => Ok(()),
    }
}

/// What identifies the file a path names, for [`check_paths`].
#[derive(PartialEq, Eq)]
enum Identity {
    /// An existing regular file: device and inode (so links and `a/../b` spellings match).
    Inode(u64, u64),
    /// A file that does not exist yet: its canonical directory and name.
    New(PathBuf),
    /// Standard output (`-`).
    Stdout,
}

/// The identity of `path`; `None` for what cannot be clobbered by a rename (devices, FIFOs,
/// folders, stdin) or what does not resolve (the read or write reports that later).
fn identity(path: &Path, is_output: bool) -> Option<Identity> {
    if path.as_os_str() == "-" {
        return is_output.then_some(Identity::Stdout);
    }
    match fs::metadata(path) {
        Ok(m) if m.is_file() => {
            #[cfg(unix)]
            {
                use std::os::unix::fs::MetadataExt;
                Some(Identity::Inode(m.dev(), m.ino()))
            }
            #[cfg(not(unix))]
            {
                fs::canonicalize(path).ok().map(Identity::New)
            }
        }
        Ok(_) => None,
        Err(_) => {
            let (target, _) = resolve(path).ok()?;
            let dir = fs::canonicalize(parent_of(&target)).ok()?;
            Some(Identity::New(dir.join(target.file_name()?)))
        }
    }
}

/// Refuses, before anything runs, an output that names the same file as an input (it would be
/// replaced before or while it is read) or as another output (the last would win). Each path
/// comes with its role (the CLI passes the flag, e.g. `--out`), which the error names. Files are
/// compared by device and inode, new paths by canonical directory and name; devices and FIFOs
/// (`/dev/null` twice) are allowed. The inputs are also registered by `protect_inputs`.
#[cfg_attr(not(feature = "cli"), allow(dead_code))] // used by the CLI only
pub(crate) fn check_paths(
    inputs: &[(&str, &Path)],
    outputs: &[(&str, &Path)],
) -> Result<(), OutputError> {
    protect_inputs(inputs);
    let ins: Vec<_> = inputs
        .iter()
        .map(|(r, p)| (*r, *p, identity(p, false)))
        .collect();
    let outs: Vec<_> = outputs
        .iter()
        .map(|(r, p)| (*r, *p, identity(p, true)))
        .collect();
    for (i, (role, path, id)) in outs.iter().enumerate() {
        let Some(id) = id else { continue };
        if let Some((in_role, ..)) = ins.iter().find(|(_, _, other)| other.as_ref() == Some(id)) {
            return Err(OutputError::SamePath {
                first: in_role.to_string(),
                second: role.to_string(),
                path: path.to_path_buf(),
                why: "the output would replace the input; write to another file",
            });
        }
        if let Some((other_role, ..)) = outs[..i]
            .iter()
            .find(|(_, _, other)| other.as_ref() == Some(id))
        {
            return Err(OutputError::SamePath {
                first: other_role.to_string(),
                second: role.to_string(),
                path: path.to_path_buf(),
                why: "two outputs cannot share one file; give each its own",
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::fault::with_write_fault;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    /// Reference: the byte-by-byte scan. Streams of numbers and near-miss words (`Nan`, `info`,
    /// `xinf`, `NaN_`, `NaNs`) with the bad words among them, cut into random pieces: the fast
    /// scan fails at the same piece (or at the end) as the slow one, or neither fails.
    #[test]
    fn fast_word_guard_agrees_with_the_byte_by_byte_scan() {
        use crate::numeric::rng::SimRng;
        let tokens: [&[u8]; 14] = [
            b"1.25",
            b"-0.5",
            b"NaN",
            b"inf",
            b"-inf",
            b"Nan",
            b"info",
            b"xinf",
            b"NaN_",
            b"NaNs",
            b"time_s",
            b"in",
            b"N",
            b"12345678901234567890",
        ];
        let seps: [&[u8]; 4] = [b",", b"\n", b"", b" "];
        let mut rng = SimRng::new(5);
        let mut failures = 0;
        for _ in 0..20_000 {
            let mut text = Vec::new();
            for _ in 0..1 + rng.below(12) {
                text.extend_from_slice(tokens[rng.below(tokens.len() as u64) as usize]);
                text.extend_from_slice(seps[rng.below(seps.len() as u64) as usize]);
            }
            let (mut fast, mut slow) = (WordGuard::default(), WordGuard::default());
            let (mut at_fast, mut at_slow) = (None, None);
            let mut start = 0;
            let mut piece = 0;
            while start < text.len() {
                let end = (start + 1 + rng.below(6) as usize).min(text.len());
                if at_fast.is_none() && fast.scan(&text[start..end]).is_err() {
                    at_fast = Some(piece);
                }
                if at_slow.is_none() && slow.scan_slow(&text[start..end]).is_err() {
                    at_slow = Some(piece);
                }
                start = end;
                piece += 1;
            }
            if at_fast.is_none() && fast.end().is_err() {
                at_fast = Some(piece);
            }
            if at_slow.is_none() && slow.end().is_err() {
                at_slow = Some(piece);
            }
            assert_eq!(at_fast, at_slow, "{}", String::from_utf8_lossy(&text));
            failures += usize::from(at_slow.is_some());
        }
        assert!(failures > 1000, "{failures}");
    }

    #[test]
    fn failed_producer_leaves_no_file_and_keeps_old_content() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        write_string_atomic(&path, "old").unwrap();
        let res = write_atomic(&path, |w| {
            w.write_all(b"half").map_err(|e| e.to_string())?;
            Err::<(), _>("bad value on line 3".to_string())
        });
        assert!(matches!(res, Err(OutputError::Producer { .. })));
        assert_eq!(fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(names(dir.path()), ["out.csv"], "temporary file left behind");
    }

    #[test]
    fn injected_write_faults_at_every_byte_keep_the_old_file_and_leave_nothing() {
        // Reference: the old content, byte for byte, and a directory listing of one file.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        write_string_atomic(&path, "old,content\n").unwrap();
        let text = "a,b\n".repeat(3000); // 12 kB: more than the 8 kB buffer
        for at in [0, 1, 4095, 8192, 11_999] {
            for errno in [libc::ENOSPC, libc::EIO] {
                let r = with_write_fault(at, errno, || write_string_atomic(&path, &text));
                let e = r.expect_err("the fault must surface").to_string();
                let os = io::Error::from_raw_os_error(errno).to_string();
                assert!(e.contains(&os) && e.contains("t.csv"), "{e}");
                assert_eq!(fs::read_to_string(&path).unwrap(), "old,content\n");
                assert_eq!(names(dir.path()), ["t.csv"]);
            }
        }
        // Beyond the last byte the fault never fires.
        with_write_fault(12_000, libc::EIO, || write_string_atomic(&path, &text)).unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), text);
    }

    #[cfg(unix)]
    #[test]
    fn permissions_are_kept_and_a_symlink_target_is_written() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.csv");
        fs::write(&real, "old").unwrap();
        fs::set_permissions(&real, fs::Permissions::from_mode(0o600)).unwrap();
        let link = dir.path().join("link.csv");
        std::os::unix::fs::symlink("real.csv", &link).unwrap();
        write_string_atomic(&link, "new").unwrap();
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read_to_string(&real).unwrap(), "new");
        let mode = fs::metadata(&real).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        fs::set_permissions(&real, fs::Permissions::from_mode(0o444)).unwrap();
        write_string_atomic(&real, "newer").unwrap();
        let mode = fs::metadata(&real).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o444);
        assert_eq!(names(dir.path()), ["link.csv", "real.csv"]);
    }

    #[cfg(unix)]
    #[test]
    fn a_device_is_written_directly_never_replaced() {
        // /dev/null accepts everything; /dev/full fails with ENOSPC — and both stay devices.
        write_string_atomic(Path::new("/dev/null"), "x").unwrap();
        if Path::new("/dev/full").exists() {
            let e = write_string_atomic(Path::new("/dev/full"), "x").unwrap_err();
            assert!(e.to_string().contains("/dev/full"), "{e}");
        }
        assert!(!fs::metadata("/dev/null").unwrap().is_file());
    }

    #[test]
    fn stale_temporaries_of_dead_processes_are_swept_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        // PID 0x7fff_fff0 does not exist (above pid_max); our own PID is alive.
        let dead = format!(".out.csv{MARK}{}-3.tmp", 0x7fff_fff0u32);
        let dead_dir = format!(".rep{MARK}partial-{}-0", 0x7fff_fff0u32);
        let live = format!(".out.csv{MARK}{}-3.tmp", std::process::id());
        let user = ".notes.123.tmp".to_string();
        fs::write(dir.path().join(&dead), "x").unwrap();
        fs::create_dir(dir.path().join(&dead_dir)).unwrap();
        fs::write(dir.path().join(&live), "x").unwrap();
        fs::write(dir.path().join(&user), "x").unwrap();
        sweep_stale(dir.path());
        let mut want = vec![live, user];
        want.sort();
        assert_eq!(names(dir.path()), want);
    }

    #[test]
    fn same_file_as_input_or_as_another_output_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        fs::write(&a, "x").unwrap();
        let dotted = dir.path().join(".").join("a.csv");
        let e = check_paths(&[("--data", &a)], &[("--out", &dotted)]).unwrap_err();
        assert!(e.to_string().contains("--data and --out"), "{e}");
        let n = dir.path().join("new.csv");
        let e = check_paths(
            &[],
            &[("--out", &n), ("--truth", &dir.path().join("./new.csv"))],
        )
        .unwrap_err();
        assert!(e.to_string().contains("--out and --truth"), "{e}");
        check_paths(&[("--data", &a)], &[("--out", &n)]).unwrap();
        check_paths(
            &[],
            &[
                ("--out", Path::new("/dev/null")),
                ("--truth", Path::new("/dev/null")),
            ],
        )
        .unwrap();
        let dash = Path::new("-");
        assert!(check_paths(&[], &[("--out", dash), ("--truth", dash)]).is_err());
    }

    #[test]
    fn staged_dir_moves_in_only_on_commit() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("rep");
        {
            let s = StagedDir::create(&out).unwrap();
            write_string_atomic(&s.path("a.txt"), "a").unwrap();
        }
        assert_eq!(names(dir.path()), Vec::<String>::new());
        let s = StagedDir::create(&out).unwrap();
        write_string_atomic(&s.path("a.txt"), "a").unwrap();
        s.commit().unwrap();
        assert_eq!(names(&out), ["a.txt"]);
        let s = StagedDir::create(&out).unwrap();
        write_string_atomic(&s.path("b.txt"), "b").unwrap();
        s.commit().unwrap();
        assert_eq!(names(&out), ["a.txt", "b.txt"]);
        assert_eq!(names(dir.path()), ["rep"]);
    }
}
