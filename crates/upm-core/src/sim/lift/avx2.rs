//! The AVX2 + FMA build of the out-of-plane step ([`super::step`]): four parts per instruction,
//! tiles of [`TILE`] vectors in registers through every step of a segment, and `1/|w|` from the
//! planar kernel's refined single-precision estimate (no square root, no division but for the
//! rare vector outside single precision's range). It agrees with the portable build to a few ulp,
//! as the AVX-512 build does.

use std::arch::x86_64::*;

use super::{Air, Reach, Steps};
use crate::sim::kernel::avx2::{leaving, mark_left, rsqrt};
use crate::sim::kernel::Lanes;

/// Vectors per tile: 32 parts (as the planar AVX2 build).
const TILE: usize = 8;

/// Advances every part of `l` through `steps`.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn run(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    if steps.half.is_finite() {
        tiles::<true>(steps, l, air)
    } else {
        tiles::<false>(steps, l, air)
    }
}

/// Without an edge (`EDGE = false`) no part leaves, so no lane keeps its state: the step writes
/// its results without a blend, as the planar build does.
#[target_feature(enable = "avx2,fma")]
unsafe fn tiles<const EDGE: bool>(steps: &Steps, l: &mut Lanes, air: &mut Air) {
    let n = l.x.len();
    let mut start = 0;
    while start < n {
        start += 4 * match (n - start).div_ceil(4) {
            1 => tile::<EDGE, 1>(steps, l, air, start),
            2 => tile::<EDGE, 2>(steps, l, air, start),
            3 | 4 => tile::<EDGE, 4>(steps, l, air, start),
            _ => tile::<EDGE, TILE>(steps, l, air, start),
        };
    }
}

/// The parts `start .. start + 4 T` (fewer at the end) through every step; returns `T`.
///
/// A step in which no part of the tile is in the air and the normal force is positive wherever
/// its parts may be ([`Reach`]) skips the flight test: most steps of most motions.
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn tile<const EDGE: bool, const T: usize>(
    steps: &Steps,
    l: &mut Lanes,
    air: &mut Air,
    start: usize,
) -> usize {
    let n = l.x.len();
    let zero = _mm256_setzero_pd();
    let inv_g = _mm256_set1_pd(1.0 / steps.g);
    let at = |j: usize| start + 4 * j;
    let mut t = Tile::<T> {
        live: [_mm256_setzero_si256(); T],
        x: [zero; T],
        y: [zero; T],
        vx: [zero; T],
        vy: [zero; T],
        slide: [zero; T],
        s2: [zero; T],
        h2: [zero; T],
        stuck: [zero; T],
        act: [zero; T],
        airborne: [false; T],
    };
    for j in 0..T {
        let count = n.saturating_sub(at(j)).min(4) as i64;
        let k = _mm256_cmpgt_epi64(_mm256_set1_epi64x(count), _mm256_set_epi64x(3, 2, 1, 0));
        t.live[j] = k;
        let load = |a: &[f64]| _mm256_maskload_pd(a.as_ptr().add(at(j)), k);
        (t.x[j], t.y[j], t.vx[j], t.vy[j]) = (load(l.x), load(l.y), load(l.vx), load(l.vy));
        t.airborne[j] = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(load(air.h), zero)) != 0;
        // mu dt and (mu dt)^2, (mu_s dt)^2: the limits are these times g + a_z (and its square)
        t.slide[j] = _mm256_mul_pd(load(l.slide), inv_g);
        t.s2[j] = _mm256_mul_pd(t.slide[j], t.slide[j]);
        let hold = _mm256_mul_pd(load(l.hold), inv_g);
        t.h2[j] = _mm256_mul_pd(hold, hold);
        t.stuck[j] = _mm256_cmp_pd::<_CMP_GT_OQ>(load(l.stuck), zero);
        t.act[j] = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GT_OQ>(load(l.active), zero),
            _mm256_castsi256_pd(k),
        );
    }
    let mut in_air = t.airborne.iter().any(|&a| a);
    let mut reach = t.reach();
    for (k, (u, nz)) in steps.u.iter().zip(steps.normals).enumerate() {
        let grounded = reach.step(in_air, u, nz, steps, || t.reach());
        let now = steps.first + k + 1;
        if grounded {
            for j in 0..T {
                t.step::<EDGE, false>(j, u, nz, steps, air, l.left, at(j), now);
            }
        } else {
            for j in 0..T {
                t.step::<EDGE, true>(j, u, nz, steps, air, l.left, at(j), now);
            }
            in_air = t.airborne.iter().any(|&a| a);
        }
    }
    let one = _mm256_set1_pd(1.0);
    for j in 0..T {
        let k = t.live[j];
        // Whole vectors with plain stores (a masked store is microcoded on AMD Zen).
        let store = |a: &mut [f64], v: __m256d| {
            if at(j) + 4 <= a.len() {
                _mm256_storeu_pd(a.as_mut_ptr().add(at(j)), v);
            } else {
                _mm256_maskstore_pd(a.as_mut_ptr().add(at(j)), k, v);
            }
        };
        store(l.x, t.x[j]);
        store(l.y, t.y[j]);
        store(l.vx, t.vx[j]);
        store(l.vy, t.vy[j]);
        store(l.stuck, _mm256_and_pd(t.stuck[j], one));
        store(l.active, _mm256_and_pd(t.act[j], one));
    }
    T
}

/// A tile's state, four parts a vector; the air state stays in memory, read only for a vector
/// with a part in the air (sixteen registers cannot hold it beside the rest, and parts seldom
/// fly).
struct Tile<const T: usize> {
    live: [__m256i; T],
    x: [__m256d; T],
    y: [__m256d; T],
    vx: [__m256d; T],
    vy: [__m256d; T],
    slide: [__m256d; T],
    s2: [__m256d; T],
    h2: [__m256d; T],
    stuck: [__m256d; T],
    act: [__m256d; T],
    airborne: [bool; T],
}

impl<const T: usize> Tile<T> {
    /// The bound on the active parts' positions and speeds, measured.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn reach(&self) -> Reach {
        let abs = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
        let (mut r, mut v) = (_mm256_setzero_pd(), _mm256_setzero_pd());
        for j in 0..T {
            let a = self.act[j];
            let far = _mm256_max_pd(_mm256_and_pd(self.x[j], abs), _mm256_and_pd(self.y[j], abs));
            let fast = _mm256_add_pd(
                _mm256_and_pd(self.vx[j], abs),
                _mm256_and_pd(self.vy[j], abs),
            );
            // NaN (a broken part) would be lost by max_pd: such a part cannot fly in either path
            r = _mm256_max_pd(_mm256_and_pd(far, a), r);
            v = _mm256_max_pd(_mm256_and_pd(fast, a), v);
        }
        let (mut rs, mut vs) = ([0.0; 4], [0.0; 4]);
        _mm256_storeu_pd(rs.as_mut_ptr(), r);
        _mm256_storeu_pd(vs.as_mut_ptr(), v);
        Reach::new(
            rs.into_iter().fold(0.0, f64::max),
            vs.into_iter().fold(0.0, f64::max),
        )
    }

    /// One step of vector `j` (the parts at `at`); `FLY = false` when no part of it can fly.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn step<const EDGE: bool, const FLY: bool>(
        &mut self,
        j: usize,
        &[u1, u2, u3]: &[f64; 3],
        nz: &[f64; 3],
        steps: &Steps,
        air: &mut Air,
        left: &mut [f64],
        at: usize,
        now: usize,
    ) {
        let zero = _mm256_setzero_pd();
        let one = _mm256_set1_pd(1.0);
        let hdt = _mm256_set1_pd(0.5 * steps.dt);
        let (u1, u2, u3) = (_mm256_set1_pd(u1), _mm256_set1_pd(u2), _mm256_set1_pd(u3));
        let base = _mm256_set1_pd(steps.g + nz[0]);
        let (ra, rb) = (_mm256_set1_pd(nz[1]), _mm256_set1_pd(nz[2]));
        let a = self.act[j];
        let (x, y, vx, vy) = (self.x[j], self.y[j], self.vx[j], self.vy[j]);
        let nrm = _mm256_fnmadd_pd(x, rb, _mm256_fmadd_pd(y, ra, base));
        let sx = _mm256_fnmadd_pd(u3, y, u1);
        let sy = _mm256_fmadd_pd(u3, x, u2);
        let (wx, wy) = (_mm256_sub_pd(vx, sx), _mm256_sub_pd(vy, sy));
        let q = _mm256_fmadd_pd(wx, wx, _mm256_mul_pd(wy, wy));
        let sl = _mm256_mul_pd(self.slide[j], nrm);
        // |w| <= mu N dt, or (stuck) <= mu_s N dt: q <= (stuck ? max(s2, h2) : s2) N^2
        let limit = _mm256_max_pd(self.s2[j], _mm256_and_pd(self.stuck[j], self.h2[j]));
        let stick = _mm256_cmp_pd::<_CMP_LE_OQ>(q, _mm256_mul_pd(limit, _mm256_mul_pd(nrm, nrm)));
        let flying = if FLY {
            let mut up = _mm256_cmp_pd::<_CMP_LT_OQ>(nrm, zero);
            if self.airborne[j] {
                let h = _mm256_maskload_pd(air.h.as_ptr().add(at), self.live[j]);
                up = _mm256_or_pd(up, _mm256_cmp_pd::<_CMP_GT_OQ>(h, zero));
            }
            _mm256_and_pd(up, a)
        } else {
            zero
        };
        let slides = _mm256_andnot_pd(flying, _mm256_andnot_pd(stick, a));
        let keep = _mm256_and_pd(slides, _mm256_fnmadd_pd(sl, rsqrt(q, slides), one));
        let mut nvx = _mm256_fmadd_pd(wx, keep, sx);
        let mut nvy = _mm256_fmadd_pd(wy, keep, sy);
        if FLY && _mm256_movemask_pd(flying) != 0 {
            let live = self.live[j];
            let (ph, phv, pf) = (
                air.h.as_mut_ptr().add(at),
                air.hv.as_mut_ptr().add(at),
                air.flight.as_mut_ptr().add(at),
            );
            let dt = _mm256_set1_pd(steps.dt);
            let (h, hv) = (_mm256_maskload_pd(ph, live), _mm256_maskload_pd(phv, live));
            let rate = _mm256_fnmadd_pd(nrm, dt, hv);
            let height = _mm256_fmadd_pd(rate, dt, h);
            let up = _mm256_and_pd(flying, _mm256_cmp_pd::<_CMP_GT_OQ>(height, zero));
            nvx = _mm256_blendv_pd(nvx, vx, flying);
            nvy = _mm256_blendv_pd(nvy, vy, flying);
            let h = _mm256_blendv_pd(h, _mm256_and_pd(up, height), flying);
            _mm256_maskstore_pd(ph, live, h);
            _mm256_maskstore_pd(
                phv,
                live,
                _mm256_blendv_pd(hv, _mm256_and_pd(up, rate), flying),
            );
            let flown = _mm256_add_pd(_mm256_maskload_pd(pf, live), _mm256_and_pd(flying, one));
            _mm256_maskstore_pd(pf, live, flown);
            self.airborne[j] = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(h, zero)) != 0;
        }
        let nx = _mm256_fmadd_pd(_mm256_add_pd(vx, nvx), hdt, x);
        let ny = _mm256_fmadd_pd(_mm256_add_pd(vy, nvy), hdt, y);
        let stuck = if FLY {
            _mm256_andnot_pd(flying, stick)
        } else {
            stick
        };
        if !EDGE {
            (self.x[j], self.y[j], self.vx[j], self.vy[j]) = (nx, ny, nvx, nvy);
            self.stuck[j] = stuck;
            return;
        }
        // parts that left the plate keep their state
        self.x[j] = _mm256_blendv_pd(x, nx, a);
        self.y[j] = _mm256_blendv_pd(y, ny, a);
        self.vx[j] = _mm256_blendv_pd(vx, nvx, a);
        self.vy[j] = _mm256_blendv_pd(vy, nvy, a);
        self.stuck[j] = _mm256_blendv_pd(self.stuck[j], stuck, a);
        let abs = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
        let halfv = _mm256_set1_pd(steps.half);
        let off = leaving(nx, ny, abs, halfv, a);
        let bits = _mm256_movemask_pd(off);
        if bits != 0 {
            self.act[j] = _mm256_andnot_pd(off, a);
            mark_left(bits, left, at, now);
        }
    }
}
