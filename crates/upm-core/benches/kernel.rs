//! The point-part step of every build this CPU has, against the exact step's hardware bound.
//!
//! `cargo bench -p upm-core --bench kernel` (the NumPy, Numba and MuJoCo peers are
//! `bench/integrator.py`). Prints the integrator's ns per part-step on one rayon thread for each
//! build (`portable`, `avx2`, `avx512`: each in a child process with `UPM_SIMD` set), 1e3 to 1e6
//! parts on a translating + rotating plate, recording only the last step. Beside them: a
//! four-lane `sqrt` plus a division on independent data of realistic magnitude, the bound of a
//! step written with a correctly rounded root and division (the vector builds use neither).
//! `ONLY=trans` or `ONLY=rot` runs the disk and polygon benches (`--disks`, `--polygons`) on one
//! plate only (for a profile of one); `EVERY=k` makes every run record every `k`-th step instead
//! of the last only (the cost of recording). `--batch` runs the batch bench alone (on one thread
//! and on every core); `--batch-profile` then repeats its one-thread batch, and
//! `--batch-fixed-profile` its 2-step call on every core, for a profiler; `--batch --batch-only`
//! (`--world-only`) runs the batch (the one world) alone, 200 times, to compare their profiles.

use std::hint::black_box;
use std::time::Instant;

use upm_core::buffer::{recycle, recycle_flags};
use upm_core::motion::PlateMotion;
use upm_core::sim::{simulate, simulate_stacked, Config, Parts, PartsView};
use upm_core::{Harmonics, Waveform};

/// As the Python extension allocates: large results on cache lines.
#[global_allocator]
static ALLOCATOR: upm_core::aligned::LineAligned = upm_core::aligned::LineAligned;

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

/// A pool of one rayon thread.
fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
}

/// `n` positions spread over a 0.2 m square (a low-discrepancy sequence).
fn spread(n: usize) -> Vec<[f64; 2]> {
    (0..n)
        .map(|i| {
            let a = i as f64 * 0.618_033_988_75;
            [
                0.1 * (a.fract() * 2.0 - 1.0),
                0.1 * ((a * 7.0).fract() * 2.0 - 1.0),
            ]
        })
        .collect()
}

/// A run of `steps` steps of `dt` recording only the last (every `EVERY`-th, if set).
fn last_step_only(steps: usize, dt: f64) -> Config {
    Config {
        dt,
        duration: steps as f64 * dt,
        g: 9.81,
        plate_size: None,
        record_every: std::env::var("EVERY").map_or(steps, |k| k.parse().expect("EVERY=k")),
        tilt: [0.0; 2],
    }
}

/// ns per part-step of `parts` (`n` of them) on a translating and on a rotating plate, one
/// thread, best of 5, printed a line each.
fn on_both_plates(parts: &Parts, n: usize, trans: &PlateMotion, rot: &PlateMotion, cfg: &Config) {
    let one = one_thread();
    let steps = (cfg.duration / cfg.dt).round() as usize;
    for (name, motion) in [("translating plate", trans), ("rotating plate", rot)] {
        if std::env::var("ONLY").is_ok_and(|o| !name.starts_with(&o)) {
            continue;
        }
        let t = one.install(|| best_of(5, || simulate(motion, parts, cfg).unwrap()));
        println!("  {name:<22}{:8.1}", t * 1e9 / (n * steps) as f64);
    }
}

/// ns per part-step of the integrator on one rayon thread, `n` parts at rest on `motion`.
fn integrator(motion: &PlateMotion, n: usize, steps: usize, dt: f64) -> f64 {
    let (one, position) = (one_thread(), spread(n));
    let parts = Parts::points(position, vec![[0.0; 2]; n], vec![0.3; n], vec![0.4; n]);
    let cfg = last_step_only(steps, dt);
    let t = one.install(|| best_of(3, || simulate(motion, &parts, &cfg).unwrap()));
    t * 1e9 / (n * steps) as f64
}

/// One friction coefficient for every part, as `upm.simulate` passes a scalar `mu`.
const MU: [f64; 1] = [0.3];
const MU_S: [f64; 1] = [0.4];

/// Point parts at `position`, at rest, as the binding passes them (no velocities, one `mu`).
fn at_rest(position: &[[f64; 2]]) -> PartsView<'_> {
    PartsView {
        position,
        velocity: None,
        mu: &MU,
        mu_s: &MU_S,
        radius: None,
        angle: None,
        spin: None,
        polygons: &[],
        surface: None,
    }
}

/// `parts` on `motion` as the binding runs one world (stacked).
fn stacked(motion: &PlateMotion, parts: &PartsView, cfg: &Config) -> upm_core::sim::Stacked {
    let run = simulate_stacked::<upm_core::Error, _>(
        std::slice::from_ref(motion),
        parts,
        cfg,
        None,
        None,
        |_| Ok(()),
    );
    run.unwrap()
}

/// A 2-step call on `n` parts at rest as `upm.simulate` makes it (one friction coefficient for
/// all, no velocities, the result's buffers recycled when it goes), ns per part, one thread.
fn per_call(motion: &PlateMotion, n: usize, dt: f64) -> f64 {
    let (one, position) = (one_thread(), spread(n));
    let parts = at_rest(&position);
    let steps = std::env::var("STEPS").map_or(2, |s| s.parse().unwrap());
    let cfg = last_step_only(steps, dt);
    let call = || {
        let run = stacked(motion, &parts, &cfg);
        let first = run.positions[0][0];
        recycle(run.positions.into_flattened());
        recycle(run.velocities.into_flattened());
        recycle(run.left);
        recycle_flags(run.stuck);
        recycle_flags(run.left_plate);
        first
    };
    let t = one.install(|| best_of(5, call));
    t * 1e9 / n as f64
}

/// The fixed cost of a small call, as a control loop or a planner makes many: 8 parts at rest,
/// 100 steps, recording the last, as the binding calls the core; on rayon's global pool (every
/// core) and on one thread as the binding's `threads=1` runs (the calling thread alone,
/// [`upm_core::parallel::serial`]), microseconds per call (the steps take about 2 us).
fn small_calls(motion: &PlateMotion, dt: f64) {
    let position = spread(8);
    let parts = at_rest(&position);
    let cfg = last_step_only(100, dt);
    let calls = 2000;
    let many = |n: usize| {
        (0..n).for_each(|_| {
            black_box(stacked(motion, &parts, &cfg));
        })
    };
    let global = best_of(5, || many(calls)) * 1e6 / calls as f64;
    let single = upm_core::parallel::serial(|| best_of(5, || many(calls))) * 1e6 / calls as f64;
    println!(
        "a call of 8 parts x 100 steps: {global:.1} us on every core, {single:.1} us on one thread"
    );
}

fn main() {
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
        trans.clone().for_duration(2.0 / f).unwrap(),
        rot.clone().for_duration(2.0 / f).unwrap(),
    ])
    .unwrap();
    let dt = 1.0 / f / 400.0;
    let sizes = [
        (1_000, 20_000),
        (10_000, 2_000),
        (100_000, 400),
        (1_000_000, 100),
    ];
    if std::env::args().any(|a| a == "--per-call") {
        // For profiling the fixed cost: 2-step calls on 1e6 parts, as the binding makes them.
        for _ in 0..10 {
            println!("{:.1} ns per part", per_call(&motion, 1_000_000, dt));
        }
        return;
    }
    if std::env::args().any(|a| a == "--small") {
        small_calls(&motion, dt);
        return;
    }
    if std::env::args().any(|a| a == "--table") {
        let jet = PlateMotion::jet([0.01, 0.02], [0.6, 0.8], 0.06, 0.3, 50.0)
            .unwrap()
            .with_envelope(0.12, 0.11, 0.12)
            .unwrap();
        let mut out = Vec::with_capacity(840);
        let t = best_of(20, || {
            for _ in 0..1000 {
                out.clear();
                jet.velocities_into(0..840, 1.0 / 2400.0, &mut out);
            }
            out[7]
        });
        println!("table of a jet: {:.2} ns per step", t * 1e9 / 840e3);
        return;
    }
    if std::env::args().any(|a| a.starts_with("--batch")) {
        batch();
        return;
    }
    if std::env::args().any(|a| a == "--disks") {
        disks(&trans, &rot, dt);
        return;
    }
    if std::env::args().any(|a| a == "--polygons") {
        polygons(&trans, &rot, dt);
        return;
    }
    if std::env::args().any(|a| a == "--one-build") {
        // A child run: this process's build (UPM_SIMD) at every size.
        let row: Vec<String> = sizes
            .iter()
            .map(|&(n, steps)| format!("{:8.2}", integrator(&motion, n, steps, dt)))
            .collect();
        println!("{}", row.join(""));
        return;
    }
    // |w|^2 of sliding parts: 1e-8 .. 1e-4 (m/s)^2, mantissas spread.
    let q: Vec<f64> = (0..256)
        .map(|i| 1e-8 * 10f64.powf(4.0 * ((i * 7919) % 256) as f64 / 256.0))
        .collect();
    let bound = divider_bound(&q) * 1e9;
    println!(
        "point-part step, ns per part-step on 1 thread (chosen build: {}):",
        upm_core::sim::simd().name()
    );
    let head: Vec<String> = sizes.iter().map(|&(n, _)| format!("{n:>8}")).collect();
    println!("  {:<22}{}", "build \\ parts", head.join(""));
    let exe = std::env::current_exe().unwrap();
    for build in upm_core::sim::Simd::available() {
        let out = std::process::Command::new(&exe)
            .arg("--one-build")
            .env("UPM_SIMD", build.name())
            .output()
            .unwrap();
        let row = String::from_utf8_lossy(&out.stdout);
        println!("  {:<22}{}", build.name(), row.trim_end());
    }
    println!("  sqrt + division alone {bound:6.2} ns/element (the exact step's bound)");
    // The fixed cost of a call: a 2-step call on 1e6 parts, per part (compute is ~2 part-steps).
    let n = 1_000_000;
    let fixed = per_call(&motion, n, dt);
    println!("  a 2-step call on {n} parts: {fixed:.1} ns per part (chosen build)");
    disks(&trans, &rot, dt);
    polygons(&trans, &rot, dt);
    batch();
}

/// Batches of small worlds (the predictive planner's rollouts: 500 enveloped jets at scattered
/// centres, 8 parts each, 840 steps) against one world of as many parts on the first jet, ns per
/// part-step on one thread and on every core; and the batch's fixed cost (a 2-step call) per
/// world.
fn batch() {
    let (b, m, steps) = (500, 8, 840);
    let dt = 1.0 / 2400.0;
    let motions: Vec<PlateMotion> = spread(b)
        .into_iter()
        .map(|c| {
            PlateMotion::jet(c, [0.6, 0.8], 0.06, 0.3, 50.0)
                .unwrap()
                .with_envelope(0.12, 0.11, 0.12)
                .unwrap()
        })
        .collect();
    let cfg = |steps: usize| Config {
        dt,
        duration: steps as f64 * dt,
        g: 9.81,
        plate_size: None,
        record_every: steps,
        tilt: [0.0; 2],
    };
    let small = Parts::points(spread(m), vec![[0.0; 2]; m], vec![0.3; m], vec![0.4; m]);
    // (stacked, as the Python binding runs a batch)
    let stacked = |steps: usize| {
        simulate_stacked(&motions, &small.view(), &cfg(steps), None, None, |_| {
            Ok::<(), upm_core::Error>(())
        })
        .unwrap()
    };
    let large = Parts::points(
        spread(b * m),
        vec![[0.0; 2]; b * m],
        vec![0.3; b * m],
        vec![0.4; b * m],
    );
    let per = |t: f64| t * 1e9 / (b * m * steps) as f64;
    // For comparing profiles of the two sides: one of them alone, 200 runs on this thread.
    for (flag, batch) in [("--batch-only", true), ("--world-only", false)] {
        if std::env::args().any(|a| a == flag) {
            for _ in 0..200 {
                if batch {
                    black_box(stacked(steps));
                } else {
                    black_box(simulate(&motions[0], &large, &cfg(steps)).unwrap());
                }
            }
            return;
        }
    }
    println!("batches, {b} enveloped jets x {m} parts x {steps} steps, ns per part-step:");
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    for threads in [1, cores] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        // (best of 15: a shared machine's other work comes and goes within a few runs)
        let time = |steps: usize| pool.install(|| best_of(15, || stacked(steps)));
        let (run, fixed) = (time(steps), time(2));
        let world =
            pool.install(|| best_of(15, || simulate(&motions[0], &large, &cfg(steps)).unwrap()));
        println!(
            "  {threads} thread(s): batch {:.2}, one world of {} parts {:.2}: {:.2}x; a 2-step \
             batch call {:.2} us per world",
            per(run),
            b * m,
            per(world),
            run / world,
            fixed * 1e6 / b as f64
        );
        if threads == 1 && std::env::args().any(|a| a == "--batch-profile") {
            for _ in 0..100 {
                black_box(pool.install(|| stacked(steps)));
            }
        }
        if threads == cores && std::env::args().any(|a| a == "--batch-fixed-profile") {
            for _ in 0..3000 {
                black_box(pool.install(|| stacked(2)));
            }
        }
    }
}

/// ns per disk-step on one thread: 2000 disks of radius 5 mm at rest on a translating and on a
/// rotating plate.
fn disks(trans: &PlateMotion, rot: &PlateMotion, dt: f64) {
    let (n, steps) = (2000, 2000);
    let mut parts = Parts::points(spread(n), vec![[0.0; 2]; n], vec![0.3; n], vec![0.3; n]);
    parts.radius = vec![0.005; n];
    let cfg = last_step_only(steps, dt);
    println!("disk parts, {n} disks x {steps} steps, ns per disk-step on 1 thread:");
    on_both_plates(&parts, n, trans, rot, &cfg);
}

/// Hexagons (issue 27's shape for its 150 ns target) of 8 mm circumradius, then 16 x 8 mm
/// rectangles (four edges: half the fan's lanes), spinning at the start (up to 5 rad/s either
/// way), ns per part-step on one thread, recording only the last step.
fn polygons(trans: &PlateMotion, rot: &PlateMotion, dt: f64) {
    let (n, steps) = (200, 2000);
    let hexagon: Vec<[f64; 2]> = (0..6)
        .map(|k| {
            let a = std::f64::consts::PI * k as f64 / 3.0;
            [0.008 * a.cos(), 0.008 * a.sin()]
        })
        .collect();
    let rectangle = [
        [-0.008, -0.004],
        [0.008, -0.004],
        [0.008, 0.004],
        [-0.008, 0.004],
    ];
    for (name, outline) in [("hexagons", &hexagon[..]), ("rectangles", &rectangle[..])] {
        let mut parts = Parts::points(spread(n), vec![[0.0; 2]; n], vec![0.3; n], vec![0.4; n]);
        let shape = upm_core::polygon::Polygon::new(name, outline).unwrap();
        parts.polygons = (0..n).map(|i| (i, shape.clone())).collect();
        parts.spin = (0..n)
            .map(|i| 5.0 * (2.0 * (i * 7919 % n) as f64 / n as f64 - 1.0))
            .collect();
        parts.angle = (0..n).map(|i| (i * 104_729 % 628) as f64 / 100.0).collect();
        let cfg = last_step_only(steps, dt);
        println!(
            "{name}, {n} x {steps} steps, ns per part-step on 1 thread (fan build: {}):",
            upm_core::sim::simd().name()
        );
        on_both_plates(&parts, n, trans, rot, &cfg);
    }
}
