//! Large output buffers: fresh vectors backed by transparent huge pages.
//!
//! A fresh 120 MB output written once costs about 30 000 page faults with 4 KiB
//! pages, more time than the arithmetic that fills it; with 2 MiB pages it costs
//! sixty. Every large, freshly allocated output of the crate (transformed points,
//! backprojected clouds, their colours and ids) goes through here, so that the
//! hint is given in one place. The hint is Linux `madvise(MADV_HUGEPAGE)`; where
//! it is unavailable or refused, the buffer works the same with small pages.

use std::mem::MaybeUninit;

use crate::error::Error;

/// Buffers from this size on are advised to use huge pages (smaller ones come
/// from the allocator's already-touched pools, where the hint would not help).
pub const HUGE_PAGE_MIN_BYTES: usize = 8 << 20;

/// Gives the allocator's free memory back to the system (glibc's
/// `malloc_trim`): after a phase that freed much (a log's scan), the freed
/// pages would otherwise stay counted as the process's while the next phase
/// allocates its own. A no-op with other allocators.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap pages to the kernel.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Freed bytes between two [`release_free_memory`] calls of a [`Releaser`].
pub const RELEASE_EVERY: usize = 16 << 20;

/// Gives memory back while a loop frees it: a scan's per-chunk parts merged
/// into one vector are freed one by one, and without this their pages stay
/// the process's until the merge ends, the parts and the merged vector
/// resident together (twice the scan).
#[derive(Debug, Default)]
pub struct Releaser {
    freed: usize,
}

impl Releaser {
    /// Counts `bytes` freed; every [`RELEASE_EVERY`] bytes, gives the free
    /// memory back.
    pub fn freed(&mut self, bytes: usize) {
        self.freed += bytes;
        if self.freed >= RELEASE_EVERY {
            release_free_memory();
            self.freed = 0;
        }
    }
}

/// Asks the kernel to back `buf` (not yet touched) with huge pages; a hint only.
pub fn advise_huge_pages<T>(buf: &mut [T]) {
    let bytes = std::mem::size_of_val(buf);
    if bytes < HUGE_PAGE_MIN_BYTES {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        // madvise needs a page-aligned start: advise the aligned part of the buffer.
        const PAGE: usize = 4096;
        let start = buf.as_mut_ptr() as usize;
        let aligned = start.next_multiple_of(PAGE);
        let len = (start + bytes).saturating_sub(aligned) / PAGE * PAGE;
        if len > 0 {
            // SAFETY: [aligned, aligned + len) lies inside `buf`, memory this process
            // owns; MADV_HUGEPAGE changes how pages are backed, never their content.
            // The result is ignored: without huge pages the buffer works the same.
            unsafe {
                libc::madvise(aligned as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
            }
        }
    }
}

/// An empty vector with room for `n` elements, advised to use huge pages.
pub fn with_capacity_advised<T>(n: usize) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    advise_huge_pages(v.spare_capacity_mut());
    v
}

/// A vector of `n` elements, all written once by `fill` (given the whole
/// uninitialised buffer, advised to use huge pages), without a zero-fill pass.
/// When `fill` panics, the vector is dropped without being read.
///
/// # Safety
///
/// `fill` must initialise every element of the `&mut [MaybeUninit<T>]` of
/// length `n` it is given before it returns: the elements are read as `T`
/// afterwards.
pub(crate) unsafe fn filled_advised<T: Copy>(
    n: usize,
    fill: impl FnOnce(&mut [MaybeUninit<T>]),
) -> Vec<T> {
    let mut v = with_capacity_advised::<T>(n);
    fill(&mut v.spare_capacity_mut()[..n]);
    // SAFETY: the caller guarantees that `fill` wrote each of the first `n`
    // elements, and `T: Copy` has no drop glue to run on them.
    unsafe { v.set_len(n) };
    v
}

/// [`filled_advised`] whose allocation may fail: an [`Error::OutOfMemory`]
/// naming `what` instead of an abort when the memory cannot be had (an
/// address-space limit, a huge request).
///
/// # Safety
///
/// As for [`filled_advised`]: `fill` must initialise every element.
pub(crate) unsafe fn try_filled_advised<T: Copy>(
    what: &str,
    n: usize,
    fill: impl FnOnce(&mut [MaybeUninit<T>]),
) -> crate::Result<Vec<T>> {
    let mut v = try_with_capacity(what, n)?;
    advise_huge_pages(v.spare_capacity_mut());
    fill(&mut v.spare_capacity_mut()[..n]);
    // SAFETY: the caller guarantees that `fill` wrote each of the first `n`
    // elements, and `T: Copy` has no drop glue to run on them.
    unsafe { v.set_len(n) };
    Ok(v)
}

/// An empty vector with room for `n` elements, or [`Error::OutOfMemory`].
pub fn try_with_capacity<T>(what: &str, n: usize) -> crate::Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| Error::OutOfMemory {
        what: what.to_string(),
        bytes: n as u128 * std::mem::size_of::<T>() as u128,
    })?;
    Ok(v)
}

/// A copy of `src` in a buffer advised to use huge pages.
pub fn copy_advised<T: Copy>(src: &[T]) -> Vec<T> {
    let mut v = with_capacity_advised(src.len());
    v.extend_from_slice(src);
    v
}

/// A vector of `n` copies of `value`, advised to use huge pages.
pub fn filled_with_advised<T: Copy>(n: usize, value: T) -> Vec<T> {
    let mut v = with_capacity_advised(n);
    v.resize(n, value);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advised_buffers_hold_what_was_written() {
        let n = HUGE_PAGE_MIN_BYTES / 4 + 7; // above the threshold
        let src: Vec<u32> = (0..n as u32).collect();
        assert_eq!(copy_advised(&src), src);
        // SAFETY: the closure writes every element.
        let v = unsafe {
            filled_advised::<u32>(n, |d| {
                for (i, x) in d.iter_mut().enumerate() {
                    x.write(2 * i as u32);
                }
            })
        };
        assert_eq!(v.len(), n);
        assert_eq!(v[n - 1], 2 * (n as u32 - 1));
        assert_eq!(filled_with_advised(5, 9u8), vec![9u8; 5]);
    }
}
