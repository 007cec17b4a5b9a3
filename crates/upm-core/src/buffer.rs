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
    }
}
