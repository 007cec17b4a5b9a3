//! The AVX2 build of [`super::lanes`]' lockstep: four disks per instruction (eight as two
//! halves), the table read by gathers, each lane's exits kept in vector masks. Every lane does
//! exactly the one-disk solve's arithmetic ([`super::halley`]: the same operations in the same
//! order, no fused multiply–add), so the results are bitwise those of the portable lockstep.

use std::arch::x86_64::*;

use super::{HALLEY_STEPS, ZTABLE};

/// Up to eight disks (`a0.len() <= 8`) through [`super::slide_newton`], four at a time.
///
/// # Safety
/// The CPU must support AVX2; `tab` is the z table.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn lockstep(
    tab: &[[f64; 2]],
    a0: &[f64],
    b0: &[f64],
    c: &[f64],
    out: &mut [Option<(f64, f64)>],
) {
    for k in (0..a0.len()).step_by(4) {
        let r = k..(k + 4).min(a0.len());
        four(
            tab,
            &a0[r.clone()],
            &b0[r.clone()],
            &c[r.clone()],
            &mut out[r],
        );
    }
}

/// Up to four disks side by side (with the target feature, so that its closures inline the
/// intrinsics).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn four(
    tab: &[[f64; 2]],
    a0: &[f64],
    b0: &[f64],
    c: &[f64],
    out: &mut [Option<(f64, f64)>],
) {
    let m = a0.len();
    debug_assert!(m <= 4 && b0.len() == m && c.len() == m && out.len() == m);
    debug_assert_eq!(tab.len(), ZTABLE);
    let base = tab.as_ptr() as *const f64;
    // lanes 0..m: all ones
    let lanes_i = _mm256_cmpgt_epi64(_mm256_set1_epi64x(m as i64), _mm256_setr_epi64x(0, 1, 2, 3));
    let lanes = _mm256_castsi256_pd(lanes_i);
    let set = _mm256_set1_pd;
    let (zero, one) = (set(0.0), set(1.0));
    let va0 = _mm256_maskload_pd(a0.as_ptr(), lanes_i);
    let vb0 = _mm256_maskload_pd(b0.as_ptr(), lanes_i);
    let vc = _mm256_maskload_pd(c.as_ptr(), lanes_i);
    let c2 = _mm256_mul_pd(set(2.0), vc);
    let c4 = _mm256_mul_pd(set(4.0), vc);
    let scale = set((ZTABLE - 1) as f64);
    let (last, top) = (
        _mm_set1_epi32(ZTABLE as i32 - 2),
        _mm_set1_epi32(ZTABLE as i32 - 1),
    );
    // Padding lanes: z = 0 and never live (their gathers read nothing).
    let mut z = _mm256_and_pd(lanes, _mm256_div_pd(vb0, _mm256_add_pd(va0, vb0)));
    let mut live = lanes;
    let (mut ok, mut ra, mut rb) = (zero, zero, zero);
    let abs = |x: __m256d| _mm256_andnot_pd(set(-0.0), x);
    for _ in 0..HALLEY_STEPS {
        if _mm256_movemask_pd(live) == 0 {
            break;
        }
        // The table's cubic at z (super::curve_z).
        let u = _mm256_mul_pd(_mm256_min_pd(_mm256_max_pd(z, zero), one), scale);
        let i = _mm_min_epi32(_mm256_cvttpd_epi32(u), last);
        let s = _mm256_sub_pd(u, _mm256_cvtepi32_pd(i));
        let k1 = _mm_set1_epi32(1);
        let idx = [
            _mm_max_epi32(_mm_sub_epi32(i, k1), _mm_setzero_si128()),
            i,
            _mm_add_epi32(i, k1),
            _mm_min_epi32(_mm_add_epi32(i, _mm_set1_epi32(2)), top),
        ];
        let gather = |k: __m128i, col: i32| {
            let off = _mm_add_epi32(_mm_slli_epi32::<1>(k), _mm_set1_epi32(col));
            _mm256_mask_i32gather_pd::<8>(zero, base, off, live)
        };
        let cr = |col: i32| {
            let (a, b, cc, d) = (
                gather(idx[0], col),
                gather(idx[1], col),
                gather(idx[2], col),
                gather(idx[3], col),
            );
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
        let ((f, df, ddf), (t, dt, ddt)) = (cr(0), cr(1));
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
            let fa = _mm256_sub_pd(
                va0,
                _mm256_mul_pd(
                    vc,
                    _mm256_add_pd(
                        _mm256_sub_pd(f, _mm256_mul_pd(df, step)),
                        _mm256_mul_pd(ddf, h),
                    ),
                ),
            );
            let fb = _mm256_sub_pd(
                vb0,
                _mm256_mul_pd(
                    c2,
                    _mm256_add_pd(
                        _mm256_sub_pd(t, _mm256_mul_pd(dt, step)),
                        _mm256_mul_pd(ddt, h),
                    ),
                ),
            );
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
    }
    let (mut xa, mut xb) = ([0.0; 4], [0.0; 4]);
    _mm256_storeu_pd(xa.as_mut_ptr(), ra);
    _mm256_storeu_pd(xb.as_mut_ptr(), rb);
    let ok = _mm256_movemask_pd(ok);
    for (l, o) in out.iter_mut().enumerate() {
        *o = (ok >> l & 1 == 1).then_some((xa[l], xb[l]));
    }
}
