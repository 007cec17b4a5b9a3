//! The point-part step: the exact implicit Coulomb step (see [`super`]) of every part of a chunk,
//! through a segment of steps.
//!
//! Three builds of the same update, one chosen at run time by CPU feature detection (never by
//! `target-cpu`), and reported by [`simd`]:
//!
//! * [`Simd::Avx512`] ([`avx512`]): eight parts per instruction, stick flags in mask registers;
//! * [`Simd::Avx2`] ([`avx2`]): four parts per instruction, with fused multiply–adds;
//! * [`Simd::Portable`]: plain Rust with a correctly rounded square root and division; it runs on
//!   any CPU and is the reference the others are tested against.
//!
//! The vector builds need neither square root nor division. The stick test compares squared norms
//! (`|w|^2 <= (mu g dt)^2`), and a sliding part needs only `1/|w|`: the hardware's reciprocal
//! square root estimate refined in double precision by a short series to about one ulp. They keep
//! a tile of parts in registers through every step of a segment (the plate's velocity table is
//! shared by every tile), so a part-step touches no memory but the table.
//!
//! The builds agree to a few ulp (tested over millions of random states): the stick decision can
//! differ only where `|w|` is within rounding of the threshold. One machine always takes the same
//! build, so results are bitwise identical for any thread count. `UPM_SIMD=portable|avx2|avx512`
//! in the environment picks a build (one the CPU lacks falls back to the best it has).

#[cfg(target_arch = "x86_64")]
pub(super) mod avx2;
#[cfg(target_arch = "x86_64")]
pub(super) mod avx512;

use crate::motion::Sample;
pub use crate::simd::{simd, Simd};

/// Step count of a part that never left the plate.
pub(super) const NEVER: f64 = f64::INFINITY;

/// One chunk's state, structure of arrays; flags are f64 (0 or 1).
pub(super) struct Lanes<'a> {
    pub x: &'a mut [f64],
    pub y: &'a mut [f64],
    pub vx: &'a mut [f64],
    pub vy: &'a mut [f64],
    pub stuck: &'a mut [f64],
    /// 0 for parts that left the plate: they keep their state (honoured with a finite plate only:
    /// without an edge no part leaves).
    pub active: &'a mut [f64],
    /// The number of steps done when the part left the plate ([`NEVER`] while it is on it; an
    /// integer, exact in f64 up to 2^53).
    pub left: &'a mut [f64],
    /// `mu g dt` per part.
    pub slide: &'a [f64],
    /// `mu_s g dt` per part.
    pub hold: &'a [f64],
    /// The velocity gravity's in-plane part adds in a step, `tilt dt` [m/s] ([`Config::tilt`]).
    ///
    /// [`Config::tilt`]: crate::sim::Config::tilt
    pub kick: [f64; 2],
}

impl Lanes<'_> {
    /// Panics unless every array has the same length (the vector builds rely on it).
    fn check(&self) {
        let n = self.x.len();
        assert!(
            [self.y.len(), self.vx.len(), self.vy.len(), self.stuck.len()]
                .iter()
                .chain(&[self.active.len(), self.left.len()])
                .chain(&[self.slide.len(), self.hold.len()])
                .all(|&l| l == n),
            "chunk arrays of unequal length"
        );
    }
}

/// The plate's velocity at the end of each step of a segment, for the parts of a chunk: one
/// table for every part, or (small worlds of a batch run side by side, `sim::group`) one column
/// per world, the worlds interleaved: sets of eight worlds, each set a run of `parts` vectors of
/// eight lanes, vector `i` of a set holding part `i` of its eight worlds, one world a lane. Lane
/// `l` then holds world `8 (l / 8 / parts) + l % 8`, and a vector's lanes read eight neighbouring
/// columns of one row: one load serves eight worlds.
#[derive(Clone, Copy)]
pub(super) struct Plate<'t> {
    /// Step after step, each component's row of `width` columns: component `c` of column `w`
    /// at step `k` is `values[(3 k + c) width + w]` (one table: `[u1, u2, u3]` a step).
    values: &'t [f64],
    width: usize,
    /// Parts per world (`usize::MAX` for one table).
    parts: usize,
    /// Eight worlds' jets evaluated by the kernel at each step's sample instead of read from
    /// `values` ([`Plate::jets`]).
    jets: Option<Jets<'t>>,
}

/// Sets of eight worlds' jets through a stint of steps: each step's sample, and each set's jets'
/// coefficients `[k, ax, ay, cx, cy]` lane by lane (see `motion::table::across::jets`).
#[derive(Clone, Copy)]
pub(super) struct Jets<'t> {
    pub samples: &'t [Sample],
    pub coef: &'t [[[f64; 8]; 5]],
}

impl<'t> Plate<'t> {
    /// One table for every part.
    pub(super) fn shared(table: &'t [[f64; 3]]) -> Self {
        Plate {
            values: table.as_flattened(),
            width: 1,
            parts: usize::MAX,
            jets: None,
        }
    }

    /// Worlds of `parts` parts interleaved (see [`Plate`]), `width` columns (a whole number of
    /// sets of eight) side by side in `values` (whole steps; checked).
    pub(super) fn interleaved(values: &'t [f64], width: usize, parts: usize) -> Self {
        assert!(
            width > 0
                && width.is_multiple_of(8)
                && parts > 0
                && values.len().is_multiple_of(3 * width),
            "columns of interleaved worlds"
        );
        Plate {
            values,
            width,
            parts,
            jets: None,
        }
    }

    /// Sets of eight worlds of `parts` parts interleaved (see [`Plate`]), one a set of the jets'
    /// coefficients, under jets the kernel evaluates at each step (the velocity
    /// `[ax g + w cy, ay g - w cx, w]`, `g` the sample's feeding profile and `w = k` times its
    /// spin: the operations of the worlds' table, so the same bits). Only the AVX-512 build
    /// takes it ([`Plate::jets_built`]).
    pub(super) fn jets(jets: Jets<'t>, parts: usize) -> Self {
        assert!(
            parts > 0 && !jets.coef.is_empty(),
            "worlds of no part, or no set"
        );
        Plate {
            values: &[],
            width: 8 * jets.coef.len(),
            parts,
            jets: Some(jets),
        }
    }

    /// Whether the build `simd` evaluates [`Plate::jets`] (the others read a table).
    pub(super) fn jets_built(simd: Simd) -> bool {
        simd == Simd::Avx512
    }

    /// The number of steps.
    pub(super) fn steps(&self) -> usize {
        match self.jets {
            Some(j) => j.samples.len(),
            None => self.values.len() / (3 * self.width),
        }
    }

    /// The jets, if the kernel evaluates them.
    #[inline]
    pub(super) fn jets_of(&self) -> Option<Jets<'t>> {
        self.jets
    }

    /// Columns side by side.
    #[inline]
    pub(super) fn width(&self) -> usize {
        self.width
    }

    /// The column of the part in `lane` (the last column for lanes past every set: they hold
    /// no part).
    #[inline]
    pub(super) fn column(&self, lane: usize) -> usize {
        if self.width == 1 {
            0
        } else {
            (lane / 8 / self.parts * 8 + lane % 8).min(self.width - 1)
        }
    }

    /// Component 0 of column `col` at step `k`, from a table of `width` columns (the caller's
    /// constant 1 for one table: its loads then are the table's own); component `c` lies
    /// `c * width` values further.
    ///
    /// # Safety
    /// `k < self.steps()`, `col < width` and `width == self.width`; whoever reads `n` columns
    /// from it needs `col + n <= width`.
    #[inline(always)]
    pub(super) unsafe fn cell(&self, width: usize, col: usize, k: usize) -> *const f64 {
        debug_assert!(k < self.steps() && col < width && width == self.width);
        // SAFETY: (3 k + c) width + col < 3 width steps = the length (the caller's promise).
        unsafe { self.values.as_ptr().add(3 * width * k + col) }
    }

    /// The velocity of column `col` at step `k` (see [`Plate::cell`]).
    ///
    /// # Safety
    /// As [`Plate::cell`].
    #[inline(always)]
    pub(super) unsafe fn at(&self, width: usize, col: usize, k: usize) -> [f64; 3] {
        // SAFETY: the caller's promise.
        unsafe {
            let p = self.cell(width, col, k);
            [*p, *p.add(width), *p.add(2 * width)]
        }
    }
}

/// Advances every part of `s` through the steps of `plate` (the plate velocity at the end of
/// each step), of length `dt`; `first` steps are already done. With a finite `half` (half the
/// plate's side) a part whose centre leaves the plate is frozen (`active = 0`) and its step count
/// stored in `left`.
pub(super) fn run(plate: Plate, first: usize, dt: f64, half: f64, s: &mut Lanes) {
    // SAFETY: simd() only reports builds the CPU has.
    unsafe { dispatch(simd(), plate, first, dt, half, s) }
}

/// [`run`] with the build `simd` (which the CPU must have; checked).
#[cfg(test)]
pub(super) fn run_with(simd: Simd, plate: Plate, first: usize, dt: f64, half: f64, s: &mut Lanes) {
    assert!(
        Simd::available().contains(&simd),
        "build {simd:?} is not available on this CPU"
    );
    // SAFETY: checked just above.
    unsafe { dispatch(simd, plate, first, dt, half, s) }
}

/// [`run`] with the build `simd` (asked for every segment of every chunk: no check here).
///
/// # Safety
/// The CPU must have the build's features.
unsafe fn dispatch(simd: Simd, table: Plate, first: usize, dt: f64, half: f64, s: &mut Lanes) {
    assert!(
        table.jets.is_none() || Plate::jets_built(simd),
        "the {} build reads a table, not jets",
        simd.name()
    );
    let edge = half.is_finite();
    match simd {
        Simd::Portable => run_portable(table, first, dt, half, s),
        // SAFETY: the CPU has the build's features (the caller's promise).
        #[cfg(target_arch = "x86_64")]
        Simd::Avx512 => unsafe {
            match (edge, table.width() == 1) {
                (true, true) => avx512::run::<true, false>(table, first, dt, half, s),
                (true, false) => avx512::run::<true, true>(table, first, dt, half, s),
                (false, true) => avx512::run::<false, false>(table, first, dt, half, s),
                (false, false) => avx512::run::<false, true>(table, first, dt, half, s),
            }
        },
        #[cfg(target_arch = "x86_64")]
        Simd::Avx2 => unsafe {
            match (edge, table.width() == 1) {
                (true, true) => avx2::run::<true, false>(table, first, dt, half, s),
                (true, false) => avx2::run::<true, true>(table, first, dt, half, s),
                (false, true) => avx2::run::<false, false>(table, first, dt, half, s),
                (false, false) => avx2::run::<false, true>(table, first, dt, half, s),
            }
        },
        #[cfg(not(target_arch = "x86_64"))]
        _ => unreachable!("only the portable build exists off x86-64"),
    }
}

/// The portable build: correctly rounded root and division, one step of the whole chunk at a time.
fn run_portable(plate: Plate, first: usize, dt: f64, half: f64, s: &mut Lanes) {
    s.check();
    let n = s.x.len();
    let width = plate.width;
    let cols: Vec<usize> = (0..n).map(|i| plate.column(i)).collect();
    for k in 0..plate.steps() {
        for (i, &col) in cols.iter().enumerate() {
            // SAFETY: k < steps, and every column is below the width.
            let u = unsafe { plate.at(width, col, k) };
            portable_step(s, i, u, first + k, dt, half);
        }
    }
}

/// Part `i`'s step `step` (0-based) under the plate velocity `u`, as [`run_portable`] takes it.
#[inline(always)]
fn portable_step(s: &mut Lanes, i: usize, [u1, u2, u3]: [f64; 3], step: usize, dt: f64, half: f64) {
    let (x, y, vx, vy) = (s.x[i], s.y[i], s.vx[i], s.vy[i]);
    let (sx, sy) = (u1 - u3 * y, u2 + u3 * x);
    let (wx, wy) = ((vx + s.kick[0]) - sx, (vy + s.kick[1]) - sy);
    let wn = (wx * wx + wy * wy).sqrt();
    let (slide, hold) = (s.slide[i], s.hold[i]);
    let stick = (wn <= slide) | ((s.stuck[i] > 0.0) & (wn <= hold));
    let keep = if stick { 0.0 } else { 1.0 - slide / wn };
    let (nvx, nvy) = (sx + wx * keep, sy + wy * keep);
    // Parts that left the plate (active = 0) keep their state.
    let a = s.active[i];
    let (nvx, nvy) = (a * nvx + (1.0 - a) * vx, a * nvy + (1.0 - a) * vy);
    // Trapezoidal position update: second order where the velocity is smooth.
    s.x[i] = x + 0.5 * (vx + nvx) * dt * a;
    s.y[i] = y + 0.5 * (vy + nvy) * dt * a;
    s.vx[i] = nvx;
    s.vy[i] = nvy;
    s.stuck[i] = a * f64::from(u8::from(stick)) + (1.0 - a) * s.stuck[i];
    if a > 0.0 && (s.x[i].abs() > half || s.y[i].abs() > half) {
        s.active[i] = 0.0;
        s.left[i] = (step + 1) as f64;
    }
}

/// Deterministic pseudo-random numbers in [-1, 1) (the kernels' tests).
#[cfg(test)]
pub(in crate::sim) fn noise(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chunk's arrays: x, y, vx, vy, stuck, active, slide, hold, and the step counts of leaving.
    #[derive(Clone)]
    struct Owned {
        v: [Vec<f64>; 8],
        left: Vec<f64>,
    }

    impl Owned {
        /// `n` parts with velocities from far above the stick threshold down to within it
        /// (`spread` decades), a third of them stuck, and every seventh off the plate with `edge`.
        fn new(n: usize, seed: u64, slide: f64, edge: bool, spread: f64) -> Self {
            let r = noise(seed, 5 * n);
            let x: Vec<f64> = r[..n].iter().map(|a| 0.1 * a).collect();
            let y: Vec<f64> = r[n..2 * n].iter().map(|a| 0.1 * a).collect();
            let scale = |k: usize| slide * 10f64.powf(spread * (r[4 * n + k] + 1.0) / 2.0 - 0.5);
            let vx: Vec<f64> = (0..n).map(|k| r[2 * n + k] * scale(k)).collect();
            let vy: Vec<f64> = (0..n).map(|k| r[3 * n + k] * scale(k)).collect();
            let stuck = (0..n).map(|k| f64::from(u8::from(k % 3 == 0))).collect();
            let active = (0..n)
                .map(|k| f64::from(u8::from(!edge || k % 7 != 5)))
                .collect();
            let sl = (0..n)
                .map(|k| slide * (1.0 + 0.1 * (k % 5) as f64))
                .collect();
            let ho = (0..n)
                .map(|k| slide * (1.3 + 0.1 * (k % 5) as f64))
                .collect();
            Owned {
                v: [x, y, vx, vy, stuck, active, sl, ho],
                left: vec![NEVER; n],
            }
        }

        fn run(&mut self, simd: Simd, table: &[[f64; 3]], half: f64) {
            let [x, y, vx, vy, stuck, active, slide, hold] = &mut self.v;
            let mut lanes = Lanes {
                x,
                y,
                vx,
                vy,
                stuck,
                active,
                left: &mut self.left,
                slide,
                hold,
                // a plate not level (0.3 and -0.5 m/s^2 in its plane): every build adds it alike
                kick: [0.3e-4, -0.5e-4],
            };
            run_with(simd, Plate::shared(table), 0, 1e-4, half, &mut lanes);
        }
    }

    /// A translating and rotating plate's velocity at the end of each of `steps` steps.
    fn plate(steps: usize) -> Vec<[f64; 3]> {
        (0..steps)
            .map(|k| {
                let t = (k + 1) as f64 * 1e-4;
                [
                    0.05 * (220.0 * t).cos(),
                    0.03 * (440.0 * t).sin(),
                    2.0 * (220.0 * t).sin(),
                ]
            })
            .collect()
    }

    #[test]
    fn the_reciprocal_square_roots_are_within_two_ulp() {
        // Over 1e-30 .. 1e30 (and, for AVX-512, the whole range a sliding part can meet), against
        // the correctly rounded 1 / sqrt(q) in f64 and its error bound.
        let r = noise(5, 1 << 20);
        let mut worst: f64 = 0.0;
        for chunk in r.chunks_exact(8) {
            let q: Vec<f64> = chunk.iter().map(|a| 10f64.powf(30.0 * a)).collect();
            for simd in Simd::available() {
                let got: Vec<f64> = match simd {
                    Simd::Portable => continue,
                    #[cfg(target_arch = "x86_64")]
                    Simd::Avx2 => q
                        .chunks_exact(4)
                        .flat_map(|c| unsafe { avx2::rsqrt_lanes([c[0], c[1], c[2], c[3]]) })
                        .collect(),
                    #[cfg(target_arch = "x86_64")]
                    Simd::Avx512 => unsafe {
                        avx512::rsqrt_lanes(q.clone().try_into().unwrap()).to_vec()
                    },
                    #[cfg(not(target_arch = "x86_64"))]
                    _ => unreachable!(),
                };
                for (&q, g) in q.iter().zip(got) {
                    let exact = 1.0 / q.sqrt();
                    worst = worst.max((g - exact).abs() / exact);
                }
            }
        }
        // 1 / sqrt(q) itself is within an ulp of the true value: 3 ulp bound the difference.
        assert!(worst <= 3.0 * f64::EPSILON, "relative error {worst:e}");
    }

    /// Every build agrees with the portable one to a few ulp after one step, over two million
    /// random states, with and without a plate edge, for tiny and zero `mu g dt`, and for every
    /// remainder of the vector tiles. The stick decision is the same except where `|w|` lies
    /// within 1e-12 of the threshold.
    #[test]
    fn builds_agree_with_the_exact_step() {
        let table = plate(1);
        let mut states = 0;
        for simd in Simd::available() {
            for n in [1, 2, 3, 4, 5, 7, 8, 9, 16, 17, 21, 31, 32, 33, 64, 67] {
                for slide in [3e-4, 1e-20, 0.0] {
                    for half in [f64::INFINITY, 0.1] {
                        let a = Owned::new(n, n as u64, slide, half.is_finite(), 4.0);
                        let (mut p, mut b) = (a.clone(), a.clone());
                        p.run(Simd::Portable, &table, half);
                        b.run(simd, &table, half);
                        compare(&a, &p, &b, &table[0], 4.0);
                        assert_eq!(p.left, b.left, "{simd:?} n {n} slide {slide} half {half}");
                    }
                }
            }
            for seed in 0..64 {
                // Close to the threshold: |w| within a factor 1.001 of it.
                let spread = if seed % 2 == 0 { 4.0 } else { 0.0004 };
                let a = Owned::new(32_768, 100 + seed, 3e-4, false, spread);
                let (mut p, mut b) = (a.clone(), a.clone());
                p.run(Simd::Portable, &table, f64::INFINITY);
                b.run(simd, &table, f64::INFINITY);
                compare(&a, &p, &b, &table[0], 4.0);
                states += 32_768;
            }
        }
        assert!(states >= 2_000_000 || Simd::available().len() < 3);
    }

    /// `p` (portable) and `b` (another build) after one step from `a` under `u`: the same stick
    /// decisions except within 1e-12 of the threshold, and values within `ulps` ulp of the
    /// surface velocity's scale elsewhere.
    fn compare(a: &Owned, p: &Owned, b: &Owned, u: &[f64; 3], ulps: f64) {
        for i in 0..a.v[0].len() {
            let [x, y, vx, vy, stuck, _, slide, hold] = std::array::from_fn(|k| a.v[k][i]);
            let (sx, sy) = (u[0] - u[2] * y, u[1] + u[2] * x);
            let wn = (vx - sx).hypot(vy - sy);
            let thr = if stuck > 0.0 { hold } else { slide };
            let near = (wn - slide).abs() <= 1e-12 * slide || (wn - thr).abs() <= 1e-12 * thr;
            if p.v[4][i] != b.v[4][i] {
                assert!(
                    near,
                    "part {i}: stick decisions differ at |w| {wn:e}, thresholds {slide:e} {hold:e}"
                );
                continue;
            }
            for k in 0..6 {
                let (g, e) = (b.v[k][i], p.v[k][i]);
                let tol = ulps * f64::EPSILON * (e.abs() + 0.25);
                assert!((g - e).abs() <= tol, "array {k} part {i}: {g} vs {e}");
            }
        }
    }

    /// Over many steps every build takes the same decisions and stays within rounding, and the
    /// steps are split at any segment boundary without changing the result.
    #[test]
    fn builds_agree_over_many_steps_and_segments() {
        let table = plate(2000);
        let a = Owned::new(67, 9, 3e-4, true, 4.0);
        let mut p = a.clone();
        p.run(Simd::Portable, &table, 0.1);
        for simd in Simd::available() {
            let mut b = a.clone();
            b.run(simd, &table, 0.1);
            let mut c = a.clone();
            for piece in table.chunks(7) {
                c.run(simd, piece, 0.1);
            }
            assert_eq!(p.left, b.left, "{simd:?}");
            for (k, ((vp, vb), vc)) in p.v.iter().zip(&b.v).zip(&c.v).enumerate() {
                for (i, ((e, g), h)) in vp.iter().zip(vb).zip(vc).enumerate() {
                    assert!(
                        (e - g).abs() <= 1e-12,
                        "{simd:?} array {k} part {i}: {g} vs {e}"
                    );
                    assert_eq!(g.to_bits(), h.to_bits(), "{simd:?} array {k} part {i}");
                }
            }
        }
    }

    #[test]
    fn the_chosen_build_is_available() {
        assert!(Simd::available().contains(&simd()));
        assert_eq!(Simd::available()[0], Simd::Portable);
    }
}
