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

/// Arenas of glibc's allocator for a process that calls
/// [`bound_arenas`]. Each thread that allocates gets an arena of its own
/// (up to eight per core) and the free memory at the top of a thread's arena
/// stays resident: `malloc_trim` gives back the top of the main arena alone.
/// A conversion's parallel tasks free a batch of keyframes or a wave of
/// chunks at a time, and on the 10x log about 20 MiB stayed resident that
/// way after each phase. With two arenas, what the tasks free is given back
/// at the end of the phase ([`release_free_memory`]).
pub const ARENAS: i32 = 2;

/// The fixed size from which glibc's allocator gives a block pages of its
/// own (and returns them when it is freed), for a process that calls
/// [`bound_arenas`]. Left to itself, glibc raises this threshold to the
/// largest block freed so far (up to 32 MiB) and the size of free memory it
/// keeps at an arena's top to twice that; a conversion frees megabyte
/// arrays a keyframe batch at a time on two threads, and the freed memory
/// then piled up resident: on the 10x log the keyframe streaming went from
/// 5 to 37 MiB resident while its heap stayed flat. A fixed threshold keeps
/// the default top of 128 KiB.
pub const MMAP_THRESHOLD: i32 = 4 << 20;

/// Bounds glibc's allocator to [`ARENAS`] arenas and fixes its mmap
/// threshold ([`MMAP_THRESHOLD`]): for the command line, whose conversions
/// promise a memory bound; the Python module leaves the host process's
/// allocator as it is. A no-op with other allocators.
pub fn bound_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt sets a tunable of the allocator; called before any
    // thread is started.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, ARENAS);
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
    }
}

/// Freed bytes between two [`release_free_memory`] calls of a [`Releaser`].
pub const RELEASE_EVERY: usize = 2 << 20;

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

/// One region of a vector filled by [`par_fill_regions`]: the values pushed,
/// in order, go into the region's reserved slots of the shared allocation,
/// then (past them) into an overflow of its own.
pub struct Region<'a, T> {
    slots: &'a mut [MaybeUninit<T>],
    filled: usize,
    overflow: Vec<T>,
}

impl<T> Region<'_, T> {
    /// Appends `value` to the region.
    #[inline]
    pub fn push(&mut self, value: T) {
        match self.slots.get_mut(self.filled) {
            Some(slot) => {
                slot.write(value);
                self.filled += 1;
            }
            None => self.overflow.push(value),
        }
    }

    /// The values pushed so far.
    pub fn len(&self) -> usize {
        self.filled + self.overflow.len()
    }

    /// Whether nothing was pushed.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Runs `fill(k, region)` for each region `k` of `lens` in parallel and gives
/// the values pushed, concatenated in region order in one vector, and each
/// region's result and count.
///
/// Region `k` is `lens[k]` slots of one allocation (advised to use huge
/// pages); pushes past them go to an overflow, as do all pushes when that
/// allocation cannot be had. The values are written where they stay: when
/// every region but the last is filled exactly (rowid ranges of a table
/// without gaps), the concatenation moves nothing; otherwise the regions are
/// moved down to close the gaps, and overflows are inserted where they
/// belong. When `fill` panics, the values written are leaked, never read.
pub fn par_fill_regions<T: Send, S: Send>(
    lens: &[usize],
    fill: impl Fn(usize, &mut Region<'_, T>) -> S + Sync,
) -> (Vec<T>, Vec<(S, usize)>) {
    use rayon::prelude::*;
    let total = lens
        .iter()
        .try_fold(0usize, |a, &n| a.checked_add(n))
        .unwrap_or(usize::MAX);
    let mut out: Vec<T> = Vec::new();
    let reserved = out.try_reserve_exact(total).is_ok();
    let lens: Vec<usize> = if reserved {
        advise_huge_pages(&mut out.spare_capacity_mut()[..total]);
        lens.to_vec()
    } else {
        vec![0; lens.len()]
    };
    let done: Vec<(S, usize, Vec<T>)> = {
        let mut rest = &mut out.spare_capacity_mut()[..lens.iter().sum::<usize>()];
        let mut regions = Vec::with_capacity(lens.len());
        for &n in &lens {
            let (slots, after) = std::mem::take(&mut rest).split_at_mut(n);
            regions.push(Region {
                slots,
                filled: 0,
                overflow: Vec::new(),
            });
            rest = after;
        }
        regions
            .into_par_iter()
            .enumerate()
            .map(|(k, mut r)| {
                let s = fill(k, &mut r);
                (s, r.filled, r.overflow)
            })
            .collect()
    };
    // Close the gaps: region k's `filled` values, at its offset, moved down
    // to follow the earlier regions' (never up: `len <= offset`).
    let base = out.as_mut_ptr();
    let (mut len, mut offset) = (0usize, 0usize);
    for ((_, filled, _), n) in done.iter().zip(&lens) {
        if offset != len {
            // SAFETY: [offset, offset + filled) was written by the region's
            // pushes and lies inside the allocation; ptr::copy allows the
            // overlap, and the source is not read again.
            unsafe { std::ptr::copy(base.add(offset), base.add(len), *filled) };
        }
        len += filled;
        offset += n;
    }
    // SAFETY: the first `len` elements were written (moved above).
    unsafe { out.set_len(len) };
    // The overflows after their region's slots, the last region first so
    // that the earlier positions stay where they were.
    let mut end = len;
    let mut results = Vec::with_capacity(done.len());
    for (s, filled, overflow) in done.into_iter().rev() {
        let count = filled + overflow.len();
        if !overflow.is_empty() {
            out.splice(end..end, overflow);
        }
        end -= filled;
        results.push((s, count));
    }
    results.reverse();
    (out, results)
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

    #[test]
    fn regions_concatenate_in_order_with_gaps_and_overflows() {
        // Region k pushes `pushes[k]` values (k, i): exactly its slots, fewer
        // (a gap to close), more (an overflow), none.
        let lens = [4, 5, 3, 0, 2];
        let pushes = [4, 2, 6, 3, 2];
        let (v, counts) = par_fill_regions(&lens, |k, r| {
            for i in 0..pushes[k] {
                r.push((k, i, format!("{k}.{i}")));
            }
            k * 10
        });
        let want: Vec<(usize, usize, String)> = (0..lens.len())
            .flat_map(|k| (0..pushes[k]).map(move |i| (k, i, format!("{k}.{i}"))))
            .collect();
        assert_eq!(v, want);
        let got: Vec<(usize, usize)> = counts;
        assert_eq!(got, vec![(0, 4), (10, 2), (20, 6), (30, 3), (40, 2)]);
    }

    #[test]
    fn regions_overflow_whole_when_the_allocation_fails() {
        // usize::MAX slots cannot be had: every push goes to the overflows.
        let (v, counts) = par_fill_regions(&[usize::MAX / 2, usize::MAX / 2], |k, r| {
            r.push(k as u64);
            r.push(k as u64 + 10);
        });
        assert_eq!(v, vec![0, 10, 1, 11]);
        assert_eq!(counts, vec![((), 2), ((), 2)]);
    }
}
