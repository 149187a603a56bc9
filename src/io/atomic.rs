//! Outputs that never destroy anything: every file a command writes goes
//! through an [`OutputSet`].
//!
//! - **Whole files or nothing.** Each output is written under a temporary
//!   name beside its destination (`.NAME.slam2world-tmp-PID-N`, recognisable,
//!   so that a later run removes those a killed run left behind) and renamed
//!   over the final name only when [`OutputSet::commit`] is reached, after
//!   every output of the set was written. A failure, an interruption
//!   (SIGINT/SIGTERM, see [`crate::interrupt`]) or a disk-full error before
//!   that removes the temporary files and leaves the previous outputs as
//!   they were.
//! - **Inputs are never outputs.** An output that resolves to the same file
//!   as an input of the run (same device and inode: hard links, symbolic
//!   links and `..` included), or into an input folder, is refused before
//!   anything is written.
//! - **Special files are not replaced.** A FIFO or a character device
//!   (`/dev/null`, `/dev/stdout`) is opened and written through, never
//!   renamed over; a symbolic link is followed and its target replaced (the
//!   link stays a link); a folder, a block device or a socket is refused.
//! - **A set replaces a set.** [`OutputSet::folder`] knows every name the
//!   command may write into its folder: on commit, the names this run did not
//!   produce are removed (a stale `map.bt` does not survive a run without an
//!   octree), and [`Committed::removed`] lists them.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// What every temporary name holds: `.NAME` + this + `PID-N`.
pub const TEMP_MARK: &str = ".slam2world-tmp-";

/// Where one output's bytes go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Destination {
    /// A regular file, or nothing yet, at this path (a symbolic link's
    /// target): written under a temporary name and renamed.
    Replace(PathBuf),
    /// A FIFO or a character device: opened and written through.
    Through(PathBuf),
}

impl Destination {
    /// The path the bytes end up at.
    pub fn path(&self) -> &Path {
        match self {
            Destination::Replace(p) | Destination::Through(p) => p,
        }
    }
}

fn refuse(path: &Path, reason: impl Into<String>) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Where writing `path` would put the bytes: symbolic links followed (up to
/// 40, as the kernel does), FIFOs and character devices written through,
/// folders, block devices and sockets refused.
pub fn destination(path: &Path) -> Result<Destination> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        let meta = match std::fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok(Destination::Replace(normalized(&p)));
            }
            Err(e) => return Err(Error::io(&p, e)),
        };
        let t = meta.file_type();
        if t.is_symlink() {
            let target = std::fs::read_link(&p).map_err(|e| Error::io(&p, e))?;
            p = match p.parent() {
                Some(dir) if target.is_relative() => dir.join(target),
                _ => target,
            };
            continue;
        }
        if t.is_file() {
            return Ok(Destination::Replace(normalized(&p)));
        }
        if t.is_dir() {
            return Err(refuse(path, "is a folder, not a file (name a file in it)"));
        }
        return match special(&meta) {
            Special::WriteThrough => Ok(Destination::Through(p)),
            Special::Refused(kind) => Err(refuse(
                path,
                format!("is a {kind}: not written (not a regular file)"),
            )),
        };
    }
    Err(refuse(path, "too many levels of symbolic links"))
}

/// `path` with its folder made canonical (links and `..` resolved), its last
/// component kept: two spellings of one output give one path.
fn normalized(path: &Path) -> PathBuf {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return path.to_path_buf();
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    match std::fs::canonicalize(dir) {
        Ok(d) => d.join(name),
        Err(_) => path.to_path_buf(),
    }
}

enum Special {
    WriteThrough,
    Refused(&'static str),
}

#[cfg(unix)]
fn special(meta: &std::fs::Metadata) -> Special {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_fifo() || t.is_char_device() {
        Special::WriteThrough
    } else if t.is_block_device() {
        Special::Refused("block device")
    } else if t.is_socket() {
        Special::Refused("socket")
    } else {
        Special::Refused("special file")
    }
}

#[cfg(not(unix))]
fn special(_meta: &std::fs::Metadata) -> Special {
    Special::Refused("special file")
}

/// True when writing `a` and writing `b` would write one file (the same
/// destination, or two names of one existing file).
pub fn same_output(a: &Path, b: &Path) -> Result<bool> {
    let (da, db) = (destination(a)?, destination(b)?);
    if da.path() == db.path() {
        return Ok(true);
    }
    Ok(matches!((identity(da.path()), identity(db.path())), (Some(x), Some(y)) if x == y))
}

/// The identity of an existing file: device and inode (Unix), else its
/// canonical path.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Identity {
    #[cfg(unix)]
    id: (u64, u64),
    #[cfg(not(unix))]
    id: PathBuf,
    dir: bool,
}

/// The identity of `path` (following links) without opening it (a FIFO would block).
fn identity(path: &Path) -> Option<Identity> {
    let meta = std::fs::metadata(path).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some(Identity {
            id: (meta.dev(), meta.ino()),
            dir: meta.is_dir(),
        })
    }
    #[cfg(not(unix))]
    {
        Some(Identity {
            id: std::fs::canonicalize(path).ok()?,
            dir: meta.is_dir(),
        })
    }
}

/// One input of the run, as given and as found.
#[derive(Clone, Debug)]
struct Input {
    path: PathBuf,
    id: Identity,
}

/// A temporary file written and waiting for its rename; removed when dropped
/// before that.
#[derive(Debug)]
struct Staged {
    tmp: PathBuf,
    target: PathBuf,
    given: PathBuf,
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// The outputs of one run (see the module documentation): added one by one,
/// published together by [`OutputSet::commit`]; dropping the set before
/// that removes every temporary file.
#[derive(Debug, Default)]
pub struct OutputSet {
    folder: Option<(PathBuf, Vec<String>)>,
    inputs: Vec<Input>,
    staged: Vec<Staged>,
    through: Vec<PathBuf>,
    cleaned: Vec<PathBuf>,
}

/// What [`OutputSet::commit`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Committed {
    /// The outputs written, as given (in the order they were added).
    pub written: Vec<PathBuf>,
    /// Outputs of an earlier run in the set's folder that this run did not
    /// produce, removed.
    pub removed: Vec<PathBuf>,
}

static COUNTER: AtomicU64 = AtomicU64::new(0);

impl OutputSet {
    /// A set of single files (each anywhere).
    pub fn new() -> Self {
        Self::default()
    }

    /// A set of files in `dir` (created by the first write when missing), any
    /// of `names`: the names this command can write there. On commit, those
    /// of `names` that were not written are removed. Errors: `dir` is a file
    /// or another non-folder ([`Error::Output`]).
    pub fn folder(dir: &Path, names: &[&str]) -> Result<Self> {
        if let Ok(m) = std::fs::metadata(dir) {
            if !m.is_dir() {
                return Err(refuse(
                    dir,
                    "the output folder is a file (give a folder, or a path that does not exist)",
                ));
            }
        }
        Ok(OutputSet {
            folder: Some((
                dir.to_path_buf(),
                names.iter().map(|s| s.to_string()).collect(),
            )),
            ..Self::default()
        })
    }

    /// `name` in the set's folder (or `name` itself for a set of single files).
    pub fn path(&self, name: &str) -> PathBuf {
        match &self.folder {
            Some((dir, _)) => dir.join(name),
            None => PathBuf::from(name),
        }
    }

    /// Records an input of the run: no output may be the same file, and none
    /// may be written into it when it is a folder. Paths that do not exist
    /// are ignored.
    pub fn input(&mut self, path: impl AsRef<Path>) -> &mut Self {
        let path = path.as_ref();
        if let Some(id) = identity(path) {
            self.inputs.push(Input {
                path: path.to_path_buf(),
                id,
            });
        }
        self
    }

    /// [`OutputSet::input`] for each path.
    pub fn with_inputs<P: AsRef<Path>>(mut self, paths: impl IntoIterator<Item = P>) -> Self {
        for p in paths {
            self.input(p);
        }
        self
    }

    /// Refuses `path` (the output as given, `dest` where it goes) when it is
    /// an input or lies in an input folder, or is already in the set.
    fn check(&self, path: &Path, dest: &Destination) -> Result<()> {
        let target = dest.path();
        if let Some(id) = identity(target) {
            if let Some(i) = self.inputs.iter().find(|i| i.id == id) {
                return Err(refuse(
                    path,
                    format!(
                        "is the input {}: an output never replaces an input",
                        i.path.display()
                    ),
                ));
            }
        }
        let parent = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if let Some(id) = identity(parent) {
            if let Some(i) = self.inputs.iter().find(|i| i.id.dir && i.id == id) {
                return Err(refuse(
                    path,
                    format!(
                        "lies in the input folder {}: outputs are not written into an input",
                        i.path.display()
                    ),
                ));
            }
        }
        let id = identity(target);
        let same = |t: &Path| t == target || (id.is_some() && identity(t) == id);
        let twice =
            self.staged.iter().any(|s| same(&s.target)) || self.through.iter().any(|t| same(t));
        if twice {
            return Err(refuse(path, "is written twice by the same run"));
        }
        Ok(())
    }

    /// Checks that `path` can be an output of this set (see [`OutputSet::write`])
    /// without writing anything: call it for every output before the long work.
    pub fn check_output(&self, path: &Path) -> Result<()> {
        let dest = destination(path)?;
        self.check(path, &dest)
    }

    /// Writes one output: `body` fills the file (its own buffering; errors
    /// name the output). Regular destinations are written under a temporary
    /// name and published by [`OutputSet::commit`]; FIFOs and character
    /// devices are written now, through.
    pub fn write(&mut self, path: &Path, body: impl FnOnce(&File) -> Result<()>) -> Result<()> {
        crate::interrupt::check()?;
        if let Some((dir, _)) = &self.folder {
            if !dir.is_dir() {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
        }
        let dest = destination(path)?;
        self.check(path, &dest)?;
        match dest {
            Destination::Through(target) => {
                let file = open_through(path, &target)?;
                body(&file)?;
                self.through.push(target);
                Ok(())
            }
            Destination::Replace(target) => {
                let dir = match target.parent() {
                    Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
                    _ => PathBuf::from("."),
                };
                if !self.cleaned.contains(&dir) {
                    remove_stale_temps(&dir);
                    self.cleaned.push(dir.clone());
                }
                let (tmp, file) = create_temp(path, &target, &dir)?;
                let staged = Staged {
                    tmp,
                    target,
                    given: path.to_path_buf(),
                };
                body(&file)?;
                // Disk-full and quota errors of delayed allocation show here.
                file.sync_all().map_err(|e| Error::io(path, e))?;
                drop(file);
                self.staged.push(staged);
                Ok(())
            }
        }
    }

    /// [`OutputSet::write`] of a buffer already in memory.
    pub fn write_bytes(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        self.write(path, |mut f| {
            f.write_all(bytes).map_err(|e| Error::io(path, e))
        })
    }

    /// Publishes every output (renames the temporary files over the final
    /// names) and removes the folder's outputs this run did not produce.
    /// Fails without publishing anything when the run was interrupted.
    pub fn commit(mut self) -> Result<Committed> {
        crate::interrupt::check()?;
        let mut written = Vec::with_capacity(self.staged.len() + self.through.len());
        let staged = std::mem::take(&mut self.staged);
        for mut s in staged {
            if let Err(e) = std::fs::rename(&s.tmp, &s.target) {
                // `s` and the rest are dropped: their temporary files removed.
                return Err(Error::io(&s.given, e));
            }
            s.tmp = PathBuf::new();
            written.push(std::mem::take(&mut s.given));
        }
        written.extend(self.through.iter().cloned());
        let mut removed = Vec::new();
        if let Some((dir, names)) = &self.folder {
            for name in names {
                let p = dir.join(name);
                let ours = written.iter().any(|w| w == &p);
                if !ours && std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_file()) {
                    std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
                    removed.push(p);
                }
            }
        }
        Ok(Committed { written, removed })
    }
}

/// Opens a FIFO or device for writing without blocking on a FIFO that has
/// no reader (an error then), then writes block as usual.
fn open_through(path: &Path, target: &Path) -> Result<File> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        use std::os::unix::io::AsRawFd;
        let file = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(target)
            .map_err(|e| {
                if e.raw_os_error() == Some(libc::ENXIO) {
                    refuse(path, "is a FIFO that no process reads: not written")
                } else {
                    Error::io(path, e)
                }
            })?;
        let fd = file.as_raw_fd();
        // SAFETY: `fd` is the open descriptor of `file`; F_GETFL/F_SETFL only
        // change its status flags.
        let ok = unsafe {
            let flags = libc::fcntl(fd, libc::F_GETFL);
            flags >= 0 && libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) == 0
        };
        if !ok {
            return Err(Error::io(path, std::io::Error::last_os_error()));
        }
        Ok(file)
    }
    #[cfg(not(unix))]
    {
        std::fs::OpenOptions::new()
            .write(true)
            .open(target)
            .map_err(|e| Error::io(path, e))
    }
}

/// A new temporary file beside `target`: `.NAME.slam2world-tmp-PID-N`,
/// created exclusively (with the permissions of an ordinary new file).
fn create_temp(given: &Path, target: &Path, dir: &Path) -> Result<(PathBuf, File)> {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    loop {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}{TEMP_MARK}{}-{n}", std::process::id()));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            // Named after the output: the temporary name means nothing to a user.
            Err(e) => return Err(Error::io(given, e)),
        }
    }
}

/// The process id in a temporary name of ours, when it is one.
pub fn temp_owner(file_name: &str) -> Option<u32> {
    let rest = file_name.strip_prefix('.')?;
    let at = rest.rfind(TEMP_MARK)?;
    let tail = &rest[at + TEMP_MARK.len()..];
    let (pid, n) = tail.split_once('-')?;
    if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Removes the temporary files in `dir` that a process no longer running
/// left behind (killed with SIGKILL, or by a power cut). Best effort.
pub fn remove_stale_temps(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(pid) = temp_owner(&name.to_string_lossy()) else {
            continue;
        };
        if !process_alive(pid) && e.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

#[cfg(unix)]
fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 checks for the process without sending anything.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

#[cfg(not(unix))]
fn process_alive(_pid: u32) -> bool {
    // Without a cheap check, never remove another process's file.
    true
}

/// Writes one file through an [`OutputSet`] of its own: `body` fills the file,
/// which replaces `path` only when complete. On any error `path` is untouched
/// and no temporary file is left.
pub fn write_atomic(path: &Path, body: impl FnOnce(&File) -> Result<()>) -> Result<()> {
    let mut set = OutputSet::new();
    set.write(path, body)?;
    set.commit().map(|_| ())
}

/// [`write_atomic`] for a buffer already in memory.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |mut f| {
        f.write_all(bytes).map_err(|e| Error::io(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn failed_body_leaves_nothing_and_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        write_bytes_atomic(&path, b"first").unwrap();
        let err = write_atomic(&path, |mut f| {
            f.write_all(b"partial").unwrap();
            Err(Error::invalid("body", "failed on purpose"))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"first");
        assert_eq!(names(dir.path()), ["out.bin"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o600, 0o600);
        }
    }

    #[test]
    fn temp_names_are_recognised() {
        assert_eq!(temp_owner(".cloud.ply.slam2world-tmp-1234-7"), Some(1234));
        assert_eq!(
            temp_owner(".a.slam2world-tmp-b.slam2world-tmp-9-0"),
            Some(9)
        );
        assert_eq!(temp_owner("cloud.ply"), None);
        assert_eq!(temp_owner(".x.slam2world-tmp-12-"), None);
        assert_eq!(temp_owner(".x.slam2world-tmp-12-3a"), None);
    }

    #[test]
    fn a_set_is_published_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut set = OutputSet::folder(d, &["a", "b", "c"]).unwrap();
        set.write_bytes(&d.join("a"), b"a1").unwrap();
        set.write_bytes(&d.join("b"), b"b1").unwrap();
        set.write_bytes(&d.join("c"), b"c1").unwrap();
        let c = set.commit().unwrap();
        assert_eq!(c.written.len(), 3);
        assert_eq!(names(d), ["a", "b", "c"]);
        // A second run that fails on its second output: nothing changes.
        let mut set = OutputSet::folder(d, &["a", "b", "c"]).unwrap();
        set.write_bytes(&d.join("a"), b"a2").unwrap();
        let e = set.write(&d.join("b"), |_| Err(Error::invalid("b", "disk full")));
        assert!(e.is_err());
        drop(set);
        assert_eq!(names(d), ["a", "b", "c"]);
        assert_eq!(std::fs::read(d.join("a")).unwrap(), b"a1");
        // A run that writes only a and b removes the stale c.
        let mut set = OutputSet::folder(d, &["a", "b", "c"]).unwrap();
        set.write_bytes(&d.join("a"), b"a3").unwrap();
        set.write_bytes(&d.join("b"), b"b3").unwrap();
        let c = set.commit().unwrap();
        assert_eq!(c.removed, vec![d.join("c")]);
        assert_eq!(names(d), ["a", "b"]);
    }

    #[test]
    fn stale_temps_of_dead_processes_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // pid_max is at most 2^22 on Linux: this process cannot exist.
        let dead = d.join(".out.bin.slam2world-tmp-4194305-0");
        let alive = d.join(format!(
            ".out.bin.slam2world-tmp-{}-999999",
            std::process::id()
        ));
        std::fs::write(&dead, b"x").unwrap();
        std::fs::write(&alive, b"x").unwrap();
        write_bytes_atomic(&d.join("out.bin"), b"y").unwrap();
        assert!(!dead.exists());
        assert!(alive.exists());
    }

    #[test]
    fn inputs_and_folders_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let input = d.join("in.ply");
        std::fs::write(&input, b"input").unwrap();
        std::fs::create_dir(d.join("sub")).unwrap();
        let mut set = OutputSet::new().with_inputs([&input]);
        // The same file by another spelling.
        let other = d.join("sub").join("..").join("in.ply");
        let e = set.write_bytes(&other, b"x").unwrap_err();
        assert!(matches!(e, Error::Output { .. }), "{e}");
        assert!(e.to_string().contains("is the input"), "{e}");
        assert_eq!(std::fs::read(&input).unwrap(), b"input");
        let e = set.write_bytes(&d.join("sub"), b"x").unwrap_err();
        assert!(e.to_string().contains("is a folder"), "{e}");
        let e = OutputSet::folder(&input, &["a"]).unwrap_err();
        assert!(e.to_string().contains("output folder is a file"), "{e}");
    }
}
