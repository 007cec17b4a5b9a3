//! Deterministic data parallelism over independent items.
//!
//! Items are computed independently and written to their own slot, so results are bitwise
//! identical for any number of threads. Batches are processed in fixed chunks so a caller (the
//! Python binding) can check for interrupts between chunks.

use rayon::prelude::*;

use crate::error::Result;

/// Items per chunk: large enough to amortise scheduling, small enough to react to Ctrl-C quickly.
pub const CHUNK: usize = 4096;

/// `f(i)` for `i` in `range`, in parallel, in order. On failure returns the error of the lowest
/// failing index (so the reported error does not depend on the thread count), with its index.
pub fn try_map<T, F>(range: std::ops::Range<usize>, f: F) -> Result<Vec<T>>
where
    T: Send,
    F: Fn(usize) -> Result<T> + Sync + Send,
{
    let results: Vec<Result<T>> = range.into_par_iter().with_min_len(16).map(&f).collect();
    let mut out = Vec::with_capacity(results.len());
    for r in results {
        out.push(r?);
    }
    Ok(out)
}

/// [`try_map`] over `0..n` in chunks of [`CHUNK`], calling `between(done)` after each chunk; an
/// error from `between` (e.g. an interrupt) stops the batch.
pub fn try_map_chunked<T, F, B, E>(n: usize, f: F, mut between: B) -> std::result::Result<Vec<T>, E>
where
    T: Send,
    F: Fn(usize) -> Result<T> + Sync + Send,
    B: FnMut(usize) -> std::result::Result<(), E>,
    E: From<crate::Error>,
{
    let mut out = Vec::with_capacity(n);
    let mut start = 0;
    while start < n {
        let end = (start + CHUNK).min(n);
        let chunk = try_map(start..end, |i| {
            f(i).map_err(|e| e.with_context(&format!("at flat index {i}")))
        })?;
        out.extend(chunk);
        between(end)?;
        start = end;
    }
    Ok(out)
}

/// A dedicated pool of `n` threads (every rayon call inside its `install` uses it). Results do not
/// depend on the thread count (see above).
pub fn pool(n: usize) -> Result<rayon::ThreadPool> {
    if n == 0 {
        return Err(crate::Error::parameter("threads", "must be >= 1"));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| crate::Error::parameter("threads", format!("no pool of {n}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;

    #[test]
    fn pool_has_that_many_threads() {
        assert_eq!(pool(1).unwrap().install(rayon::current_num_threads), 1);
        assert_eq!(pool(3).unwrap().install(rayon::current_num_threads), 3);
        assert!(pool(0).is_err());
    }

    #[test]
    fn identical_for_one_and_two_threads() {
        let f = |i: usize| Ok(((i as f64) * 0.37).sin().powi(3));
        let (one, two) = (pool(1).unwrap(), pool(2).unwrap());
        let a: Vec<f64> = one.install(|| try_map(0..10_000, f)).unwrap();
        let b: Vec<f64> = two.install(|| try_map(0..10_000, f)).unwrap();
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    #[test]
    fn reports_the_lowest_failing_index() {
        let f = |i: usize| {
            if i % 1000 == 999 {
                Err(Error::parameter("x", format!("bad {i}")))
            } else {
                Ok(i)
            }
        };
        let e = try_map_chunked(10_000, f, |_| Ok::<(), Error>(())).unwrap_err();
        assert_eq!(e.to_string(), "x bad 999 (at flat index 999)");
    }
}
