//! Throughput of the exact root-based averages, one thread against all threads, in one run.
//!
//! `cargo bench -p upm-core --bench theory` (the NumPy peer is `bench/theory.py`). Prints items per
//! second for a single rayon thread and for the machine's pool, and their ratio.

use std::f64::consts::TAU;
use std::hint::black_box;
use std::time::Instant;

use upm_core::friction::{feed_rate, two_sinusoid_force};
use upm_core::parallel::try_map;
use upm_core::{Harmonics, Waveform};

fn time<T>(f: impl Fn() -> T) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let start = Instant::now();
        black_box(f());
        best = best.min(start.elapsed().as_secs_f64());
    }
    best
}

fn main() {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let threads = rayon::current_num_threads();
    let n_psi = 200_000;
    let psi: Vec<f64> = (0..n_psi)
        .map(|i| TAU * (i as f64 + 0.5) / n_psi as f64)
        .collect();
    let n_pairs = 40_000;
    let pairs: Vec<(f64, f64)> = (0..n_pairs)
        .map(|i| {
            (
                2.0 * ((i * 7919) % n_pairs) as f64 / n_pairs as f64,
                TAU * (i as f64) / n_pairs as f64 - 3.0,
            )
        })
        .collect();

    println!(
        "{:<38} {:>12} {:>12} {:>8}",
        "",
        "1 thread",
        format!("{threads} threads"),
        "ratio"
    );
    for (n1, n2) in [(1, 2), (2, 5), (3, 7)] {
        let run = || try_map(0..n_psi, |i| two_sinusoid_force(n1, n2, psi[i], 1.0)).unwrap();
        let (t1, tn) = (one.install(|| time(run)), time(run));
        let label = format!("force_table({n1}, {n2}) [M psi/s]");
        println!(
            "{label:<38} {:>12.3} {:>12.3} {:>7.2}x",
            n_psi as f64 / t1 / 1e6,
            n_psi as f64 / tn / 1e6,
            t1 / tn
        );
    }
    let run = || {
        try_map(0..n_pairs, |i| {
            let w: Waveform = Harmonics::two_harmonic(pairs[i].0, pairs[i].1, 1.0, 1.0)?.into();
            feed_rate(&w)
        })
        .unwrap()
    };
    let (t1, tn) = (one.install(|| time(run)), time(run));
    let label = "feed_rate(TwoHarmonic) [k pairs/s]";
    println!(
        "{label:<38} {:>12.1} {:>12.1} {:>7.2}x",
        n_pairs as f64 / t1 / 1e3,
        n_pairs as f64 / tn / 1e3,
        t1 / tn
    );
}
