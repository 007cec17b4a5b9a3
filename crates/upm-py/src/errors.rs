//! Error mapping and the one helper every long call goes through.
//!
//! `upm_core::Error` variants map one-to-one onto the Python tree in `upm._errors` (root
//! `upm.UpmError`). Heavy work runs with the GIL released, in fixed chunks with a signal check
//! between them (so Ctrl-C works), and inside `catch_unwind`, so a Rust panic surfaces as
//! `upm.InternalError` instead of crossing into Python.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use pyo3::exceptions::PyImportError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyType;
use upm_core::Error;

/// Failures inside a detached call: a core error, a Python error (an interrupt) or a panic.
pub enum Failure {
    Core(Error),
    Python(PyErr),
    Panic(String),
}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        Failure::Core(e)
    }
}

impl From<PyErr> for Failure {
    fn from(e: PyErr) -> Self {
        Failure::Python(e)
    }
}

/// The exception classes of `upm._errors` the extension raises, each fetched once.
#[derive(Clone, Copy)]
enum Class {
    Parameter,
    Shape,
    Convergence,
    Internal,
}

impl Class {
    fn name(self) -> &'static str {
        match self {
            Class::Parameter => "ParameterError",
            Class::Shape => "ShapeError",
            Class::Convergence => "ConvergenceError",
            Class::Internal => "InternalError",
        }
    }
}

static CLASSES: [PyOnceLock<Py<PyType>>; 4] = [
    PyOnceLock::new(),
    PyOnceLock::new(),
    PyOnceLock::new(),
    PyOnceLock::new(),
];

/// An instance of `class` with `message`. Should the class not load (`_core` imported without
/// its package, or `upm._errors` broken), the error says so, with the original message and the
/// cause chained: never a built-in exception passed off as upm's.
fn exception(py: Python<'_>, class: Class, message: String) -> PyErr {
    let found = CLASSES[class as usize]
        .import(py, "upm._errors", class.name())
        .and_then(|c| c.call1((message.clone(),)));
    match found {
        Ok(instance) => PyErr::from_value(instance),
        Err(cause) => {
            let err = PyImportError::new_err(format!(
                "upm._core could not load its exception class upm._errors.{} to raise: {message}",
                class.name()
            ));
            err.set_cause(py, Some(cause));
            err
        }
    }
}

/// A core error as the matching `upm` exception.
pub fn to_py(py: Python<'_>, e: Error) -> PyErr {
    let class = match e {
        Error::Parameter { .. } => Class::Parameter,
        Error::Shape(_) => Class::Shape,
        Error::Convergence(_) => Class::Convergence,
    };
    exception(py, class, e.to_string())
}

/// An `InternalError` with `message`: an invariant of the binding broken (a bug).
pub fn internal(py: Python<'_>, message: String) -> PyErr {
    exception(
        py,
        Class::Internal,
        format!("internal error in upm (please report it): {message}"),
    )
}

/// A `ShapeError` with `message`.
pub fn shape_error(py: Python<'_>, message: String) -> PyErr {
    exception(py, Class::Shape, message)
}

fn failure_to_py(py: Python<'_>, f: Failure) -> PyErr {
    match f {
        Failure::Core(e) => to_py(py, e),
        Failure::Python(e) => e,
        Failure::Panic(m) => internal(py, m),
    }
}

fn panic_message(p: Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a Rust panic".to_string())
}

/// Runs `work` with the GIL released; panics and errors come back as Python exceptions.
pub fn detached<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, Failure> + Send,
{
    let result = py.detach(|| match catch_unwind(AssertUnwindSafe(work)) {
        Ok(r) => r,
        Err(p) => Err(Failure::Panic(panic_message(p))),
    });
    result.map_err(|f| failure_to_py(py, f))
}

/// The Ctrl-C check long calls run between blocks (`_done`: their progress): a pending SIGINT
/// becomes the call's error.
pub fn interrupted(_done: usize) -> Result<(), Failure> {
    Python::attach(|py| py.check_signals()).map_err(Failure::from)
}

/// `work(between)` on a pool of `threads` threads, or on this thread: with rayon's global pool
/// (`None`), or alone (one thread: [`upm_core::parallel::serial`], no pool to hand the work to and
/// wait for); `between` is the Ctrl-C check `work` runs between its blocks.
///
/// CPython acts on signals only on its main thread, and `work` runs as a job on a worker of the
/// pool (one kept for this thread, [`pool_of`]), so with a pool this thread waits for `work` and
/// checks for signals itself, every 20 ms;
/// a pending SIGINT is handed to `work`'s next `between`, which stops it with that error (and
/// ends the call with it if `work` had already passed its last check).
pub fn on_threads<T, F>(threads: Option<usize>, work: F) -> Result<T, Failure>
where
    T: Send,
    F: FnOnce(&(dyn Fn(usize) -> Result<(), Failure> + Sync)) -> Result<T, Failure> + Send,
{
    // rayon's global pool does not survive fork(): its threads exist only in the parent, so a
    // forked child (multiprocessing's default start method) that used it would wait forever.
    // Such a child runs on a pool of its own, of the same size.
    static GLOBAL_POOL_PID: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    let forked = *GLOBAL_POOL_PID.get_or_init(std::process::id) != std::process::id();
    let n = match threads {
        Some(1) => return upm_core::parallel::serial(|| work(&interrupted)),
        None if !forked => return work(&interrupted),
        Some(n) => n,
        None => rayon::current_num_threads(),
    };
    let pool = pool_of(n)?;
    let signal: Mutex<Option<PyErr>> = Mutex::new(None);
    let between = |_done: usize| match signal.lock().map(|mut s| s.take()) {
        Ok(Some(e)) => Err(Failure::Python(e)),
        _ => Ok(()),
    };
    let mut outcome = None;
    // `work` goes to the pool as a job (no thread is started for it); this thread waits for it
    // here, checking for signals. A panic in the job comes back here when the scope ends.
    pool.in_place_scope(|scope| {
        let (sender, receiver) = mpsc::channel();
        let (slot, between) = (&mut outcome, &between);
        scope.spawn(move |_| {
            *slot = Some(work(between));
            // The receiver only goes away once the scope has ended.
            let _ = sender.send(());
        });
        let mut pending = true;
        while let Err(RecvTimeoutError::Timeout) = receiver.recv_timeout(Duration::from_millis(20))
        {
            if pending {
                if let Err(e) = Python::attach(|py| py.check_signals()) {
                    pending = false;
                    if let Ok(mut s) = signal.lock() {
                        *s = Some(e);
                    }
                }
            }
        }
    });
    let result = outcome.unwrap_or_else(|| {
        Err(Failure::Panic(
            "the pool ended without running the call".into(),
        ))
    });
    // A signal caught after `work`'s last check still ends the call with its error.
    match signal.lock().ok().and_then(|mut s| s.take()) {
        Some(e) => Err(Failure::Python(e)),
        None => result,
    }
}

/// Pools kept for reuse, per calling thread (two threads calling with `threads=1` each keep
/// their own pool, so their calls run side by side as before) and per process (a forked child
/// has none of its parent's pool threads): building one took about 100 us, a small call's
/// whole cost several times over.
const KEPT_POOLS: usize = 4;

thread_local! {
    static POOLS: std::cell::RefCell<Vec<(u32, usize, Arc<rayon::ThreadPool>)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// A pool of `n` threads for this thread's calls: kept from an earlier call, or new (and kept
/// while fewer than [`KEPT_POOLS`] are).
fn pool_of(n: usize) -> Result<Arc<rayon::ThreadPool>, Failure> {
    let pid = std::process::id();
    let kept = POOLS.with(|p| {
        p.borrow()
            .iter()
            .find(|(id, size, _)| (*id, *size) == (pid, n))
            .map(|(_, _, pool)| pool.clone())
    });
    if let Some(pool) = kept {
        return Ok(pool);
    }
    let pool = Arc::new(upm_core::parallel::pool(n)?);
    POOLS.with(|p| {
        let mut p = p.borrow_mut();
        if p.len() < KEPT_POOLS {
            p.push((pid, n, pool.clone()));
        }
    });
    Ok(pool)
}

/// `f(i)` for `i` in `0..n`, in parallel, GIL released, checking for Ctrl-C between chunks.
pub fn batch<T, F>(py: Python<'_>, n: usize, f: F) -> PyResult<Vec<T>>
where
    T: Send,
    F: Fn(usize) -> upm_core::Result<T> + Sync + Send,
{
    batch_on(py, n, None, f)
}

/// [`batch`] on a pool of `threads` threads (`None`: rayon's global pool).
pub fn batch_on<T, F>(py: Python<'_>, n: usize, threads: Option<usize>, f: F) -> PyResult<Vec<T>>
where
    T: Send,
    F: Fn(usize) -> upm_core::Result<T> + Sync + Send,
{
    detached(py, || {
        on_threads(threads, |between| {
            upm_core::parallel::try_map_chunked(n, &f, between)
        })
    })
}

/// A core result as a Python result.
pub fn core<T>(py: Python<'_>, r: upm_core::Result<T>) -> PyResult<T> {
    r.map_err(|e| to_py(py, e))
}
