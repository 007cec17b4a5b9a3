//! Deterministic data parallelism over independent items.
//!
//! Items are computed independently and written to their own slot, so results are bitwise
//! identical for any number of threads. Batches are processed in fixed chunks so a caller (the
//! Python binding) can check for interrupts between chunks.
//!
//! Every parallel section of the core splits its items no finer than [`min_len`] and joins
//! through [`join`], so that a call made in [`serial`] runs on its caller's thread alone: one
//! thread without a pool, whose hand-off (the job queued, a worker woken, the caller woken when it
//! is done) costs tens of microseconds on a busy machine, a small call's whole cost several times
//! over.

use std::cell::Cell;

use rayon::prelude::*;

use crate::error::Result;

thread_local! {
    static SERIAL: Cell<bool> = const { Cell::new(false) };
}

/// `work()` on this thread with every parallel section of the core in it run in order on this
/// thread (the same results, bit for bit, as on a pool of any size).
pub fn serial<T>(work: impl FnOnce() -> T) -> T {
    let _alone = Alone::when(true);
    work()
}

/// While it lives (from [`Alone::when`] with `true`), this thread's parallel sections run in
/// order on it, as in [`serial`]; the thread's earlier state comes back when it is dropped (also
/// by a panic).
#[must_use = "the sections run alone only while it lives"]
pub struct Alone(bool);

impl Alone {
    /// This thread's sections alone from now on if `alone` (as they were otherwise).
    pub fn when(alone: bool) -> Self {
        Alone(SERIAL.with(|s| s.replace(alone || s.get())))
    }
}

impl Drop for Alone {
    fn drop(&mut self) {
        SERIAL.with(|s| s.set(self.0));
    }
}

/// Whether this thread runs in [`serial`].
pub fn is_serial() -> bool {
    SERIAL.with(Cell::get)
}

/// The fewest items a parallel section gives one task: every item in [`serial`] (so the section
/// runs on this thread, never handed to a pool), one otherwise.
pub fn min_len() -> usize {
    if is_serial() {
        usize::MAX
    } else {
        1
    }
}

/// The threads a parallel section may spread over: one in [`serial`], the current pool's
/// otherwise.
pub fn threads() -> usize {
    if is_serial() {
        1
    } else {
        rayon::current_num_threads()
    }
}

/// `(a(), b())`: side by side on the current pool ([`rayon::join`]), or in order on this thread
/// in [`serial`].
pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    if is_serial() {
        (a(), b())
    } else {
        rayon::join(a, b)
    }
}

/// Items per chunk: large enough to amortise scheduling, small enough to react to Ctrl-C quickly.
pub const CHUNK: usize = 4096;

/// `f(i)` for `i` in `range`, in parallel, in order. On failure returns the error of the lowest
/// failing index (so the reported error does not depend on the thread count), with its index.
pub fn try_map<T, F>(range: std::ops::Range<usize>, f: F) -> Result<Vec<T>>
where
    T: Send,
    F: Fn(usize) -> Result<T> + Sync + Send,
{
    let results: Vec<Result<T>> = range
        .into_par_iter()
        .with_min_len(min_len().max(16))
        .map(&f)
        .collect();
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

    /// A serial call runs every section on its caller's thread (without it, a pool's workers
    /// take some of the items), with the same results; the flag ends with it, also by a panic.
    #[test]
    fn serial_runs_on_the_calling_thread() {
        let me = std::thread::current().id();
        let f = |i: usize| Ok((((i as f64) * 0.37).sin(), std::thread::current().id()));
        let spread = pool(2).unwrap().install(|| try_map(0..50_000, f)).unwrap();
        assert!(spread.iter().any(|(_, id)| *id != me));
        let (alone, inner) = serial(|| join(|| try_map(0..50_000, f).unwrap(), threads));
        assert!(alone.iter().all(|(_, id)| *id == me));
        assert_eq!(inner, 1);
        let bits = |v: &[(f64, std::thread::ThreadId)]| {
            v.iter().map(|x| x.0.to_bits()).collect::<Vec<_>>()
        };
        assert_eq!(bits(&alone), bits(&spread));
        let ones = serial(|| {
            let mut v = vec![(0usize, me); 10_000];
            v.par_chunks_mut(7)
                .with_min_len(min_len())
                .for_each(|c| c.fill((1, std::thread::current().id())));
            v
        });
        assert!(ones.iter().all(|&(one, id)| one == 1 && id == me));
        assert!(std::panic::catch_unwind(|| serial(|| panic!("in serial"))).is_err());
        assert!(!is_serial() && min_len() == 1);
    }

    /// `Alone::when(false)` leaves the thread as it was (alone inside `serial`), `when(true)`
    /// makes it alone until dropped, nested or not.
    #[test]
    fn alone_lasts_while_it_lives_and_nests() {
        {
            let _not = Alone::when(false);
            assert!(!is_serial());
            let _alone = Alone::when(true);
            assert!(is_serial() && threads() == 1);
        }
        assert!(!is_serial());
        serial(|| {
            let _not = Alone::when(false);
            assert!(is_serial());
        });
        assert!(!is_serial());
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
