//! Result cells written a vector at a time: the `(x, y)` pairs of four lanes, eight stuck flags
//! as a word, and the times of leaving the plate, with non-temporal stores for a result
//! streamed to memory (`NT`, see [`super::Rec::points_run`]) or plain ones, and as values the
//! one-pass short run stores itself (`sim::short`).

/// The cells `(a[q], b[q])` of four lanes, in order, as two vectors of two cells each.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(in crate::sim) unsafe fn cells(
    a: std::arch::x86_64::__m256d,
    b: std::arch::x86_64::__m256d,
) -> [std::arch::x86_64::__m256d; 2] {
    use std::arch::x86_64::*;
    // (a0 b0 a2 b2) and (a1 b1 a3 b3), then their 128-bit halves regrouped in order
    let (lo, hi) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
    [
        _mm256_permute2f128_pd::<0x20>(lo, hi),
        _mm256_permute2f128_pd::<0x31>(lo, hi),
    ]
}

/// Writes `(a[q], b[q])` at `out[q]` for every `q`, pairs of cells as one 32-byte store each;
/// non-temporal (`NT`) from where `out` is 32-byte aligned (16-byte ones until then).
///
/// # Safety
/// The build has AVX; `out` is 16-byte aligned with room for `a.len()` cells; `b` is as long.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
pub(super) unsafe fn pairs<const NT: bool>(out: *mut [f64; 2], a: &[f64], b: &[f64]) {
    use std::arch::x86_64::*;
    let k = a.len().min(b.len());
    let one = |q: usize| {
        let cell = _mm_set_pd(b[q], a[q]);
        if NT {
            _mm_stream_pd(out.add(q).cast(), cell)
        } else {
            _mm_storeu_pd(out.add(q).cast(), cell)
        }
    };
    let mut q = 0;
    while NT && q < k && !(out.add(q) as usize).is_multiple_of(32) {
        one(q);
        q += 1;
    }
    while q + 4 <= k {
        let x = _mm256_loadu_pd(a.as_ptr().add(q));
        let y = _mm256_loadu_pd(b.as_ptr().add(q));
        let [c01, c23] = cells(x, y);
        if NT {
            _mm256_stream_pd(out.add(q).cast(), c01);
            _mm256_stream_pd(out.add(q + 2).cast(), c23);
        } else {
            _mm256_storeu_pd(out.add(q).cast(), c01);
            _mm256_storeu_pd(out.add(q + 2).cast(), c23);
        }
        q += 4;
    }
    while q < k {
        one(q);
        q += 1;
    }
}

/// Eight flags (the bits of the index, flag `j` bit `j`) as eight bools (byte `j`, little-endian).
pub(in crate::sim) const FLAG_BYTES: [u64; 256] = {
    let mut table = [0u64; 256];
    let mut bits = 0;
    while bits < 256 {
        let mut j = 0;
        while j < 8 {
            table[bits] |= (((bits >> j) & 1) as u64) << (8 * j);
            j += 1;
        }
        bits += 1;
    }
    table
};

/// `out[q] = values[q] OP against` for every `q`, `OP` the comparison `_mm256_cmp_pd` takes as
/// `OP`; whole words of eight, non-temporal (`NT`) and aligned.
///
/// # Safety
/// The build has AVX2; `out` has room for `values.len()` flags.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn flags<const OP: i32, const NT: bool>(
    out: *mut bool,
    values: &[f64],
    against: f64,
) {
    use std::arch::x86_64::*;
    let k = values.len();
    let against = _mm256_set1_pd(against);
    let test = |v: __m256d| _mm256_cmp_pd::<OP>(v, against);
    let one = |q: usize| _mm256_movemask_pd(test(_mm256_set1_pd(values[q]))) & 1 == 1;
    let mut q = 0;
    while NT && q < k && !(out.add(q) as usize).is_multiple_of(8) {
        out.add(q).write(one(q));
        q += 1;
    }
    let set = |at: usize| _mm256_movemask_pd(test(_mm256_loadu_pd(values.as_ptr().add(at))));
    while q + 8 <= k {
        let word = FLAG_BYTES[(set(q) | set(q + 4) << 4) as usize];
        if NT {
            // The word is aligned and within `out` (above).
            _mm_stream_si64(out.add(q).cast(), word as i64);
        } else {
            out.add(q).cast::<u64>().write_unaligned(word);
        }
        q += 8;
    }
    while q < k {
        out.add(q).write(one(q));
        q += 1;
    }
}

/// The time [s] of leaving the plate after `steps` steps of `dt` ([`crate::sim::kernel::NEVER`]:
/// never, NaN).
#[inline(always)]
pub(super) fn left_time(steps: f64, dt: f64) -> f64 {
    if steps != crate::sim::kernel::NEVER {
        steps * dt
    } else {
        f64::NAN
    }
}

/// [`left_time`] of four step counts, and the lanes that left (all ones).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(in crate::sim) unsafe fn left_times(
    steps: std::arch::x86_64::__m256d,
    dt: f64,
) -> [std::arch::x86_64::__m256d; 2] {
    use std::arch::x86_64::*;
    let left = _mm256_cmp_pd::<_CMP_NEQ_OQ>(steps, _mm256_set1_pd(crate::sim::kernel::NEVER));
    let time = _mm256_mul_pd(steps, _mm256_set1_pd(dt));
    [_mm256_blendv_pd(_mm256_set1_pd(f64::NAN), time, left), left]
}

/// `out[q] = left_time(steps[q], dt)` for every `q`, four a store (the same product, so the
/// same bits); non-temporal (`NT`) from where `out` is 32-byte aligned (8-byte ones until then).
///
/// # Safety
/// The build has AVX2; `out` is 8-byte aligned with room for `steps.len()` times.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn times<const NT: bool>(out: *mut f64, steps: &[f64], dt: f64) {
    use std::arch::x86_64::*;
    let k = steps.len();
    let mut q = 0;
    while NT && q < k && !(out.add(q) as usize).is_multiple_of(32) {
        out.add(q).write(left_time(steps[q], dt));
        q += 1;
    }
    while q + 4 <= k {
        let t = left_times(_mm256_loadu_pd(steps.as_ptr().add(q)), dt)[0];
        if NT {
            _mm256_stream_pd(out.add(q), t);
        } else {
            _mm256_storeu_pd(out.add(q), t);
        }
        q += 4;
    }
    while q < k {
        out.add(q).write(left_time(steps[q], dt));
        q += 1;
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::sim::kernel::NEVER;

    /// Step counts, some never leaving, at every offset into an aligned buffer and of every
    /// length up to past four vectors.
    fn cases() -> impl Iterator<Item = (usize, Vec<f64>)> {
        (0..9).flat_map(|offset| {
            (0..40).map(move |k| {
                let steps = (0..k)
                    .map(|q| {
                        if (q * 7 + offset) % 3 == 0 {
                            NEVER
                        } else {
                            (q * 13 + 1) as f64
                        }
                    })
                    .collect();
                (offset, steps)
            })
        })
    }

    /// The cells, times and flags [`pairs`], [`times`] and [`flags`] write (`NT` or not)
    /// against the scalar ones, at `offset` cells into an aligned buffer; nothing written past
    /// the last.
    unsafe fn check<const NT: bool>(offset: usize, steps: &[f64]) {
        let (dt, k) = (1.0 / 2400.0, steps.len());
        let y: Vec<f64> = steps.iter().map(|s| -0.5 * s).collect();
        // (buffers of 32-byte units, so that `offset` walks the alignments)
        let mut times_at = vec![[0.0f64; 4]; (offset + k).div_ceil(4) + 1];
        let mut cells_at = vec![[0.0f64; 4]; (offset + k).div_ceil(2) + 1];
        let mut flags_at = vec![u64::from_ne_bytes([7; 8]); (offset + k).div_ceil(8) + 1];
        let (t, c, f) = (
            times_at.as_mut_ptr().cast::<f64>().add(offset),
            cells_at.as_mut_ptr().cast::<[f64; 2]>().add(offset),
            flags_at.as_mut_ptr().cast::<bool>().add(offset),
        );
        times::<NT>(t, steps, dt);
        pairs::<NT>(c, steps, &y);
        flags::<{ std::arch::x86_64::_CMP_NEQ_OQ }, NT>(f, steps, NEVER);
        std::arch::x86_64::_mm_sfence();
        let at = format!("NT {NT} offset {offset} k {k}");
        for (q, &s) in steps.iter().enumerate() {
            let want = if s == NEVER { f64::NAN } else { s * dt };
            assert_eq!((*t.add(q)).to_bits(), want.to_bits(), "{at} q {q}");
            assert_eq!(*c.add(q), [s, y[q]], "{at} q {q}");
            assert_eq!(*f.add(q).cast::<u8>(), u8::from(s != NEVER), "{at} q {q}");
        }
        assert_eq!(*f.add(k).cast::<u8>(), 7, "{at}");
        assert_eq!(*t.add(k), 0.0, "{at}");
        assert_eq!(*c.add(k), [0.0; 2], "{at}");
    }

    #[test]
    fn vector_cells_times_and_flags_are_the_scalar_ones() {
        if !is_x86_feature_detected!("avx2") {
            return;
        }
        for (offset, steps) in cases() {
            // SAFETY: AVX2 (checked).
            unsafe {
                check::<true>(offset, &steps);
                check::<false>(offset, &steps);
            }
        }
    }
}
