//! The point-part step against the hardware's bound for it, in one run.
//!
//! `cargo bench -p upm-core --bench kernel` (the NumPy and MuJoCo peers are `bench/integrator.py`).
//! Every exact Coulomb step of a point part takes one square root and one division (docs/spec.md §1), so a
//! four-lane `sqrt` plus a division, timed on independent data of realistic magnitude, bounds the
//! ns per part-step one core can reach with correctly rounded results. Prints that bound, the
//! integrator's ns per part-step on one rayon thread (1e5 parts, translating + rotating plate, no
//! recording but the last step), and their ratio.

use std::hint::black_box;
use std::time::Instant;

use upm_core::motion::PlateMotion;
use upm_core::sim::{simulate, Config, Parts};
use upm_core::{Harmonics, Waveform};

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    (0..runs)
        .map(|_| {
            let start = Instant::now();
            black_box(f());
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Seconds per element of `sqrt` then division, over `q` (four lanes at a time where the
/// compiler vectorises; AVX2 is enabled at run time like the kernel's).
fn divider_bound(q: &[f64]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        #[target_feature(enable = "avx2")]
        unsafe fn pass(q: &[f64], out: &mut [f64]) {
            for (o, &v) in out.iter_mut().zip(q) {
                *o = 3e-4 / v.sqrt();
            }
        }
        let mut out = vec![0.0; q.len()];
        let reps = 2000;
        // SAFETY: AVX2 is present (checked above).
        let t = best_of(5, || {
            for _ in 0..reps {
                unsafe { pass(black_box(q), &mut out) };
            }
            out[7]
        });
        return t / (reps * q.len()) as f64;
    }
    let mut out = vec![0.0; q.len()];
    let t = best_of(5, || {
        for _ in 0..2000 {
            for (o, &v) in out.iter_mut().zip(black_box(q)) {
                *o = 3e-4 / v.sqrt();
            }
        }
        out[7]
    });
    t / (2000 * q.len()) as f64
}

fn main() {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let f = 35.0;
    let trans = PlateMotion::translation(
        [0.6, 0.8],
        Waveform::Harmonics(Harmonics::two_harmonic(0.5, 1.57, 0.05, f).unwrap()),
    )
    .unwrap();
    let rot = PlateMotion::rotation(
        [0.03, -0.02],
        Waveform::Harmonics(Harmonics::new(vec![0.0], vec![0.5, -0.25], f).unwrap()),
    )
    .unwrap();
    let motion = PlateMotion::sequence(vec![
        trans.for_duration(2.0 / f).unwrap(),
        rot.for_duration(2.0 / f).unwrap(),
    ])
    .unwrap();
    let (n, steps) = (100_000, 1000);
    let dt = 1.0 / f / 400.0;
    let position: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let a = i as f64 * 0.618_033_988_75;
            [
                0.1 * (a.fract() * 2.0 - 1.0),
                0.1 * ((a * 7.0).fract() * 2.0 - 1.0),
            ]
        })
        .collect();
    let parts = Parts::points(position, vec![[0.0; 2]; n], vec![0.3; n], vec![0.4; n]);
    let cfg = Config {
        dt,
        duration: steps as f64 * dt,
        g: 9.81,
        plate_size: None,
        record_every: steps,
    };
    let t_sim = one.install(|| best_of(3, || simulate(&motion, &parts, &cfg).unwrap()));
    let per_step = t_sim / (n * steps) as f64;
    // |w|^2 of sliding parts: 1e-8 .. 1e-4 (m/s)^2, mantissas spread.
    let q: Vec<f64> = (0..256)
        .map(|i| 1e-8 * 10f64.powf(4.0 * ((i * 7919) % 256) as f64 / 256.0))
        .collect();
    let bound = divider_bound(&q);
    println!("point-part step, 1 thread, {n} parts x {steps} steps:");
    println!("  integrator          {:6.2} ns/part-step", per_step * 1e9);
    println!(
        "  sqrt + division     {:6.2} ns/element (bound)",
        bound * 1e9
    );
    println!("  integrator / bound  {:6.2}x", per_step / bound);
}
