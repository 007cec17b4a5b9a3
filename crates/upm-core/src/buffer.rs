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

/// Spare buffers of one element type, kept by [`recycle`] and [`recycle_flags`].
struct Pool<T>(std::sync::Mutex<Vec<Vec<T>>>);

/// Spare buffers of values (state, positions, velocities, times) and of flags (stuck, left).
static VALUES: Pool<f64> = Pool::new();
static FLAGS: Pool<bool> = Pool::new();

impl<T> Pool<T> {
    const fn new() -> Self {
        Pool(std::sync::Mutex::new(Vec::new()))
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Vec<T>>> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A spare buffer with room for `n` (at most 4n) elements, if one is kept (with an even
    /// capacity if `even`).
    fn take(&self, n: usize, even: bool) -> Option<Vec<T>> {
        if n < SPARE_FROM {
            return None;
        }
        let mut spare = self.lock();
        let fit = spare
            .iter()
            .enumerate()
            .filter(|(_, v)| v.capacity() >= n && v.capacity() <= 4 * n)
            .filter(|(_, v)| !even || v.capacity().is_multiple_of(2))
            .min_by_key(|(_, v)| v.capacity())
            .map(|(i, _)| i)?;
        Some(spare.swap_remove(fit))
    }

    /// A spare buffer with room for `n` elements (an even capacity if `even`), or a new one
    /// reserved fallibly; `what` names the result in the error.
    fn taken(&self, n: usize, even: bool, what: &str) -> Result<Vec<T>> {
        match self.take(n, even) {
            Some(v) => Ok(v),
            None => {
                let mut v = Vec::new();
                reserve(&mut v, n, what)?;
                Ok(v)
            }
        }
    }

    /// Keeps `v` for reuse (the largest are kept, within [`SPARES`] buffers and
    /// [`SPARE_BYTES`]).
    fn give(&self, mut v: Vec<T>) {
        let size = std::mem::size_of::<T>();
        if v.capacity() < SPARE_FROM || v.capacity() > SPARE_BYTES / size {
            return;
        }
        v.clear();
        let mut spare = self.lock();
        spare.push(v);
        let bytes = |s: &Vec<Vec<T>>| s.iter().map(|v| v.capacity() * size).sum::<usize>();
        while spare.len() > SPARES || bytes(&spare) > SPARE_BYTES {
            let smallest = (0..spare.len())
                .min_by_key(|&i| spare[i].capacity())
                .unwrap_or(0);
            spare.swap_remove(smallest);
        }
    }
}

/// An empty buffer with room for `n` elements, for state that lives only during a call: a buffer
/// [`recycle`]d by an earlier call when one fits (its pages are already mapped, so a simulation
/// called again and again pays no page faults for its state), else a new one.
pub fn scratch(n: usize) -> Vec<f64> {
    if let Some(v) = VALUES.take(n, false) {
        return v;
    }
    Vec::with_capacity(n)
}

/// An empty buffer with room for `n` values, for a result: a [`recycle`]d buffer when one fits
/// (a result that was handed back, e.g. by the NumPy array that owned it: its pages are mapped,
/// so a caller that simulates again and again pays no page faults for its results), else one
/// reserved fallibly; `what` names the result in the error.
pub fn result(n: usize, what: &str) -> Result<Vec<f64>> {
    VALUES.taken(n, false, what)
}

/// [`result`] for `n` pairs.
pub fn result_pairs(n: usize, what: &str) -> Result<Vec<[f64; 2]>> {
    let twice = n
        .checked_mul(2)
        .ok_or_else(|| too_big(n as f64 * 16.0, what))?;
    Ok(pairs(VALUES.taken(twice, true, what)?))
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
pub fn recycle(v: Vec<f64>) {
    VALUES.give(v);
}

/// [`result`] for `n` flags (stuck, left the plate): a buffer of flags handed back by
/// [`recycle_flags`] when one fits, else one reserved fallibly.
pub fn result_flags(n: usize, what: &str) -> Result<Vec<bool>> {
    FLAGS.taken(n, false, what)
}

/// [`recycle`] for a buffer of flags.
pub fn recycle_flags(v: Vec<bool>) {
    FLAGS.give(v);
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
    fn flags_given_back_are_reused_and_kept_apart_from_values() {
        // (a size no other test asks for: the pools are the process's)
        let n = 3_000_017;
        let mut f = result_flags(n, "the stuck flags").unwrap();
        assert!(f.is_empty() && f.capacity() >= n);
        f.resize(n, true);
        let at = f.as_ptr();
        recycle_flags(f);
        let g = result_flags(n, "the stuck flags").unwrap();
        assert!(g.is_empty() && g.capacity() >= n);
        assert_eq!(
            g.as_ptr(),
            at,
            "the flags handed back are the ones taken next"
        );
        assert!(VALUES
            .lock()
            .iter()
            .all(|v| v.as_ptr().cast::<bool>() != at));
        assert!(result_flags(usize::MAX / 2, "the stuck flags").is_err());
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
        let spare = VALUES.lock();
        assert!(spare.len() <= SPARES);
        assert!(spare.iter().map(|v| v.capacity() * 8).sum::<usize>() <= SPARE_BYTES);
        assert!(spare.iter().all(Vec::is_empty));
    }
}
