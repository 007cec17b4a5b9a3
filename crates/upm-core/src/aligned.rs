//! An allocator that starts every large block on a cache line: the system allocator's, with each
//! block of [`LARGE`] bytes or more placed at the first cache line of a slightly larger system
//! block.
//!
//! A large result is written with non-temporal stores of whole cache lines
//! ([`crate::sim`]'s one-pass run). glibc's `malloc` puts a large block 16 bytes past a page
//! boundary, so every run of lines a tile wrote began and ended in a line shared with its
//! neighbours, written by two masked plain stores that each read the line for ownership: a 2-step
//! call on 1e6 points cost 14.3–16.3 ns per part on one thread, and 8.5–10.0 with its result on
//! lines (Intel Xeon with AVX-512, `cargo bench -p upm-core --bench kernel -- --per-call`).
//!
//! The large block is placed within a system block of the same alignment as any other (not
//! allocated with a larger alignment): a zeroed one is then the system's `calloc`, whose large
//! blocks are pages the kernel maps lazily, never written until used (an aligned allocation is
//! zeroed by writing it, every page of a result that is never written included).
//!
//! A library cannot choose its users' allocator: the Python extension and the benches declare
//! this one (`#[global_allocator]`); a Rust program may too. The results are the same without it.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks of at least this many bytes start on a cache line.
pub const LARGE: usize = 64 << 10;

/// A cache line's bytes.
const LINE: usize = 64;

/// Bytes a large block's system block has beyond it: the system block starts 16-byte aligned, and
/// the first line at least 8 bytes into it (room to note where the system block starts) is at
/// most 8 + 48 bytes in.
const EXTRA: usize = LINE;

/// The system allocator, with blocks of [`LARGE`] bytes or more aligned to a cache line.
#[derive(Debug, Default, Clone, Copy)]
pub struct LineAligned;

/// Whether a block of `layout` is placed on a line within a system block. (A function of the size
/// and alignment alone, which a block's release gives as its allocation did.)
fn placed(layout: Layout) -> bool {
    layout.size() >= LARGE && layout.align() <= LINE
}

/// The system block that holds a placed block of `size` bytes (`None`: too large for any).
fn outer(size: usize) -> Option<Layout> {
    Layout::from_size_align(size.checked_add(EXTRA)?, 16).ok()
}

/// How far into the system block `base` its placed block starts: the first line at least 8
/// bytes in.
fn offset(base: *mut u8) -> usize {
    (base as usize + 8).next_multiple_of(LINE) - base as usize
}

/// The placed block of the system block `base` (null stays null), with `base` noted in the 8
/// bytes before it.
///
/// # Safety
/// `base` is null or a system block of an [`outer`] layout.
unsafe fn place(base: *mut u8) -> *mut u8 {
    if base.is_null() {
        return base;
    }
    let start = base.add(offset(base));
    start.cast::<*mut u8>().sub(1).write(base);
    start
}

/// The system block a placed block `ptr` lies in (noted by [`place`]).
///
/// # Safety
/// `ptr` is a placed block.
unsafe fn base(ptr: *mut u8) -> *mut u8 {
    ptr.cast::<*mut u8>().sub(1).read()
}

// SAFETY: a block that is not placed is the system's own, allocated and released with the
// caller's layout. A placed block lies within a system block of the `outer` layout of its size,
// starting 8 to 64 bytes into it (`base` is 16-byte aligned, `EXTRA` is 64), so its `size` bytes
// are the system block's, aligned to a line (to any alignment the caller may ask of a placed
// block); it is released through the note before it, with the same `outer` layout (`placed` and
// `outer` depend only on the size and alignment, the same at release as at allocation).
unsafe impl GlobalAlloc for LineAligned {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !placed(layout) {
            return System.alloc(layout);
        }
        outer(layout.size()).map_or(std::ptr::null_mut(), |o| place(System.alloc(o)))
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !placed(layout) {
            return System.alloc_zeroed(layout);
        }
        outer(layout.size()).map_or(std::ptr::null_mut(), |o| place(System.alloc_zeroed(o)))
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        match outer(layout.size()).filter(|_| placed(layout)) {
            Some(o) => System.dealloc(base(ptr), o),
            None => System.dealloc(ptr, layout),
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller guarantees new_size, rounded up to the alignment, does not overflow.
        let new = Layout::from_size_align_unchecked(new_size, layout.align());
        match (placed(layout), placed(new)) {
            (false, false) => System.realloc(ptr, layout, new_size),
            (true, true) => {
                // (the system's reallocation, then the contents moved to the new block's line if
                // they are not on it: a large block grows in place or by remapping its pages)
                let (Some(old), Some(grown)) = (outer(layout.size()), outer(new_size)) else {
                    return std::ptr::null_mut();
                };
                let from = base(ptr);
                let at = ptr as usize - from as usize;
                let moved = System.realloc(from, old, grown.size());
                if moved.is_null() {
                    return moved;
                }
                let line = offset(moved);
                if line != at {
                    std::ptr::copy(moved.add(at), moved.add(line), layout.size().min(new_size));
                }
                place(moved)
            }
            _ => {
                let moved = self.alloc(new);
                if !moved.is_null() {
                    std::ptr::copy_nonoverlapping(ptr, moved, layout.size().min(new_size));
                    self.dealloc(ptr, layout);
                }
                moved
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes `0..n` of `p` hold the pattern `seed` (see [`fill`]).
    unsafe fn holds(p: *const u8, n: usize, seed: usize) -> bool {
        (0..n).all(|i| *p.add(i) == (i * 31 + seed) as u8)
    }

    unsafe fn fill(p: *mut u8, n: usize, seed: usize) {
        for i in 0..n {
            *p.add(i) = (i * 31 + seed) as u8;
        }
    }

    /// Large blocks start on a line whatever alignment up to a line is asked (a larger one is
    /// kept), small ones keep the system's; zeroed blocks are zero; the whole block is usable.
    #[test]
    fn large_blocks_start_on_a_line() {
        let a = LineAligned;
        for (size, align) in [
            (LARGE, 8),
            (LARGE + 24, 16),
            (3 * LARGE + 8, 1),
            (LARGE + 8, 64),
            (2 * LARGE, 4096),
            (1 << 24, 8),
            (100, 8),
        ] {
            let layout = Layout::from_size_align(size, align).unwrap();
            let line = if size >= LARGE {
                LINE.max(align)
            } else {
                align
            };
            // SAFETY: non-zero sizes; every block is released with its layout.
            unsafe {
                let p = a.alloc(layout);
                assert!(
                    !p.is_null() && (p as usize).is_multiple_of(line),
                    "{size} {align}"
                );
                fill(p, size, 3);
                assert!(holds(p, size, 3));
                a.dealloc(p, layout);
                let z = a.alloc_zeroed(layout);
                assert!((z as usize).is_multiple_of(line), "{size} {align}");
                assert!(std::slice::from_raw_parts(z, size).iter().all(|&b| b == 0));
                a.dealloc(z, layout);
            }
        }
    }

    /// A reallocation keeps the contents, growing and shrinking, across the threshold both ways
    /// and between large sizes (where the system's block may come back at another offset from a
    /// line, and the contents are moved onto the new block's line).
    #[test]
    fn a_reallocation_keeps_the_contents() {
        let a = LineAligned;
        let sizes = [
            100,
            3 * LARGE,
            LARGE + 40,
            9 * LARGE + 8,
            LARGE,
            2 * LARGE + 16,
            1 << 22,
            70,
        ];
        let at = |s: usize| Layout::from_size_align(s, 8).unwrap();
        // SAFETY: each block is released once, with the layout of its last size; every read is
        // within the bytes written.
        unsafe {
            let mut p = a.alloc(at(sizes[0]));
            fill(p, sizes[0], 0);
            let mut kept = sizes[0];
            // (a block allocated between the steps moves the system's free blocks about)
            let mut others = Vec::new();
            for (k, w) in sizes.windows(2).enumerate() {
                p = a.realloc(p, at(w[0]), w[1]);
                assert!(!p.is_null());
                if w[1] >= LARGE {
                    assert!((p as usize).is_multiple_of(LINE), "{w:?}");
                }
                kept = kept.min(w[1]);
                assert!(holds(p, kept, 0), "{w:?}");
                fill(p, w[1], 0);
                kept = w[1];
                others.push((a.alloc(at(LARGE + 8 * k)), LARGE + 8 * k));
            }
            a.dealloc(p, at(*sizes.last().unwrap()));
            for (o, s) in others {
                a.dealloc(o, at(s));
            }
        }
    }

    /// A large zeroed block is the system's zeroed memory, not written by the allocator: 1 GiB
    /// of it does not become resident (the process's resident size grows by far less).
    #[test]
    #[cfg(target_os = "linux")]
    fn a_large_zeroed_block_is_not_written() {
        let resident = || {
            let statm = std::fs::read_to_string("/proc/self/statm").unwrap();
            let pages: usize = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
            pages * 4096
        };
        let size = 1 << 30;
        let layout = Layout::from_size_align(size, 8).unwrap();
        let before = resident();
        // SAFETY: a non-zero size, released with its layout.
        unsafe {
            let z = LineAligned.alloc_zeroed(layout);
            assert!(!z.is_null() && (z as usize).is_multiple_of(LINE));
            assert_eq!(*z.add(size / 2), 0);
            let grown = resident().saturating_sub(before);
            LineAligned.dealloc(z, layout);
            assert!(grown < size / 4, "{grown} bytes became resident");
        }
    }
}
