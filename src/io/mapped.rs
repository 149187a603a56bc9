//! Read-only memory maps of log files that survive the file being truncated
//! while it is read.
//!
//! A page of a map that lies past the end of a file that shrank raises
//! SIGBUS on access, which ends the process (Python too). [`Mapped`] registers
//! its address range with a SIGBUS handler (installed once, on Linux): a
//! fault inside a registered range maps a page of zeros over the faulting
//! page and marks the map, so the reader goes on (reading zeros) and
//! [`Mapped::check`] then fails with an error that says the file shrank. A
//! fault anywhere else is handed to the handler that was there before (or
//! the default action), as if this one did not exist.
//!
//! Elsewhere (not Linux) the map is a plain `memmap2` map and [`Mapped::check`]
//! compares the file's size only.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::error::{ContainerError, Error, Result};

/// Refuses anything at `path` but a regular file (following links) without
/// opening it: a folder, a FIFO, a pipe, `/dev/null`, a socket. `expected`
/// names what the reader wanted (`an MCAP file`).
pub fn require_file(path: &Path, expected: &'static str) -> Result<()> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let reason = if meta.is_dir() {
        ContainerError::Folder { expected }
    } else if !meta.is_file() {
        ContainerError::NotAFile {
            kind: special_kind(&meta),
        }
    } else {
        return Ok(());
    };
    Err(Error::Container {
        path: path.to_path_buf(),
        reason,
    })
}

/// What a path that is neither a file nor a folder is: `FIFO`, `socket`,
/// `character device`, `block device` or `special file`.
#[cfg(unix)]
pub fn special_kind(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_fifo() {
        "FIFO"
    } else if t.is_socket() {
        "socket"
    } else if t.is_char_device() {
        "character device"
    } else if t.is_block_device() {
        "block device"
    } else {
        "special file"
    }
}

/// What a path that is neither a file nor a folder is.
#[cfg(not(unix))]
pub fn special_kind(_meta: &std::fs::Metadata) -> &'static str {
    "special file"
}

/// Bytes on each side of a slice given back with it: a fault maps the file
/// pages around the one it needs (64 KiB of fault-around with small pages;
/// the whole folio, up to 2 MiB, with the large page-cache folios of current
/// kernels), and those that fall in a neighbour given back before would stay.
pub const RELEASE_MARGIN: usize = 2 << 20;

/// A read-only map of a whole file.
pub struct Mapped {
    map: memmap2::Mmap,
    file: File,
    path: PathBuf,
    #[cfg(target_os = "linux")]
    slot: Option<usize>,
}

impl std::ops::Deref for Mapped {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.map
    }
}

impl Mapped {
    /// Maps `file` (opened read-only from `path`).
    pub fn map(file: File, path: &Path) -> Result<Mapped> {
        // SAFETY: the map is read-only and private to this reader. A file that
        // shrinks while mapped makes accesses past its new end fault: the SIGBUS
        // handler of this module turns those into zero pages (Linux) and `check`
        // reports the shrink.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        #[cfg(target_os = "linux")]
        let slot = guard::register(map.as_ptr() as usize, map.len());
        Ok(Mapped {
            map,
            file,
            path: path.to_path_buf(),
            #[cfg(target_os = "linux")]
            slot,
        })
    }

    /// Gives back this process's pages of `bytes` (a slice of the map, and
    /// [`RELEASE_MARGIN`] beside it) once a
    /// reader is done with them (a chunk decompressed): the memory they held
    /// no longer counts as the process's, and a later read of them maps them
    /// again from the page cache. A reader that walks a long log chunk by
    /// chunk then holds a few chunks of it, not the whole file. A no-op for
    /// a slice outside the map, and elsewhere than Linux.
    pub fn release(&self, bytes: &[u8]) {
        #[cfg(target_os = "linux")]
        {
            let base = self.map.as_ptr() as usize;
            let (start, len) = (bytes.as_ptr() as usize, bytes.len());
            if len == 0 || start < base || start + len > base + self.map.len() {
                return;
            }
            // SAFETY: sysconf has no preconditions.
            let page = usize::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) })
                .unwrap_or(4096)
                .max(1);
            // Every page the slice touches, and those the kernel mapped
            // beside it when it faulted them in (RELEASE_MARGIN): a
            // neighbour given back before would otherwise keep them, up to
            // a folio for each chunk of a long log. A reader still on a
            // neighbour only faults its pages in again.
            let base_page = base.div_ceil(page) * page;
            let end = base + self.map.len();
            let a = (start.saturating_sub(RELEASE_MARGIN) / page * page).max(base_page);
            let b = ((start + len + RELEASE_MARGIN).div_ceil(page) * page)
                .min(end.div_ceil(page) * page);
            if b > a {
                // SAFETY: [a, b) lies inside this read-only file map (the map
                // starts on a page and covers its last page whole), which
                // stays mapped: MADV_DONTNEED only drops the page-table
                // entries, and a later access faults the same file pages in
                // again (the map is never written, so nothing is lost).
                unsafe {
                    libc::madvise(a as *mut libc::c_void, b - a, libc::MADV_DONTNEED);
                }
            }
        }
        #[cfg(not(target_os = "linux"))]
        let _ = bytes;
    }

    /// Fails when the file shrank since it was mapped (a page past its new end
    /// was read as zeros, or its size is now smaller): whatever was read from
    /// the map is then not the file.
    pub fn check(&self) -> Result<()> {
        #[cfg(target_os = "linux")]
        let faulted = self.slot.is_some_and(guard::faulted);
        #[cfg(not(target_os = "linux"))]
        let faulted = false;
        let now = self.file.metadata().map(|m| m.len()).unwrap_or(0);
        if faulted || now < self.map.len() as u64 {
            return Err(Error::Io {
                path: self.path.clone(),
                source: std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    format!(
                        "the file shrank while it was read ({} bytes when opened, {now} now): \
                         read it again once it is complete",
                        self.map.len()
                    ),
                ),
            });
        }
        Ok(())
    }
}

impl Drop for Mapped {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if let Some(s) = self.slot {
            guard::unregister(s);
        }
    }
}

#[cfg(target_os = "linux")]
mod guard {
    //! The SIGBUS handler and its lock-free table of mapped ranges.

    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::sync::Once;

    const SLOTS: usize = 256;

    struct Slot {
        start: AtomicUsize,
        len: AtomicUsize,
        faulted: AtomicBool,
        taken: AtomicBool,
    }

    #[allow(clippy::declare_interior_mutable_const)]
    const EMPTY: Slot = Slot {
        start: AtomicUsize::new(0),
        len: AtomicUsize::new(0),
        faulted: AtomicBool::new(false),
        taken: AtomicBool::new(false),
    };

    static TABLE: [Slot; SLOTS] = [EMPTY; SLOTS];
    static PAGE: AtomicUsize = AtomicUsize::new(4096);
    static INSTALL: Once = Once::new();
    static INSTALLED: AtomicBool = AtomicBool::new(false);
    /// The disposition before ours (written once, before ours is installed).
    static mut PREVIOUS: std::mem::MaybeUninit<libc::sigaction> = std::mem::MaybeUninit::zeroed();

    extern "C" fn on_sigbus(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
        // SAFETY: the kernel passes a valid siginfo_t for an SA_SIGINFO handler.
        let addr = unsafe { (*info).si_addr() } as usize;
        let page = PAGE.load(Ordering::Relaxed);
        for s in &TABLE {
            let start = s.start.load(Ordering::Acquire);
            let len = s.len.load(Ordering::Acquire);
            if start != 0 && addr >= start && addr < start + len {
                let at = addr & !(page - 1);
                // SAFETY: replaces one page of our own read-only map (inside the
                // registered range) by a private zero page; mmap is a system call
                // that takes no lock of this process.
                let r = unsafe {
                    libc::mmap(
                        at as *mut libc::c_void,
                        page,
                        libc::PROT_READ,
                        libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED,
                        -1,
                        0,
                    )
                };
                if r != libc::MAP_FAILED {
                    s.faulted.store(true, Ordering::Release);
                    return;
                }
            }
        }
        // Not ours: what was there before.
        // SAFETY: PREVIOUS was written before this handler was installed and is
        // never written again.
        let prev = unsafe { (*std::ptr::addr_of!(PREVIOUS)).assume_init_ref() };
        let h = prev.sa_sigaction;
        if h == libc::SIG_DFL || h == libc::SIG_IGN {
            // SAFETY: restoring the default disposition; the faulting access runs
            // again on return and ends the process as it would have.
            unsafe {
                let mut dfl: libc::sigaction = std::mem::zeroed();
                dfl.sa_sigaction = libc::SIG_DFL;
                libc::sigaction(libc::SIGBUS, &dfl, std::ptr::null_mut());
            }
        } else if prev.sa_flags & libc::SA_SIGINFO != 0 {
            // SAFETY: the previous handler was installed with SA_SIGINFO and this signature.
            let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                unsafe { std::mem::transmute(h) };
            f(sig, info, ctx);
        } else {
            // SAFETY: the previous handler was installed without SA_SIGINFO.
            let f: extern "C" fn(libc::c_int) = unsafe { std::mem::transmute(h) };
            f(sig);
        }
    }

    fn install() {
        INSTALL.call_once(|| {
            // SAFETY: sysconf, and sigaction with a handler that only touches
            // atomics and calls mmap/sigaction; PREVIOUS is written here before the
            // handler can run.
            unsafe {
                let p = libc::sysconf(libc::_SC_PAGESIZE);
                if p > 0 {
                    PAGE.store(p as usize, Ordering::Relaxed);
                }
                let mut act: libc::sigaction = std::mem::zeroed();
                act.sa_sigaction = on_sigbus as *const () as usize;
                act.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK;
                libc::sigemptyset(&mut act.sa_mask);
                let prev = (*std::ptr::addr_of_mut!(PREVIOUS)).as_mut_ptr();
                if libc::sigaction(libc::SIGBUS, &act, prev) == 0 {
                    INSTALLED.store(true, Ordering::Release);
                }
            }
        });
    }

    /// Registers a mapped range; `None` when the table is full or the handler
    /// could not be installed (the map then works without the guard).
    pub(super) fn register(start: usize, len: usize) -> Option<usize> {
        if len == 0 {
            return None;
        }
        install();
        if !INSTALLED.load(Ordering::Acquire) {
            return None;
        }
        for (i, s) in TABLE.iter().enumerate() {
            if s.taken
                .compare_exchange(false, true, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
            {
                s.faulted.store(false, Ordering::Release);
                s.len.store(len, Ordering::Release);
                s.start.store(start, Ordering::Release);
                return Some(i);
            }
        }
        None
    }

    pub(super) fn faulted(slot: usize) -> bool {
        TABLE[slot].faulted.load(Ordering::Acquire)
    }

    pub(super) fn unregister(slot: usize) {
        let s = &TABLE[slot];
        s.start.store(0, Ordering::Release);
        s.len.store(0, Ordering::Release);
        s.taken.store(false, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_that_shrinks_under_its_map_is_an_error_not_a_crash() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.bin");
        let n = 1 << 20;
        std::fs::write(&path, vec![7u8; n]).unwrap();
        let m = Mapped::map(File::open(&path).unwrap(), &path).unwrap();
        assert!(m.check().is_ok());
        std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_len(4096)
            .unwrap();
        // Reading past the new end: zeros, not SIGBUS (Linux); the check says why.
        let sum: u64 = m.iter().map(|&b| b as u64).sum();
        assert!(sum >= 7 * 4096 && sum < 7 * n as u64, "{sum}");
        let e = m.check().unwrap_err();
        assert!(e.to_string().contains("shrank"), "{e}");
    }

    /// Resident KiB of the map of `path` in this process (`/proc/self/smaps`).
    #[cfg(target_os = "linux")]
    fn resident_kib(path: &Path) -> u64 {
        let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
        let name = path.to_string_lossy();
        let mut lines = smaps.lines();
        while let Some(l) = lines.next() {
            if l.ends_with(&*name) {
                for l in lines.by_ref() {
                    if let Some(v) = l.strip_prefix("Rss:") {
                        return v.trim().trim_end_matches("kB").trim().parse().unwrap();
                    }
                }
            }
        }
        panic!("no map of {name}");
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn released_slices_leave_no_page_behind_and_read_the_same_again() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("chunks.bin");
        let n = 4 << 20;
        let bytes: Vec<u8> = (0..n).map(|i| (i % 251) as u8).collect();
        std::fs::write(&path, &bytes).unwrap();
        let m = Mapped::map(File::open(&path).unwrap(), &path).unwrap();
        // Pages of 4 KiB, not the 2 MiB folios a page cache may map whole
        // (and give back whole), so that every page left behind shows.
        // SAFETY: advice on this test's own read-only map.
        unsafe {
            libc::madvise(m.as_ptr() as *mut libc::c_void, n, libc::MADV_NOHUGEPAGE);
        }
        let sum = |s: &[u8]| s.iter().map(|&b| u64::from(b)).sum::<u64>();
        let whole = sum(&m);
        assert_eq!(resident_kib(&path), (n / 1024) as u64);
        // Slices that start and end inside pages, as a log's chunks do,
        // given back one after another in an order that leaves neighbours
        // faulted in after their own release: nothing stays.
        let cuts = [0, 5000, 300_001, 1_000_003, 2_500_000, 4_000_001, n];
        for w in cuts.windows(2).rev() {
            let chunk = &m[w[0]..w[1]];
            assert_eq!(sum(chunk), sum(&bytes[w[0]..w[1]]));
            m.release(chunk);
        }
        assert_eq!(resident_kib(&path), 0);
        // A slice inside the map drops its pages and RELEASE_MARGIN beside
        // them; what is read again is the file.
        assert_eq!(sum(&m), whole);
        m.release(&m[3_000_003..3_000_010]);
        let (a, b) = (3_000_003 - RELEASE_MARGIN, 3_000_010 + RELEASE_MARGIN);
        let pages = (b.div_ceil(4096).min(n / 4096) - a / 4096) as u64;
        assert_eq!((n / 1024) as u64 - resident_kib(&path), 4 * pages);
        assert_eq!(sum(&m), whole);
        assert!(m.check().is_ok());
    }
}
