//! The AVX-512 build of [`super::lanes`]' lockstep: eight disks per instruction, the table read
//! by gathers, each lane's exits kept in masks. Every lane does exactly the one-disk solve's
//! arithmetic ([`super::halley`]: the same operations in the same order, no fused multiply–add),
//! so the results are bitwise those of the portable lockstep.

use std::arch::x86_64::*;

use super::{HALLEY_STEPS, ZTABLE};

/// Lanes `0..k` of eight.
fn first_lanes(k: usize) -> __mmask8 {
    if k >= 8 {
        0xff
    } else {
        ((1u16 << k) - 1) as __mmask8
    }
}

/// Up to eight disks (`a0.len() <= 8`) through [`super::slide_newton`], side by side.
///
/// # Safety
/// The CPU must support AVX-512F and AVX2; `tab` is the z table.
#[target_feature(enable = "avx512f,avx2")]
pub(super) unsafe fn lockstep(
    tab: &[[f64; 2]],
    a0: &[f64],
    b0: &[f64],
    c: &[f64],
    out: &mut [Option<(f64, f64)>],
) {
    let m = a0.len();
    debug_assert!(m <= 8 && b0.len() == m && c.len() == m && out.len() == m);
    debug_assert_eq!(tab.len(), ZTABLE);
    let base = tab.as_ptr() as *const f64;
    let lanes = first_lanes(m);
    let set = _mm512_set1_pd;
    let (zero, one) = (set(0.0), set(1.0));
    let va0 = _mm512_maskz_loadu_pd(lanes, a0.as_ptr());
    let vb0 = _mm512_maskz_loadu_pd(lanes, b0.as_ptr());
    let vc = _mm512_maskz_loadu_pd(lanes, c.as_ptr());
    let c2 = _mm512_mul_pd(set(2.0), vc);
    let c4 = _mm512_mul_pd(set(4.0), vc);
    let scale = set((ZTABLE - 1) as f64);
    let (last, top) = (
        _mm256_set1_epi32(ZTABLE as i32 - 2),
        _mm256_set1_epi32(ZTABLE as i32 - 1),
    );
    // Padding lanes: z = 0 and never live (their gathers read nothing).
    let mut z = _mm512_maskz_div_pd(lanes, vb0, _mm512_add_pd(va0, vb0));
    let mut live = lanes;
    let (mut ok, mut ra, mut rb): (__mmask8, _, _) = (0, zero, zero);
    for _ in 0..HALLEY_STEPS {
        if live == 0 {
            break;
        }
        // The table's cubic at z (super::curve_z).
        let u = _mm512_mul_pd(_mm512_min_pd(_mm512_max_pd(z, zero), one), scale);
        let i = _mm256_min_epi32(_mm512_cvttpd_epi32(u), last);
        let s = _mm512_sub_pd(u, _mm512_cvtepi32_pd(i));
        let k1 = _mm256_set1_epi32(1);
        let idx = [
            _mm256_max_epi32(_mm256_sub_epi32(i, k1), _mm256_setzero_si256()),
            i,
            _mm256_add_epi32(i, k1),
            _mm256_min_epi32(_mm256_add_epi32(i, _mm256_set1_epi32(2)), top),
        ];
        let gather = |k: __m256i, col: i32| {
            let off = _mm256_add_epi32(_mm256_slli_epi32::<1>(k), _mm256_set1_epi32(col));
            _mm512_mask_i32gather_pd::<8>(zero, live, off, base)
        };
        let cr = |col: i32| {
            let (a, b, cc, d) = (
                gather(idx[0], col),
                gather(idx[1], col),
                gather(idx[2], col),
                gather(idx[3], col),
            );
            let c1 = _mm512_mul_pd(set(0.5), _mm512_sub_pd(cc, a));
            let c2 = _mm512_sub_pd(
                _mm512_add_pd(
                    _mm512_sub_pd(a, _mm512_mul_pd(set(2.5), b)),
                    _mm512_mul_pd(set(2.0), cc),
                ),
                _mm512_mul_pd(set(0.5), d),
            );
            let c3 = _mm512_add_pd(
                _mm512_mul_pd(set(1.5), _mm512_sub_pd(b, cc)),
                _mm512_mul_pd(set(0.5), _mm512_sub_pd(d, a)),
            );
            let v0 = _mm512_add_pd(
                b,
                _mm512_mul_pd(
                    s,
                    _mm512_add_pd(
                        c1,
                        _mm512_mul_pd(s, _mm512_add_pd(c2, _mm512_mul_pd(s, c3))),
                    ),
                ),
            );
            let v1 = _mm512_mul_pd(
                _mm512_add_pd(
                    c1,
                    _mm512_mul_pd(
                        s,
                        _mm512_add_pd(
                            _mm512_mul_pd(set(2.0), c2),
                            _mm512_mul_pd(_mm512_mul_pd(set(3.0), s), c3),
                        ),
                    ),
                ),
                scale,
            );
            let v2 = _mm512_mul_pd(
                _mm512_mul_pd(
                    _mm512_add_pd(
                        _mm512_mul_pd(set(2.0), c2),
                        _mm512_mul_pd(_mm512_mul_pd(set(6.0), s), c3),
                    ),
                    scale,
                ),
                scale,
            );
            (v0, v1, v2)
        };
        let ((f, df, ddf), (t, dt, ddt)) = (cr(0), cr(1));
        // One Halley step (super::halley).
        let a = _mm512_sub_pd(va0, _mm512_mul_pd(vc, f));
        let b = _mm512_sub_pd(vb0, _mm512_mul_pd(c2, t));
        let omz = _mm512_sub_pd(one, z);
        let cz = _mm512_mul_pd(vc, z);
        let c2omz = _mm512_mul_pd(c2, omz);
        let r = _mm512_sub_pd(_mm512_mul_pd(omz, b), _mm512_mul_pd(z, a));
        // -b, as Rust's negation: the sign bit flipped.
        let neg_b = _mm512_castsi512_pd(_mm512_xor_si512(
            _mm512_castpd_si512(b),
            _mm512_set1_epi64(i64::MIN),
        ));
        let dr = _mm512_add_pd(
            _mm512_sub_pd(_mm512_sub_pd(neg_b, a), _mm512_mul_pd(c2omz, dt)),
            _mm512_mul_pd(cz, df),
        );
        let ddr = _mm512_add_pd(
            _mm512_sub_pd(
                _mm512_add_pd(_mm512_mul_pd(c4, dt), _mm512_mul_pd(c2, df)),
                _mm512_mul_pd(c2omz, ddt),
            ),
            _mm512_mul_pd(cz, ddf),
        );
        // dr NaN or >= 0: not sliding as assumed.
        live &= !_mm512_cmp_pd_mask::<_CMP_NLT_UQ>(dr, zero);
        let newton = _mm512_div_pd(r, dr);
        let step = _mm512_div_pd(
            newton,
            _mm512_sub_pd(
                one,
                _mm512_div_pd(_mm512_mul_pd(_mm512_mul_pd(set(0.5), newton), ddr), dr),
            ),
        );
        let next = _mm512_sub_pd(z, step);
        live &= _mm512_cmp_pd_mask::<_CMP_GE_OQ>(next, zero)
            & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(next, one);
        let settled = live & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(_mm512_abs_pd(step), set(1e-6));
        if settled != 0 {
            let h = _mm512_mul_pd(_mm512_mul_pd(set(0.5), step), step);
            let fa = _mm512_sub_pd(
                va0,
                _mm512_mul_pd(
                    vc,
                    _mm512_add_pd(
                        _mm512_sub_pd(f, _mm512_mul_pd(df, step)),
                        _mm512_mul_pd(ddf, h),
                    ),
                ),
            );
            let fb = _mm512_sub_pd(
                vb0,
                _mm512_mul_pd(
                    c2,
                    _mm512_add_pd(
                        _mm512_sub_pd(t, _mm512_mul_pd(dt, step)),
                        _mm512_mul_pd(ddt, h),
                    ),
                ),
            );
            ok |= settled
                & _mm512_cmp_pd_mask::<_CMP_GT_OQ>(fa, zero)
                & _mm512_cmp_pd_mask::<_CMP_GT_OQ>(fb, zero);
            ra = _mm512_mask_mov_pd(ra, settled, fa);
            rb = _mm512_mask_mov_pd(rb, settled, fb);
            live &= !settled;
        }
        z = _mm512_mask_mov_pd(z, live, next);
    }
    let (mut xa, mut xb) = ([0.0; 8], [0.0; 8]);
    _mm512_storeu_pd(xa.as_mut_ptr(), ra);
    _mm512_storeu_pd(xb.as_mut_ptr(), rb);
    for (l, o) in out.iter_mut().enumerate() {
        *o = (ok >> l & 1 == 1).then_some((xa[l], xb[l]));
    }
}
