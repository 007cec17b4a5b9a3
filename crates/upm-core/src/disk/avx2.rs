//! The AVX2 build of [`super::lanes`]' lockstep: four disks per instruction, up to eight vectors
//! side by side, each lane's table rows read by two wide loads, each lane's exits kept in vector
//! masks. Every lane does
//! exactly the one-disk solve's arithmetic ([`super::halley`]: the same operations in the same
//! order, no fused multiply–add), so the results are bitwise those of the portable lockstep.

use std::arch::x86_64::*;

use super::{HALLEY_STEPS, ZTABLE};

/// Vectors of four disks [`lockstep`] iterates side by side.
pub(super) const VECTORS: usize = 8;

/// One vector's Halley state (see [`super::halley`]): the disks' `(a0, b0, c)`, `2c`, `4c`, the
/// iterate `z`, which lanes still iterate, which settled with a positive result and that result.
#[derive(Clone, Copy)]
struct Four {
    a0: __m256d,
    b0: __m256d,
    c: __m256d,
    c2: __m256d,
    c4: __m256d,
    z: __m256d,
    live: __m256d,
    ok: __m256d,
    ra: __m256d,
    rb: __m256d,
}

/// Up to `4 VECTORS` disks (`a0.len() <= 32`) through [`super::slide_newton`], four to a vector;
/// round by round, each round one Halley step of every vector still iterating, so that the
/// vectors' long dependency chains (table rows, cubic, three divisions) overlap in the out-of-order
/// core.
///
/// # Safety
/// The CPU must support AVX2; `tab` is the padded z table ([`super::ztable_padded`]).
#[target_feature(enable = "avx2")]
pub(super) unsafe fn lockstep(
    tab: &[[f64; 2]],
    a0: &[f64],
    b0: &[f64],
    c: &[f64],
    out: &mut [Option<(f64, f64)>],
) {
    let n = a0.len();
    assert!(
        n <= 4 * VECTORS && b0.len() == n && c.len() == n && out.len() == n,
        "lockstep: at most {} disks, slices of one length",
        4 * VECTORS
    );
    assert_eq!(tab.len(), ZTABLE + 2, "lockstep reads the padded z table");
    let vectors = n.div_ceil(4);
    let zero = _mm256_setzero_pd();
    let mut state = [Four {
        a0: zero,
        b0: zero,
        c: zero,
        c2: zero,
        c4: zero,
        z: zero,
        live: zero,
        ok: zero,
        ra: zero,
        rb: zero,
    }; VECTORS];
    for (v, s) in state.iter_mut().enumerate().take(vectors) {
        let at = 4 * v;
        // lanes at .. n: all ones
        let lanes_i = _mm256_cmpgt_epi64(
            _mm256_set1_epi64x((n - at) as i64),
            _mm256_setr_epi64x(0, 1, 2, 3),
        );
        let lanes = _mm256_castsi256_pd(lanes_i);
        s.a0 = _mm256_maskload_pd(a0.as_ptr().add(at), lanes_i);
        s.b0 = _mm256_maskload_pd(b0.as_ptr().add(at), lanes_i);
        s.c = _mm256_maskload_pd(c.as_ptr().add(at), lanes_i);
        s.c2 = _mm256_mul_pd(_mm256_set1_pd(2.0), s.c);
        s.c4 = _mm256_mul_pd(_mm256_set1_pd(4.0), s.c);
        // Padding lanes: z = 0 (their loads read the table's first rows) and never live.
        s.z = _mm256_and_pd(lanes, _mm256_div_pd(s.b0, _mm256_add_pd(s.a0, s.b0)));
        s.live = lanes;
    }
    let base = tab.as_ptr() as *const f64;
    for _ in 0..HALLEY_STEPS {
        let mut any = false;
        for s in state.iter_mut().take(vectors) {
            if _mm256_movemask_pd(s.live) != 0 {
                step(base, s);
                any = true;
            }
        }
        if !any {
            break;
        }
    }
    for (v, s) in state.iter().enumerate().take(vectors) {
        let (mut xa, mut xb) = ([0.0; 4], [0.0; 4]);
        _mm256_storeu_pd(xa.as_mut_ptr(), s.ra);
        _mm256_storeu_pd(xb.as_mut_ptr(), s.rb);
        let ok = _mm256_movemask_pd(s.ok);
        for (l, o) in out[4 * v..].iter_mut().take(4).enumerate() {
            *o = (ok >> l & 1 == 1).then_some((xa[l], xb[l]));
        }
    }
}

/// One Halley step ([`super::halley`]) of the live lanes of `st`, on the padded z table at
/// `base` (with the target feature, so that its closures inline the intrinsics).
///
/// # Safety
/// The CPU must support AVX2; `base` is the padded z table's ([`super::ztable_padded`]).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn step(base: *const f64, st: &mut Four) {
    let set = _mm256_set1_pd;
    let (zero, one) = (set(0.0), set(1.0));
    let scale = set((ZTABLE - 1) as f64);
    let last = _mm_set1_epi32(ZTABLE as i32 - 2);
    let abs = |x: __m256d| _mm256_andnot_pd(set(-0.0), x);
    let Four {
        a0: va0,
        b0: vb0,
        c: vc,
        c2,
        c4,
        mut z,
        mut live,
        mut ok,
        mut ra,
        mut rb,
    } = *st;
    // The table's cubic at z (super::curve_z).
    let u = _mm256_mul_pd(_mm256_min_pd(_mm256_max_pd(z, zero), one), scale);
    let i = _mm_min_epi32(_mm256_cvttpd_epi32(u), last);
    let s = _mm256_sub_pd(u, _mm256_cvtepi32_pd(i));
    // Each lane's four rows i - 1 .. i + 2 as two loads from the padded table (its row i + 1
    // is the table's row i; the edge rows repeated, as the clamped indices of curve_z read them),
    // then transposed: every lane reads a valid row (z is clamped), so no lane is masked.
    let mut rows = [0i32; 4];
    _mm_storeu_si128(rows.as_mut_ptr().cast(), i);
    let lo = rows.map(|r| _mm256_loadu_pd(base.add(2 * r as usize)));
    let hi = rows.map(|r| _mm256_loadu_pd(base.add(2 * r as usize + 4)));
    // [f(r) t(r) f(r+1) t(r+1)] of the four lanes -> ([f(r)], [f(r+1)], [t(r)], [t(r+1)]).
    let transpose = |v: [__m256d; 4]| {
        let (f01, t01) = (
            _mm256_unpacklo_pd(v[0], v[1]),
            _mm256_unpackhi_pd(v[0], v[1]),
        );
        let (f23, t23) = (
            _mm256_unpacklo_pd(v[2], v[3]),
            _mm256_unpackhi_pd(v[2], v[3]),
        );
        (
            _mm256_permute2f128_pd::<0x20>(f01, f23),
            _mm256_permute2f128_pd::<0x31>(f01, f23),
            _mm256_permute2f128_pd::<0x20>(t01, t23),
            _mm256_permute2f128_pd::<0x31>(t01, t23),
        )
    };
    let (f0, f1, t0, t1) = transpose(lo);
    let (f2, f3, t2, t3) = transpose(hi);
    // the cubic through the rows a, b, cc, d at s, with its first two derivatives
    let cr = |a: __m256d, b: __m256d, cc: __m256d, d: __m256d| {
        let c1 = _mm256_mul_pd(set(0.5), _mm256_sub_pd(cc, a));
        let c2 = _mm256_sub_pd(
            _mm256_add_pd(
                _mm256_sub_pd(a, _mm256_mul_pd(set(2.5), b)),
                _mm256_mul_pd(set(2.0), cc),
            ),
            _mm256_mul_pd(set(0.5), d),
        );
        let c3 = _mm256_add_pd(
            _mm256_mul_pd(set(1.5), _mm256_sub_pd(b, cc)),
            _mm256_mul_pd(set(0.5), _mm256_sub_pd(d, a)),
        );
        let v0 = _mm256_add_pd(
            b,
            _mm256_mul_pd(
                s,
                _mm256_add_pd(
                    c1,
                    _mm256_mul_pd(s, _mm256_add_pd(c2, _mm256_mul_pd(s, c3))),
                ),
            ),
        );
        let v1 = _mm256_mul_pd(
            _mm256_add_pd(
                c1,
                _mm256_mul_pd(
                    s,
                    _mm256_add_pd(
                        _mm256_mul_pd(set(2.0), c2),
                        _mm256_mul_pd(_mm256_mul_pd(set(3.0), s), c3),
                    ),
                ),
            ),
            scale,
        );
        let v2 = _mm256_mul_pd(
            _mm256_mul_pd(
                _mm256_add_pd(
                    _mm256_mul_pd(set(2.0), c2),
                    _mm256_mul_pd(_mm256_mul_pd(set(6.0), s), c3),
                ),
                scale,
            ),
            scale,
        );
        (v0, v1, v2)
    };
    let ((f, df, ddf), (t, dt, ddt)) = (cr(f0, f1, f2, f3), cr(t0, t1, t2, t3));
    // One Halley step (super::halley).
    let a = _mm256_sub_pd(va0, _mm256_mul_pd(vc, f));
    let b = _mm256_sub_pd(vb0, _mm256_mul_pd(c2, t));
    let omz = _mm256_sub_pd(one, z);
    let cz = _mm256_mul_pd(vc, z);
    let c2omz = _mm256_mul_pd(c2, omz);
    let r = _mm256_sub_pd(_mm256_mul_pd(omz, b), _mm256_mul_pd(z, a));
    // -b, as Rust's negation: the sign bit flipped.
    let neg_b = _mm256_xor_pd(b, set(-0.0));
    let dr = _mm256_add_pd(
        _mm256_sub_pd(_mm256_sub_pd(neg_b, a), _mm256_mul_pd(c2omz, dt)),
        _mm256_mul_pd(cz, df),
    );
    let ddr = _mm256_add_pd(
        _mm256_sub_pd(
            _mm256_add_pd(_mm256_mul_pd(c4, dt), _mm256_mul_pd(c2, df)),
            _mm256_mul_pd(c2omz, ddt),
        ),
        _mm256_mul_pd(cz, ddf),
    );
    // dr NaN or >= 0: not sliding as assumed.
    live = _mm256_andnot_pd(_mm256_cmp_pd::<_CMP_NLT_UQ>(dr, zero), live);
    let newton = _mm256_div_pd(r, dr);
    let step = _mm256_div_pd(
        newton,
        _mm256_sub_pd(
            one,
            _mm256_div_pd(_mm256_mul_pd(_mm256_mul_pd(set(0.5), newton), ddr), dr),
        ),
    );
    let next = _mm256_sub_pd(z, step);
    live = _mm256_and_pd(
        live,
        _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GE_OQ>(next, zero),
            _mm256_cmp_pd::<_CMP_LE_OQ>(next, one),
        ),
    );
    let settled = _mm256_and_pd(live, _mm256_cmp_pd::<_CMP_LE_OQ>(abs(step), set(1e-6)));
    if _mm256_movemask_pd(settled) != 0 {
        let h = _mm256_mul_pd(_mm256_mul_pd(set(0.5), step), step);
        // x0 - k (v - v' step + v'' h): the result from the curve's Taylor polynomial
        let taylor = |x0: __m256d, k: __m256d, v: __m256d, dv: __m256d, ddv: __m256d| {
            _mm256_sub_pd(
                x0,
                _mm256_mul_pd(
                    k,
                    _mm256_add_pd(
                        _mm256_sub_pd(v, _mm256_mul_pd(dv, step)),
                        _mm256_mul_pd(ddv, h),
                    ),
                ),
            )
        };
        let (fa, fb) = (taylor(va0, vc, f, df, ddf), taylor(vb0, c2, t, dt, ddt));
        let positive = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GT_OQ>(fa, zero),
            _mm256_cmp_pd::<_CMP_GT_OQ>(fb, zero),
        );
        ok = _mm256_or_pd(ok, _mm256_and_pd(settled, positive));
        ra = _mm256_blendv_pd(ra, fa, settled);
        rb = _mm256_blendv_pd(rb, fb, settled);
        live = _mm256_andnot_pd(settled, live);
    }
    z = _mm256_blendv_pd(z, next, live);
    *st = Four {
        z,
        live,
        ok,
        ra,
        rb,
        ..*st
    };
}
