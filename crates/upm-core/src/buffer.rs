//! Large result buffers. They are reserved fallibly, so a result too big for memory is an
//! [`Error`], never an abort of the process, and kept for reuse when their owner is done with
//! them ([`recycle`]), so a caller that simulates again and again writes into memory already
//! mapped instead of paying a page fault per 4 KiB for every call.
//!
//! They are not advised onto transparent huge pages: with the kernel's default `defrag=madvise`
//! a first touch of advised memory compacts memory synchronously, and on a machine up for hours
//! that made the first call recording 1 GB take 4 s instead of 0.33 s (and a 2-step call on 1e6
//! parts 0.9 s instead of 0.1 s).

use crate::error::{Error, Result};

/// The error for a result of `bytes` bytes that cannot be allocated; `what` names it.
fn too_big(bytes: f64, what: &str) -> Error {
    Error::parameter(
        "record_every",
        format!(
            "is too small for this run: {what} needs {:.3} GB more, which cannot be allocated; \
             raise record_every, simulate fewer parts or split the batch",
            bytes / 1e9
        ),
    )
}

/// Reserves room for exactly `n` more elements of `v`; `what` names the result in the error.
pub fn reserve<T>(v: &mut Vec<T>, n: usize, what: &str) -> Result<()> {
    v.try_reserve_exact(n)
        .map_err(|_| too_big(n as f64 * std::mem::size_of::<T>() as f64, what))
}

/// `n` zeros, allocated fallibly and zeroed by the allocator (for large buffers, pages the kernel
/// maps lazily: a buffer nobody writes costs no page faults until it is read).
pub fn zeroed(n: usize, what: &str) -> Result<Vec<f64>> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let error = || too_big(n as f64 * 8.0, what);
    let layout = std::alloc::Layout::array::<f64>(n).map_err(|_| error())?;
    // SAFETY: the layout has non-zero size; a null return is handled; the zeroed allocation is
    // `n` valid f64 (all-zero bits are 0.0) owned by the Vec with the global allocator's layout.
    unsafe {
        let ptr = std::alloc::alloc_zeroed(layout) as *mut f64;
        if ptr.is_null() {
            return Err(error());
        }
        Ok(Vec::from_raw_parts(ptr, n, n))
    }
}

/// Buffers of at least this many elements are kept for reuse by [`scratch`] (smaller ones the
/// allocator reuses by itself).
const SPARE_FROM: usize = 1 << 16;
/// At most this many spare buffers are kept, and at most this many bytes in all (the largest
/// are kept when there are more).
const SPARES: usize = 36;
const SPARE_BYTES: usize = 1 << 30;

fn spares() -> &'static std::sync::Mutex<Vec<Vec<f64>>> {
    static SPARE: std::sync::OnceLock<std::sync::Mutex<Vec<Vec<f64>>>> = std::sync::OnceLock::new();
    SPARE.get_or_init(Default::default)
}

/// An empty buffer with room for `n` elements, for state that lives only during a call: a buffer
/// [`recycle`]d by an earlier call when one fits (its pages are already mapped, so a simulation
/// called again and again pays no page faults for its state), else a new one.
pub fn scratch(n: usize) -> Vec<f64> {
    if let Some(v) = spare(n, false) {
        return v;
    }
    Vec::with_capacity(n)
}

/// A spare buffer with room for `n` (at most 4n) elements, if one is kept (with an even capacity
/// if `even`).
fn spare(n: usize, even: bool) -> Option<Vec<f64>> {
    if n < SPARE_FROM {
        return None;
    }
    let mut spare = spares().lock().unwrap_or_else(|e| e.into_inner());
    let fit = spare
        .iter()
        .enumerate()
        .filter(|(_, v)| v.capacity() >= n && v.capacity() <= 4 * n)
        .filter(|(_, v)| !even || v.capacity().is_multiple_of(2))
        .min_by_key(|(_, v)| v.capacity())
        .map(|(i, _)| i)?;
    Some(spare.swap_remove(fit))
}

/// An empty buffer with room for `n` values, for a result: a [`recycle`]d buffer when one fits
/// (a result that was handed back, e.g. by the NumPy array that owned it: its pages are mapped,
/// so a caller that simulates again and again pays no page faults for its results), else one
/// reserved fallibly; `what` names the result in the error.
pub fn result(n: usize, what: &str) -> Result<Vec<f64>> {
    taken(n, false, what)
}

/// [`result`] for `n` pairs.
pub fn result_pairs(n: usize, what: &str) -> Result<Vec<[f64; 2]>> {
    let twice = n
        .checked_mul(2)
        .ok_or_else(|| too_big(n as f64 * 16.0, what))?;
    Ok(pairs(taken(twice, true, what)?))
}

/// A [`spare`] buffer with room for `n` values (an even capacity if `even`), or a new one
/// reserved fallibly.
fn taken(n: usize, even: bool, what: &str) -> Result<Vec<f64>> {
    match spare(n, even) {
        Some(v) => Ok(v),
        None => {
            let mut v = Vec::new();
            reserve(&mut v, n, what)?;
            Ok(v)
        }
    }
}

/// An empty buffer of pairs over the allocation of `v` (an even capacity).
fn pairs(v: Vec<f64>) -> Vec<[f64; 2]> {
    assert!(v.is_empty() && v.capacity().is_multiple_of(2));
    let mut v = std::mem::ManuallyDrop::new(v);
    // SAFETY: [f64; 2] has f64's alignment and twice its size, so capacity/2 pairs span exactly
    // the allocation (same size and alignment for the allocator); the vector is empty.
    unsafe { Vec::from_raw_parts(v.as_mut_ptr().cast::<[f64; 2]>(), 0, v.capacity() / 2) }
}

/// Gives a [`scratch`] or result buffer back for reuse (the largest are kept, within
/// [`SPARES`] buffers and [`SPARE_BYTES`]).
pub fn recycle(mut v: Vec<f64>) {
    if v.capacity() < SPARE_FROM || v.capacity() > SPARE_BYTES / 8 {
        return;
    }
    v.clear();
    let mut spare = spares().lock().unwrap_or_else(|e| e.into_inner());
    spare.push(v);
    let bytes = |s: &Vec<Vec<f64>>| s.iter().map(|v| v.capacity() * 8).sum::<usize>();
    while spare.len() > SPARES || bytes(&spare) > SPARE_BYTES {
        let smallest = (0..spare.len())
            .min_by_key(|&i| spare[i].capacity())
            .unwrap_or(0);
        spare.swap_remove(smallest);
    }
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
        recycle(a);
        let b = scratch(1 << 20);
        assert!(b.is_empty() && b.capacity() >= 1 << 20);
        assert!(z.len() == 3 << 20 && z.iter().all(|&a| a == 0.0));
    }

    #[test]
    fn a_result_given_back_is_reused_as_pairs_and_the_pool_is_bounded() {
        let mut p = result_pairs(1 << 18, "the positions").unwrap();
        assert!(p.is_empty() && p.capacity() >= 1 << 18);
        p.extend((0..1 << 18).map(|i| [i as f64, -(i as f64)]));
        recycle(p.into_flattened());
        let q = result_pairs(1 << 18, "the positions").unwrap();
        assert!(q.is_empty() && q.capacity() >= 1 << 18);
        // Too large to keep: dropped, not pooled.
        recycle(Vec::with_capacity(SPARE_BYTES / 8 + 1));
        let spare = spares().lock().unwrap_or_else(|e| e.into_inner());
        assert!(spare.len() <= SPARES);
        assert!(spare.iter().map(|v| v.capacity() * 8).sum::<usize>() <= SPARE_BYTES);
        assert!(spare.iter().all(Vec::is_empty));
    }
}
