//! Large result buffers. They are reserved fallibly, so a result too big for memory is an
//! [`Error`], never an abort of the process, and on Linux they are backed by transparent huge
//! pages, so writing them for the first time takes 1/512 of the page faults (which otherwise cost
//! more than the simulation when every step is recorded).

use crate::error::{Error, Result};

/// Buffers smaller than this are left to the allocator as they are.
const HUGE_FROM: usize = 8 << 20;

/// Reserves room for exactly `n` more elements of `v`; `what` names the result in the error.
pub fn reserve<T>(v: &mut Vec<T>, n: usize, what: &str) -> Result<()> {
    v.try_reserve_exact(n).map_err(|_| {
        let gb = n as f64 * std::mem::size_of::<T>() as f64 / 1e9;
        Error::parameter(
            "record_every",
            format!(
                "is too small for this run: {what} needs {gb:.3} GB more, which cannot be allocated; \
                 raise record_every, simulate fewer parts or split the batch"
            ),
        )
    })?;
    advise_huge_pages(v);
    Ok(())
}

/// `n` zeros, allocated fallibly and zeroed by the allocator (for large buffers, pages the kernel
/// maps lazily: a buffer nobody writes costs no page faults until it is read).
pub fn zeroed(n: usize, what: &str) -> Result<Vec<f64>> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let too_big = || {
        Error::parameter(
            "record_every",
            format!(
                "is too small for this run: {what} needs {:.3} GB more, which cannot be allocated; \
                 raise record_every, simulate fewer parts or split the batch",
                n as f64 * 8.0 / 1e9
            ),
        )
    };
    let layout = std::alloc::Layout::array::<f64>(n).map_err(|_| too_big())?;
    // SAFETY: the layout has non-zero size; a null return is handled; the zeroed allocation is
    // `n` valid f64 (all-zero bits are 0.0) owned by the Vec with the global allocator's layout.
    unsafe {
        let ptr = std::alloc::alloc_zeroed(layout) as *mut f64;
        if ptr.is_null() {
            return Err(too_big());
        }
        Ok(Vec::from_raw_parts(ptr, n, n))
    }
}

/// Buffers of at least this many elements are kept for reuse by [`scratch`] (smaller ones the
/// allocator reuses by itself).
const SPARE_FROM: usize = 1 << 16;
/// At most this many spare buffers are kept.
const SPARES: usize = 36;

fn spares() -> &'static std::sync::Mutex<Vec<Vec<f64>>> {
    static SPARE: std::sync::OnceLock<std::sync::Mutex<Vec<Vec<f64>>>> = std::sync::OnceLock::new();
    SPARE.get_or_init(Default::default)
}

/// An empty buffer with room for `n` elements, for state that lives only during a call: a buffer
/// [`recycle`]d by an earlier call when one fits (its pages are already mapped, so a simulation
/// called again and again pays no page faults for its state), else a new one on huge pages.
pub fn scratch(n: usize) -> Vec<f64> {
    if n >= SPARE_FROM {
        let mut spare = spares().lock().unwrap_or_else(|e| e.into_inner());
        let fit = spare
            .iter()
            .enumerate()
            .filter(|(_, v)| v.capacity() >= n && v.capacity() <= 4 * n)
            .min_by_key(|(_, v)| v.capacity())
            .map(|(i, _)| i);
        if let Some(i) = fit {
            return spare.swap_remove(i);
        }
    }
    let mut v = Vec::with_capacity(n);
    advise_huge_pages(&v);
    v.clear();
    v
}

/// Gives a [`scratch`] buffer back for reuse (the largest are kept).
pub fn recycle(mut v: Vec<f64>) {
    if v.capacity() < SPARE_FROM {
        return;
    }
    v.clear();
    let mut spare = spares().lock().unwrap_or_else(|e| e.into_inner());
    spare.push(v);
    if spare.len() > SPARES {
        let smallest = (0..spare.len())
            .min_by_key(|&i| spare[i].capacity())
            .unwrap_or(0);
        spare.swap_remove(smallest);
    }
}

/// Asks the kernel to back the spare capacity of `v` with huge pages (a hint: it may decline).
#[cfg(target_os = "linux")]
fn advise_huge_pages<T>(v: &Vec<T>) {
    let spare = (v.capacity() - v.len()) * std::mem::size_of::<T>();
    if spare < HUGE_FROM {
        return;
    }
    const PAGE: usize = 4096;
    let first = v.as_ptr() as usize + v.len() * std::mem::size_of::<T>();
    let start = first.div_ceil(PAGE) * PAGE;
    let end = (first + spare) / PAGE * PAGE;
    if end > start {
        // SAFETY: the range lies inside the vector's own allocation, page-aligned; madvise only
        // changes how the kernel backs those pages, never their contents.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages<T>(_v: &Vec<T>) {
    let _ = HUGE_FROM;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_impossible_reservation_is_an_error_not_an_abort() {
        let mut v: Vec<f64> = Vec::new();
        let err = reserve(&mut v, usize::MAX / 16, "the positions").unwrap_err();
        assert!(err.to_string().contains("raise record_every"), "{err}");
        reserve(&mut v, 3 << 20, "the positions").unwrap();
        assert!(v.capacity() >= 3 << 20);
        assert!(zeroed(usize::MAX / 4, "the angles").is_err());
        let z = zeroed(3 << 20, "the angles").unwrap();
        let a = scratch(1 << 20);
        assert!(a.is_empty() && a.capacity() >= 1 << 20);
        let at = a.as_ptr();
        recycle(a);
        let b = scratch(1 << 20);
        assert!(b.is_empty() && b.capacity() >= 1 << 20);
        // The recycled buffer is reused (unless another test took it meanwhile).
        let _ = b.as_ptr() == at;
        assert!(z.len() == 3 << 20 && z.iter().all(|&a| a == 0.0));
    }
}
