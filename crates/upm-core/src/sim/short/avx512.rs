//! The one-pass short run on the AVX-512 build: tiles of up to eight vectors of eight points (see
//! [`super`]), the kernel's [`step`]. A result streamed to memory ([`Rec::streams`]) is written
//! with non-temporal stores of whole cache lines: on an Intel Xeon (Sapphire Rapids class) plain
//! stores reach 7 GB/s on one core and non-temporal ones 13.5, and a 2-step call on 1e6 parts
//! writes 75 bytes per part.

use std::arch::x86_64::*;
use std::sync::atomic::Ordering;

use crate::sim::kernel::avx512::{leaving, splat, step, tile_width, Consts, Eight};
use crate::sim::kernel::NEVER;
use crate::sim::record::{Rec, FLAG_BYTES};
use crate::sim::source::Source;

/// The points `start .. end` (whole vectors of eight) in tiles of up to eight vectors.
///
/// # Safety
/// As [`Source::short`], on a CPU with AVX-512F.
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn tiles<const EDGE: bool>(
    src: &Source,
    start: usize,
    end: usize,
    table: &[[f64; 3]],
    dt: f64,
    rec: &Rec,
) {
    let mut at = start;
    while at < end {
        at += 8 * match tile_width((end - at) / 8) {
            1 => tile::<EDGE, 1>(src, at, table, dt, rec),
            2 => tile::<EDGE, 2>(src, at, table, dt, rec),
            3 => tile::<EDGE, 3>(src, at, table, dt, rec),
            4 => tile::<EDGE, 4>(src, at, table, dt, rec),
            5 => tile::<EDGE, 5>(src, at, table, dt, rec),
            6 => tile::<EDGE, 6>(src, at, table, dt, rec),
            7 => tile::<EDGE, 7>(src, at, table, dt, rec),
            _ => tile::<EDGE, 8>(src, at, table, dt, rec),
        };
    }
}

/// One tile of `T` vectors: the points `at .. at + 8 T`, read, recorded and stepped; returns
/// `T`.
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn tile<const EDGE: bool, const T: usize>(
    src: &Source,
    at: usize,
    table: &[[f64; 3]],
    dt: f64,
    rec: &Rec,
) -> usize {
    let p = &src.parts;
    let zero = _mm512_setzero_pd();
    let [u1, u2, u3] = src.u0.map(|u| _mm512_set1_pd(u));
    let (half, scale) = (_mm512_set1_pd(src.half), _mm512_set1_pd(src.scale));
    let never = _mm512_set1_pd(NEVER);
    // each lane's step count when it left the plate (NEVER: it did not)
    let mut left = [never; T];
    let mut finite: __mmask8 = 0xff;
    let mut place = std::mem::MaybeUninit::<[Eight; T]>::uninit();
    for (j, left) in left.iter_mut().enumerate() {
        let i = at + 8 * j;
        let (x, y) = split(p.position.as_ptr().add(i));
        let (vx, vy) = p
            .velocity
            .map_or((zero, zero), |w| split(w.as_ptr().add(i)));
        for a in [x, y, vx, vy] {
            finite &= _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(_mm512_sub_pd(a, a), zero);
        }
        // a part that starts moving with the plate surface starts stuck (`moves_with_plate`:
        // a product and a difference, not fused)
        let sx = _mm512_sub_pd(u1, _mm512_mul_pd(u3, y));
        let sy = _mm512_add_pd(u2, _mm512_mul_pd(u3, x));
        let stuck =
            _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(vx, sx) & _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(vy, sy);
        // one off the plate at the start has left it at step 0 (`off_plate`)
        let off = leaving(x, y, half, 0xff);
        *left = _mm512_mask_mov_pd(never, off, zero);
        let each = |a: &[f64]| {
            if a.len() == 1 {
                _mm512_set1_pd(a[0])
            } else {
                _mm512_loadu_pd(a.as_ptr().add(i))
            }
        };
        let (slide, hold) = (
            _mm512_mul_pd(each(p.mu), scale),
            _mm512_mul_pd(each(p.mu_s), scale),
        );
        let eight = Eight {
            x,
            y,
            vx,
            vy,
            stuck,
            act: !off,
            slide,
            s2: _mm512_mul_pd(slide, slide),
            h2: _mm512_mul_pd(hold, hold),
        };
        place.as_mut_ptr().cast::<Eight>().add(j).write(eight);
    }
    // SAFETY: each of the T vectors was written just now.
    let v = &mut *place.as_mut_ptr();
    if finite != 0xff {
        src.not_finite.store(true, Ordering::Relaxed);
    }
    record(rec, 0, at, v);
    let c = Consts::new(dt, src.half, src.kick);
    let mut next = rec.next_after(0);
    for (k, &u) in table.iter().enumerate() {
        let u = splat(u);
        for j in 0..T {
            let off = step::<EDGE>(&mut v[j], u, &c);
            if EDGE {
                left[j] = _mm512_mask_mov_pd(left[j], off, _mm512_set1_pd((k + 1) as f64));
            }
        }
        if k + 1 == next {
            if let Some(row) = rec.row(k + 1) {
                record(rec, row, at, v);
            }
            next = rec.next_after(k + 1);
        }
    }
    // when each left (`left_time`: the step count times dt, NaN: never), and whether it did
    let (times, gone) = rec.left_cells(at);
    let mut t = [zero; T];
    for (j, &l) in left.iter().enumerate() {
        let did = _mm512_cmp_pd_mask::<_CMP_NEQ_OQ>(l, never);
        let time = _mm512_mul_pd(l, _mm512_set1_pd(dt));
        t[j] = _mm512_mask_mov_pd(_mm512_set1_pd(f64::NAN), did, time);
        gone.add(8 * j)
            .cast::<u64>()
            .write_unaligned(FLAG_BYTES[did as usize]);
    }
    store(rec.streams(), times, &t);
    T
}

/// The x and y of the eight pairs at `p` (`[x0, y0, x1, y1, ..., x7, y7]`).
#[inline(always)]
unsafe fn split(p: *const [f64; 2]) -> (__m512d, __m512d) {
    let (a, b) = (_mm512_loadu_pd(p.cast()), _mm512_loadu_pd(p.add(4).cast()));
    let even = _mm512_set_epi64(14, 12, 10, 8, 6, 4, 2, 0);
    let odd = _mm512_set_epi64(15, 13, 11, 9, 7, 5, 3, 1);
    (
        _mm512_permutex2var_pd(a, even, b),
        _mm512_permutex2var_pd(a, odd, b),
    )
}

/// The cells `(a[q], b[q])` of eight lanes, in order, as two vectors of four cells each.
#[inline(always)]
unsafe fn cells(a: __m512d, b: __m512d) -> [__m512d; 2] {
    let lo = _mm512_set_epi64(11, 3, 10, 2, 9, 1, 8, 0);
    let hi = _mm512_set_epi64(15, 7, 14, 6, 13, 5, 12, 4);
    [
        _mm512_permutex2var_pd(a, lo, b),
        _mm512_permutex2var_pd(a, hi, b),
    ]
}

/// Writes the vectors' positions, velocities and stuck flags into `row` for the parts `at ..`.
#[inline(always)]
unsafe fn record<const T: usize>(rec: &Rec, row: usize, at: usize, v: &[Eight; T]) {
    let (pos, vel, stuck) = rec.row_cells(row, at);
    let stream = rec.streams();
    // (loops, not `map`: a closure's intrinsics were calls, not instructions)
    let (mut p, mut w) = ([[_mm512_setzero_pd(); 2]; T], [[_mm512_setzero_pd(); 2]; T]);
    for (j, f) in v.iter().enumerate() {
        p[j] = cells(f.x, f.y);
        w[j] = cells(f.vx, f.vy);
    }
    store(stream, pos.cast(), p.as_flattened());
    store(stream, vel.cast(), w.as_flattened());
    for (j, f) in v.iter().enumerate() {
        let word = FLAG_BYTES[f.stuck as usize];
        stuck.add(8 * j).cast::<u64>().write_unaligned(word);
    }
}

/// Writes the vectors `c` one after another at `out` (8-byte aligned): with `stream`, each whole
/// cache line they cover with a non-temporal store and the two partial ones at the ends (which
/// the neighbouring tiles share) with masked plain stores within the line; else with plain
/// stores. (A masked store of the unaligned vector, its masked lanes in the next line, made the
/// streamed lines 13x slower on an Intel Xeon: 2.2 GB/s against 18.)
#[inline(always)]
unsafe fn store(stream: bool, out: *mut f64, c: &[__m512d]) {
    // (the qwords from the start of the first line)
    let d = (out as usize / 8) % 8;
    if !stream {
        for (j, &v) in c.iter().enumerate() {
            _mm512_storeu_pd(out.add(8 * j), v);
        }
    } else if d == 0 {
        for (j, &v) in c.iter().enumerate() {
            _mm512_stream_pd(out.add(8 * j), v);
        }
    } else {
        // line i (from out - d) holds the last d qwords of c[i - 1] and the first 8 - d of
        // c[i]: lane k takes qword 8 - d + k of the pair (c[i - 1], c[i])
        let shift = _mm512_add_epi64(
            _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0),
            _mm512_set1_epi64(8 - d as i64),
        );
        let (n, line) = (c.len(), out.sub(d));
        // lanes 0 .. d of a line
        let lower = ((1u16 << d) - 1) as __mmask8;
        let first = _mm512_permutex2var_pd(c[0], shift, c[0]);
        _mm512_mask_storeu_pd(line, !lower, first);
        for i in 1..n {
            let v = _mm512_permutex2var_pd(c[i - 1], shift, c[i]);
            _mm512_stream_pd(line.add(8 * i), v);
        }
        let last = _mm512_permutex2var_pd(c[n - 1], shift, c[n - 1]);
        _mm512_mask_storeu_pd(line.add(8 * n), lower, last);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every alignment of the first qword within its cache line, with one to four vectors,
    /// streamed or not: the vectors land in order, and nothing around them is touched.
    #[test]
    fn stored_vectors_land_in_order_at_every_alignment() {
        if !is_x86_feature_detected!("avx512f") {
            return;
        }
        #[repr(align(64))]
        struct Lines([f64; 64]);
        for stream in [false, true] {
            for d in 0..8 {
                for n in 1..=4 {
                    let mut buf = Lines([-1.0; 64]);
                    let values: Vec<f64> = (0..8 * n).map(|q| q as f64).collect();
                    // SAFETY: AVX-512F (checked); 8 + d + 8 n <= 48 qwords of the buffer.
                    unsafe {
                        let c: Vec<__m512d> = values
                            .chunks(8)
                            .map(|v| _mm512_loadu_pd(v.as_ptr()))
                            .collect();
                        store(stream, buf.0.as_mut_ptr().add(8 + d), &c);
                        _mm_sfence();
                    }
                    let at = 8 + d;
                    assert_eq!(&buf.0[at..at + 8 * n], &values[..], "d {d} n {n} {stream}");
                    assert!(buf.0[..at].iter().all(|&v| v == -1.0), "d {d} n {n}");
                    assert!(
                        buf.0[at + 8 * n..].iter().all(|&v| v == -1.0),
                        "d {d} n {n}"
                    );
                }
            }
        }
    }
}
