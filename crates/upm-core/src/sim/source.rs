//! Where the point parts' initial state comes from, until every chunk has read it: the parts a
//! run was given ([`Source`]), read into a chunk's state arrays by [`Source::fill`] (and, for the
//! one-pass short runs of `sim::short`, straight into the kernel's registers).

use std::sync::atomic::{AtomicBool, Ordering};

use super::base::{Base, ARRAYS};
use super::kernel::NEVER;
use super::{half_side, moves_with_plate, off_plate, Config, PartsView};
use crate::simd::Simd;

/// Where the points' initial state comes from, until every chunk has read it.
#[derive(Clone, Copy)]
pub(super) struct Source<'p> {
    pub(super) parts: PartsView<'p>,
    /// The points' places among the parts (`None`: the same).
    index: Option<&'p [usize]>,
    /// The plate velocity at the start.
    pub(super) u0: [f64; 3],
    /// Half the plate's side.
    pub(super) half: f64,
    /// Gravity's in-plane velocity a step [m/s] ([`Config::tilt`] `dt`).
    pub(super) kick: [f64; 2],
    /// `g dt`.
    pub(super) scale: f64,
    /// Set when a point's position or velocity is not finite (the run then stops after its
    /// first block with the full check's error).
    pub(super) not_finite: &'p AtomicBool,
}

impl<'p> Source<'p> {
    /// The points of `parts` (at `index` among them; `None`: every part) on a plate whose
    /// velocity at the start is `u0`; `not_finite` is set if a state read is not finite.
    pub(super) fn new(
        parts: &PartsView<'p>,
        index: Option<&'p [usize]>,
        cfg: &Config,
        u0: [f64; 3],
        not_finite: &'p AtomicBool,
    ) -> Self {
        Source {
            parts: *parts,
            index,
            u0,
            half: half_side(cfg),
            kick: cfg.kick(),
            scale: cfg.g * cfg.dt,
            not_finite,
        }
    }

    /// Writes the initial state of the points `start .. start + k` at `at ..` of `base`'s arrays.
    ///
    /// # Safety
    /// The range `at .. at + k` is within the capacity of every array of `base` the run uses,
    /// and nothing else addresses it meanwhile.
    pub(super) unsafe fn fill(
        &self,
        base: &Base,
        at: usize,
        start: usize,
        k: usize,
        spatial: bool,
    ) {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::simd() != Simd::Portable {
            return self.fill_avx2(base, at, start, k, spatial);
        }
        self.fill_any(base, at, start, k, spatial)
    }

    /// [`Source::fill`] compiled for AVX2 (the same operations, so the same results: no
    /// contraction into fused multiply–adds).
    ///
    /// # Safety
    /// As [`Source::fill`]; the CPU must support AVX2 and FMA (as [`super::simd`] found).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn fill_avx2(&self, base: &Base, at: usize, start: usize, k: usize, spatial: bool) {
        self.fill_any(base, at, start, k, spatial)
    }

    /// [`Source::fill`] in plain Rust, one array at a time in branch-free loops the compiler
    /// vectorises when the points are all the parts (no index).
    #[inline(always)]
    unsafe fn fill_any(&self, base: &Base, at: usize, start: usize, k: usize, spatial: bool) {
        use std::mem::MaybeUninit;
        let p = &self.parts;
        let out = |a: usize| std::slice::from_raw_parts_mut(base.0[a].add(at).cast(), k);
        let [x, y, vx, vy, stuck, active, left, slide, hold]: [&mut [MaybeUninit<f64>]; 9] =
            std::array::from_fn(out);
        let ix = |q: usize| self.index.map_or(start + q, |ix| ix[start + q]);
        // Whether every value read is finite, found as it is copied (reading the lanes back
        // with vectors right after the scalar stores would wait for the stores to complete).
        let finite = |a: f64, b: f64| a.is_finite() & b.is_finite();
        let mut ok = true;
        match self.index {
            None => {
                for (q, &[a, b]) in p.position[start..start + k].iter().enumerate() {
                    x[q].write(a);
                    y[q].write(b);
                    ok &= finite(a, b);
                }
            }
            Some(_) => {
                for q in 0..k {
                    let [a, b] = p.position[ix(q)];
                    x[q].write(a);
                    y[q].write(b);
                    ok &= finite(a, b);
                }
            }
        }
        match (self.index, p.velocity) {
            (_, None) => {
                vx.fill(MaybeUninit::new(0.0));
                vy.fill(MaybeUninit::new(0.0));
            }
            (None, Some(v)) => {
                for (q, &[a, b]) in v[start..start + k].iter().enumerate() {
                    vx[q].write(a);
                    vy[q].write(b);
                    ok &= finite(a, b);
                }
            }
            (Some(_), Some(v)) => {
                for q in 0..k {
                    let [a, b] = v[ix(q)];
                    vx[q].write(a);
                    vy[q].write(b);
                    ok &= finite(a, b);
                }
            }
        }
        let [x, y, vx, vy] =
            [x, y, vx, vy].map(|a| &*(a as *const [MaybeUninit<f64>] as *const [f64]));
        if !ok {
            self.not_finite.store(true, Ordering::Relaxed);
        }
        let (u0, half) = (self.u0, self.half);
        for q in 0..k {
            // A part that starts moving with the plate surface starts stuck.
            let s = moves_with_plate([x[q], y[q]], [vx[q], vy[q]], u0);
            stuck[q].write(if s { 1.0 } else { 0.0 });
            // On an unbounded plate (infinite `half`) every part is on it.
            let on = !off_plate(x[q], y[q], half);
            active[q].write(if on { 1.0 } else { 0.0 });
            left[q].write(if on { NEVER } else { 0.0 });
        }
        if p.mu.len() == 1 && p.mu_s.len() == 1 {
            slide.fill(MaybeUninit::new(p.mu(0) * self.scale));
            hold.fill(MaybeUninit::new(p.mu_s(0) * self.scale));
        } else {
            for q in 0..k {
                let i = ix(q);
                slide[q].write(p.mu(i) * self.scale);
                hold[q].write(p.mu_s(i) * self.scale);
            }
        }
        if spatial {
            for a in 9..ARRAYS {
                out(a).fill(MaybeUninit::new(0.0));
            }
        }
    }
}
