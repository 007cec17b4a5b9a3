//! An allocator that starts every large block on a cache line: the system allocator's, with the
//! alignment of blocks of [`LARGE`] bytes or more raised to 64.
//!
//! A large result is written with non-temporal stores of whole cache lines
//! ([`crate::sim`]'s one-pass run). glibc's `malloc` puts a large block 16 bytes past a page
//! boundary, so every run of lines a tile wrote began and ended in a line shared with its
//! neighbours, written by two masked plain stores that each read the line for ownership: a 2-step
//! call on 1e6 points cost 14.6–16.0 ns per part on one thread, and 8.8–10.4 with its result on
//! lines (Intel Xeon with AVX-512, `cargo bench -p upm-core --bench kernel -- --per-call`).
//!
//! A library cannot choose its users' allocator: the Python extension and the benches declare
//! this one (`#[global_allocator]`); a Rust program may too. The results are the same without it.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks of at least this many bytes start on a cache line.
pub const LARGE: usize = 64 << 10;

/// A cache line's bytes.
const LINE: usize = 64;

/// The system allocator, with blocks of [`LARGE`] bytes or more aligned to a cache line.
#[derive(Debug, Default, Clone, Copy)]
pub struct LineAligned;

/// The layout the system allocator is asked for in place of `layout`: the same but for the
/// alignment of a large block. (A function of the size and alignment alone, so that a block is
/// freed with the layout it was allocated with.)
fn system(layout: Layout) -> Layout {
    if layout.size() >= LARGE && layout.align() < LINE {
        // SAFETY: LINE is a power of two; a size that fitted under its alignment fits under a
        // larger one (`isize::MAX` rounded down to LINE is far above any size there is room for).
        unsafe { Layout::from_size_align_unchecked(layout.size(), LINE) }
    } else {
        layout
    }
}

// SAFETY: every call passes on to `System` with the layout `system` makes of the caller's, the
// same for a block's allocation and its release (it depends only on the size and alignment the
// caller gives both, as `GlobalAlloc` requires them to be the same); a reallocation that changes
// that layout's alignment moves the block itself.
unsafe impl GlobalAlloc for LineAligned {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        System.alloc(system(layout))
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        System.alloc_zeroed(system(layout))
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, system(layout))
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = system(layout);
        // SAFETY: the caller guarantees new_size, rounded up to the alignment, does not overflow.
        let new = system(Layout::from_size_align_unchecked(new_size, layout.align()));
        if old.align() == new.align() {
            return System.realloc(ptr, old, new_size);
        }
        let moved = System.alloc(new);
        if !moved.is_null() {
            std::ptr::copy_nonoverlapping(ptr, moved, layout.size().min(new_size));
            System.dealloc(ptr, old);
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Large blocks start on a line whatever the alignment asked; small ones keep the system's;
    /// zeroed blocks are zero; a reallocation keeps the contents across the threshold both ways
    /// and lands on a line when large.
    #[test]
    fn large_blocks_start_on_a_line_and_keep_their_contents() {
        let a = LineAligned;
        for (size, align) in [
            (LARGE, 8),
            (LARGE + 24, 16),
            (3 * LARGE + 8, 1),
            (1 << 24, 8),
        ] {
            let layout = Layout::from_size_align(size, align).unwrap();
            // SAFETY: non-zero sizes; every block is released with its layout.
            unsafe {
                let p = a.alloc(layout);
                assert!(
                    !p.is_null() && (p as usize).is_multiple_of(LINE),
                    "{size} {align}"
                );
                a.dealloc(p, layout);
                let z = a.alloc_zeroed(layout);
                assert!((z as usize).is_multiple_of(LINE));
                assert!(std::slice::from_raw_parts(z, size).iter().all(|&b| b == 0));
                a.dealloc(z, layout);
            }
        }
        let small = Layout::from_size_align(100, 8).unwrap();
        // SAFETY: as above; each reallocation's result is released with its new size.
        unsafe {
            let p = a.alloc(small);
            assert!((p as usize).is_multiple_of(8));
            for i in 0..100 {
                *p.add(i) = i as u8;
            }
            let big = a.realloc(p, small, 2 * LARGE);
            assert!((big as usize).is_multiple_of(LINE));
            assert!((0..100).all(|i| *big.add(i) == i as u8));
            *big.add(2 * LARGE - 1) = 7;
            let bigger = a.realloc(
                big,
                Layout::from_size_align(2 * LARGE, 8).unwrap(),
                5 * LARGE,
            );
            assert!((bigger as usize).is_multiple_of(LINE));
            assert!((0..100).all(|i| *bigger.add(i) == i as u8) && *bigger.add(2 * LARGE - 1) == 7);
            let back = a.realloc(bigger, Layout::from_size_align(5 * LARGE, 8).unwrap(), 50);
            assert!((0..50).all(|i| *back.add(i) == i as u8));
            a.dealloc(back, Layout::from_size_align(50, 8).unwrap());
        }
    }
}
