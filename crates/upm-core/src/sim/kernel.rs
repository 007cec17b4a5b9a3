//! The point-part step: one implicit Coulomb step (see [`super`]) for every part of a chunk.
//!
//! Two builds of the same update, both with a true square root and division (no approximations):
//!
//! * [`step_portable`]: plain Rust; it runs on any CPU and the compiler vectorises it as it can.
//! * an AVX2 + FMA build (x86-64, chosen at run time by CPU feature detection, never by
//!   `target-cpu`): four parts per instruction and fused multiply–adds, in two passes over short
//!   spans of parts. The first pass takes the stick decision and the share `1 - mu g dt / |w|` of
//!   the relative velocity the step keeps (its square root and division are the long latency);
//!   the second moves the parts. Short dependency chains let the out-of-order core overlap many
//!   parts, and parts that cannot leave the plate (no plate edge) skip the leaving masks.
//!
//! The two builds agree to rounding (tested; fused multiply–adds round once where plain Rust
//! rounds twice), not bitwise. One machine always takes the same build, so results are bitwise
//! identical for any thread count.
//!
//! On the AMD EPYC (Zen 3) this was tuned on, a four-lane `sqrt` and a division alone take about
//! 13 cycles, about 1 ns per part-step: `crates/upm-core/benches/kernel.rs` prints that bound next
//! to the kernel's time. A 12-bit reciprocal square root refined by Newton steps in f64 was tried
//! and measured slower there (the extra multiplies cost more than the divider saves).

/// One chunk's state, structure of arrays; flags are f64 (0 or 1).
pub(super) struct Lanes<'a> {
    pub x: &'a mut [f64],
    pub y: &'a mut [f64],
    pub vx: &'a mut [f64],
    pub vy: &'a mut [f64],
    pub stuck: &'a mut [f64],
    /// 0 for parts that left the plate: they keep their state (honoured with a finite plate only:
    /// without an edge no part leaves).
    pub active: &'a [f64],
    /// `mu g dt` per part.
    pub slide: &'a [f64],
    /// `mu_s g dt` per part.
    pub hold: &'a [f64],
}

/// Advances every part of `s` by one step of length `dt` under the plate velocity `u` at the
/// step's end. With a finite `half` (half the plate's side) parts that left the plate are frozen
/// (`active = 0`), and the return value says whether an active part is now off the plate.
pub(super) fn step(u: [f64; 3], dt: f64, half: f64, s: &mut Lanes) -> bool {
    #[cfg(target_arch = "x86_64")]
    if use_avx2() {
        // SAFETY: the CPU supports AVX2 and FMA (checked at run time by `use_avx2`).
        return unsafe {
            if half.is_finite() {
                avx2::step::<true>(u, dt, half, s)
            } else {
                avx2::step::<false>(u, dt, half, s)
            }
        };
    }
    step_portable(u, dt, half, s)
}

/// The portable build: correctly rounded root and division.
pub(super) fn step_portable(u: [f64; 3], dt: f64, half: f64, s: &mut Lanes) -> bool {
    let n = s.x.len();
    let (x, y, vx, vy, stuck) = (
        &mut s.x[..n],
        &mut s.y[..n],
        &mut s.vx[..n],
        &mut s.vy[..n],
        &mut s.stuck[..n],
    );
    let (active, slide, hold) = (&s.active[..n], &s.slide[..n], &s.hold[..n]);
    let [u1, u2, u3] = u;
    let mut off = false;
    for i in 0..n {
        let (sx, sy) = (u1 - u3 * y[i], u2 + u3 * x[i]);
        let (wx, wy) = (vx[i] - sx, vy[i] - sy);
        let wn = (wx * wx + wy * wy).sqrt();
        let stick = (wn <= slide[i]) | ((stuck[i] > 0.0) & (wn <= hold[i]));
        let keep = if stick { 0.0 } else { 1.0 - slide[i] / wn };
        let (nvx, nvy) = (sx + wx * keep, sy + wy * keep);
        // Parts that left the plate (active = 0) keep their state.
        let a = active[i];
        let (nvx, nvy) = (a * nvx + (1.0 - a) * vx[i], a * nvy + (1.0 - a) * vy[i]);
        // Trapezoidal position update: second order where the velocity is smooth.
        x[i] += 0.5 * (vx[i] + nvx) * dt * a;
        y[i] += 0.5 * (vy[i] + nvy) * dt * a;
        vx[i] = nvx;
        vy[i] = nvy;
        stuck[i] = a * f64::from(u8::from(stick)) + (1.0 - a) * stuck[i];
        off |= (a > 0.0) & ((x[i].abs() > half) | (y[i].abs() > half));
    }
    off
}

/// Whether the AVX2 + FMA build can run here (checked once, at run time).
#[cfg(target_arch = "x86_64")]
fn use_avx2() -> bool {
    static AVX2: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX2.get_or_init(|| is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"))
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::Lanes;

    /// Constants of one step, broadcast to four lanes.
    struct Consts {
        u1: __m256d,
        u2: __m256d,
        u3: __m256d,
        hdt: __m256d,
        half: __m256d,
        one: __m256d,
        zero: __m256d,
        abs: __m256d,
    }

    /// Raw views of one chunk's arrays (four lanes are read and written at a time).
    struct Ptrs {
        x: *mut f64,
        y: *mut f64,
        vx: *mut f64,
        vy: *mut f64,
        stuck: *mut f64,
        active: *const f64,
        slide: *const f64,
        hold: *const f64,
    }

    /// The surface velocity under four parts at `i` and their velocity relative to it.
    #[inline(always)]
    unsafe fn relative(c: &Consts, p: &Ptrs, i: usize) -> [__m256d; 8] {
        let (px, py) = (_mm256_loadu_pd(p.x.add(i)), _mm256_loadu_pd(p.y.add(i)));
        let (pvx, pvy) = (_mm256_loadu_pd(p.vx.add(i)), _mm256_loadu_pd(p.vy.add(i)));
        let sx = _mm256_fnmadd_pd(c.u3, py, c.u1);
        let sy = _mm256_fmadd_pd(c.u3, px, c.u2);
        let (wx, wy) = (_mm256_sub_pd(pvx, sx), _mm256_sub_pd(pvy, sy));
        [px, py, pvx, pvy, sx, sy, wx, wy]
    }

    /// First pass over four parts at `i`: the stick decision (stored) and the share of the
    /// relative velocity the step keeps (returned). Split from [`advance`] so that each pass is a
    /// short dependency chain and the out-of-order core overlaps many parts.
    #[inline(always)]
    unsafe fn keep<const EDGE: bool>(c: &Consts, p: &Ptrs, i: usize) -> __m256d {
        let [.., wx, wy] = relative(c, p, i);
        let st = _mm256_loadu_pd(p.stuck.add(i));
        let (slide, hold) = (
            _mm256_loadu_pd(p.slide.add(i)),
            _mm256_loadu_pd(p.hold.add(i)),
        );
        let q = _mm256_fmadd_pd(wx, wx, _mm256_mul_pd(wy, wy));
        let was = _mm256_cmp_pd::<_CMP_GT_OQ>(st, c.zero);
        let wn = _mm256_sqrt_pd(q);
        let by_slide = _mm256_cmp_pd::<_CMP_LE_OQ>(wn, slide);
        let by_hold = _mm256_cmp_pd::<_CMP_LE_OQ>(wn, hold);
        let stick = _mm256_or_pd(by_slide, _mm256_and_pd(was, by_hold));
        let ratio = _mm256_div_pd(slide, wn);
        let mut nst = _mm256_and_pd(stick, c.one);
        if EDGE {
            let a = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_loadu_pd(p.active.add(i)), c.zero);
            nst = _mm256_blendv_pd(st, nst, a);
        }
        _mm256_storeu_pd(p.stuck.add(i), nst);
        // Stuck lanes keep nothing of w (at `w = 0` the ratio is infinite: the mask clears it).
        _mm256_andnot_pd(stick, _mm256_sub_pd(c.one, ratio))
    }

    /// Second pass over four parts at `i`: new velocity and position; returns the lanes of active
    /// parts now off the plate.
    #[inline(always)]
    unsafe fn advance<const EDGE: bool>(c: &Consts, p: &Ptrs, i: usize, keep: __m256d) -> __m256d {
        let [px, py, pvx, pvy, sx, sy, wx, wy] = relative(c, p, i);
        let mut nvx = _mm256_fmadd_pd(wx, keep, sx);
        let mut nvy = _mm256_fmadd_pd(wy, keep, sy);
        let mut nx = _mm256_fmadd_pd(_mm256_add_pd(pvx, nvx), c.hdt, px);
        let mut ny = _mm256_fmadd_pd(_mm256_add_pd(pvy, nvy), c.hdt, py);
        let mut off = c.zero;
        if EDGE {
            let a = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_loadu_pd(p.active.add(i)), c.zero);
            nvx = _mm256_blendv_pd(pvx, nvx, a);
            nvy = _mm256_blendv_pd(pvy, nvy, a);
            nx = _mm256_blendv_pd(px, nx, a);
            ny = _mm256_blendv_pd(py, ny, a);
            let ox = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_and_pd(nx, c.abs), c.half);
            let oy = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_and_pd(ny, c.abs), c.half);
            off = _mm256_and_pd(_mm256_or_pd(ox, oy), a);
        }
        _mm256_storeu_pd(p.x.add(i), nx);
        _mm256_storeu_pd(p.y.add(i), ny);
        _mm256_storeu_pd(p.vx.add(i), nvx);
        _mm256_storeu_pd(p.vy.add(i), nvy);
        off
    }

    /// Both passes over the `4 * groups` parts from `start`.
    #[inline(always)]
    unsafe fn span<const EDGE: bool>(c: &Consts, p: &Ptrs, start: usize, groups: usize) -> __m256d {
        let mut keeps = [_mm256_setzero_pd(); SPAN];
        for (g, k) in keeps.iter_mut().enumerate().take(groups) {
            *k = keep::<EDGE>(c, p, start + 4 * g);
        }
        let mut off = c.zero;
        for (g, &k) in keeps.iter().enumerate().take(groups) {
            off = _mm256_or_pd(off, advance::<EDGE>(c, p, start + 4 * g, k));
        }
        off
    }

    /// Four-lane groups per span of the two passes (their `keep`s stay in registers or on the
    /// stack; 4 measured best of 1, 2, 4, 8 and 16).
    const SPAN: usize = 4;

    /// The AVX2 build of [`super::step`].
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn step<const EDGE: bool>(
        u: [f64; 3],
        dt: f64,
        half: f64,
        s: &mut Lanes,
    ) -> bool {
        let n = s.x.len();
        assert!(
            [s.y.len(), s.vx.len(), s.vy.len(), s.stuck.len()]
                .iter()
                .chain(&[s.active.len(), s.slide.len(), s.hold.len()])
                .all(|&l| l == n),
            "chunk arrays of unequal length"
        );
        let c = Consts {
            u1: _mm256_set1_pd(u[0]),
            u2: _mm256_set1_pd(u[1]),
            u3: _mm256_set1_pd(u[2]),
            hdt: _mm256_set1_pd(0.5 * dt),
            half: _mm256_set1_pd(half),
            one: _mm256_set1_pd(1.0),
            zero: _mm256_setzero_pd(),
            abs: _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX)),
        };
        let p = Ptrs {
            x: s.x.as_mut_ptr(),
            y: s.y.as_mut_ptr(),
            vx: s.vx.as_mut_ptr(),
            vy: s.vy.as_mut_ptr(),
            stuck: s.stuck.as_mut_ptr(),
            active: s.active.as_ptr(),
            slide: s.slide.as_ptr(),
            hold: s.hold.as_ptr(),
        };
        let body = n - n % 4;
        let mut off = _mm256_setzero_pd();
        let mut i = 0;
        while i < body {
            let groups = ((body - i) / 4).min(SPAN);
            off = _mm256_or_pd(off, span::<EDGE>(&c, &p, i, groups));
            i += 4 * groups;
        }
        if body < n {
            // The last one to three parts go through the same four-lane code, padded with parts
            // that left the plate (their lanes are neither kept nor reported).
            let mut t = [[0.0f64; 4]; 8];
            for k in 0..n - body {
                let j = body + k;
                for (row, v) in t.iter_mut().zip([
                    s.x[j],
                    s.y[j],
                    s.vx[j],
                    s.vy[j],
                    s.stuck[j],
                    s.active[j],
                    s.slide[j],
                    s.hold[j],
                ]) {
                    row[k] = v;
                }
            }
            let [mut tx, mut ty, mut tvx, mut tvy, mut tst, ta, tsl, tho] = t;
            let tp = Ptrs {
                x: tx.as_mut_ptr(),
                y: ty.as_mut_ptr(),
                vx: tvx.as_mut_ptr(),
                vy: tvy.as_mut_ptr(),
                stuck: tst.as_mut_ptr(),
                active: ta.as_ptr(),
                slide: tsl.as_ptr(),
                hold: tho.as_ptr(),
            };
            off = _mm256_or_pd(off, span::<EDGE>(&c, &tp, 0, 1));
            for k in 0..n - body {
                let j = body + k;
                (s.x[j], s.y[j], s.vx[j], s.vy[j], s.stuck[j]) =
                    (tx[k], ty[k], tvx[k], tvy[k], tst[k]);
            }
        }
        _mm256_movemask_pd(off) != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [-1, 1).
    fn noise(seed: u64, n: usize) -> Vec<f64> {
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

    struct Owned {
        v: [Vec<f64>; 8],
    }

    impl Owned {
        fn new(n: usize, seed: u64, slide: f64, edge: bool) -> Self {
            let r = noise(seed, 5 * n);
            let x: Vec<f64> = r[..n].iter().map(|a| 0.1 * a).collect();
            let y: Vec<f64> = r[n..2 * n].iter().map(|a| 0.1 * a).collect();
            // Velocities from far above the stick threshold down to within it.
            let scale = |k: usize| slide * 10f64.powf(4.0 * (r[4 * n + k] + 1.0) / 2.0 - 0.5);
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
            }
        }

        fn run(&mut self, portable: bool, steps: usize, half: f64) -> Vec<bool> {
            let [x, y, vx, vy, stuck, active, slide, hold] = &mut self.v;
            let mut lanes = Lanes {
                x,
                y,
                vx,
                vy,
                stuck,
                active,
                slide,
                hold,
            };
            (0..steps)
                .map(|k| {
                    let t = k as f64 * 1e-4;
                    let u = [
                        0.05 * (220.0 * t).cos(),
                        0.03 * (440.0 * t).sin(),
                        2.0 * (220.0 * t).sin(),
                    ];
                    if portable {
                        step_portable(u, 1e-4, half, &mut lanes)
                    } else {
                        step(u, 1e-4, half, &mut lanes)
                    }
                })
                .collect()
        }
    }

    /// The dispatched build (AVX2 where the CPU has it) agrees with the portable one to rounding,
    /// for every remainder of the four-lane loop and span, with and without a plate edge, and for
    /// tiny and zero `mu g dt`.
    #[test]
    fn builds_agree_to_rounding() {
        for n in [1, 2, 3, 4, 5, 7, 16, 17, 21, 64, 67] {
            for slide in [3e-4, 1e-20, 0.0] {
                for half in [f64::INFINITY, 0.1] {
                    let mut a = Owned::new(n, n as u64, slide, half.is_finite());
                    let mut b = Owned::new(n, n as u64, slide, half.is_finite());
                    let off_a = a.run(true, 1, half);
                    let off_b = b.run(false, 1, half);
                    assert_eq!(off_a, off_b, "n {n} slide {slide} half {half}");
                    for (k, (va, vb)) in a.v.iter().zip(&b.v).enumerate() {
                        for (i, (p, q)) in va.iter().zip(vb).enumerate() {
                            // Rounding of the surface velocity (up to 0.25 m/s here) bounds the difference.
                            let tol = 4.0 * f64::EPSILON * (p.abs() + 0.25);
                            assert!(
                                (p - q).abs() <= tol,
                                "array {k} part {i}: {p} vs {q} (n {n} slide {slide} half {half})"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Over many steps the builds take the same stick–slip decisions and stay within rounding.
    #[test]
    fn builds_agree_over_many_steps() {
        let mut a = Owned::new(67, 9, 3e-4, false);
        let mut b = Owned::new(67, 9, 3e-4, false);
        a.run(true, 2000, f64::INFINITY);
        b.run(false, 2000, f64::INFINITY);
        for (k, (va, vb)) in a.v.iter().zip(&b.v).enumerate() {
            for (i, (p, q)) in va.iter().zip(vb).enumerate() {
                assert!((p - q).abs() <= 1e-12, "array {k} part {i}: {p} vs {q}");
            }
        }
    }
}
