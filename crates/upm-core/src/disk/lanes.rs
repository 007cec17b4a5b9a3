//! The disks' sliding solve ([`super::slide`]) for many disks at once: [`slide_many`] runs
//! `LANES` independent disks' Halley iterations side by side, so that their long dependency
//! chains (table look-up, cubic, two divisions: about 70 cycles a step) overlap instead of
//! running one after another. Each disk's arithmetic is exactly that of the one-disk solve, so
//! the results are bitwise the same, whatever the grouping.

use super::{halley, ztable, ztable_padded, Halley, HALLEY_STEPS};
use crate::simd::Simd;

/// Disks solved side by side.
pub const LANES: usize = 8;

/// [`super::slide`]'s Halley stage for the disks `(a0[k], b0[k])` with `c[k] = mu g dt`: `out[k]`
/// is `Some((|w'|, R |W'|))`, or `None` where it does not settle (the caller then takes
/// [`super::slide_safe`]). The slices have one length.
pub fn slide_many(a0: &[f64], b0: &[f64], c: &[f64], out: &mut [Option<(f64, f64)>]) {
    let n = a0.len();
    assert!(
        b0.len() == n && c.len() == n && out.len() == n,
        "slide_many: slices of unequal length"
    );
    let tab = ztable();
    let wide = wide();
    // (the AVX2 build takes up to eight vectors of four side by side)
    let width = match wide {
        #[cfg(target_arch = "x86_64")]
        Simd::Avx2 => 4 * super::avx2::VECTORS,
        _ => LANES,
    };
    for k in (0..n).step_by(width) {
        let m = width.min(n - k);
        let r = k..k + m;
        let (a0, b0, c, out) = (&a0[r.clone()], &b0[r.clone()], &c[r.clone()], &mut out[r]);
        match wide {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `wide` is Avx512 only where the CPU has AVX-512F (and so AVX2); m <= 8.
            Simd::Avx512 => unsafe { super::avx512::lockstep(tab, a0, b0, c, out) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `wide` is Avx2 only where the CPU has AVX2; m <= 32.
            Simd::Avx2 => unsafe { super::avx2::lockstep(ztable_padded(), a0, b0, c, out) },
            _ => lockstep(tab, a0, b0, c, out),
        }
    }
}

/// The build [`slide_many`] takes: the kernel's ([`crate::simd::simd`]).
fn wide() -> Simd {
    crate::simd::simd()
}

/// Up to [`LANES`] disks' Halley iterations in lockstep: each round advances every disk still
/// iterating by one step.
#[inline(always)]
fn lockstep(tab: &[[f64; 2]], a0: &[f64], b0: &[f64], c: &[f64], out: &mut [Option<(f64, f64)>]) {
    let m = a0.len();
    let mut z = [0.0; LANES];
    let mut live = [false; LANES];
    for l in 0..m {
        z[l] = b0[l] / (a0[l] + b0[l]);
        live[l] = true;
        out[l] = None;
    }
    for _ in 0..HALLEY_STEPS {
        let mut any = false;
        for l in 0..m {
            if !live[l] {
                continue;
            }
            match halley(tab, a0[l], b0[l], c[l], z[l]) {
                Halley::Next(next) => {
                    z[l] = next;
                    any = true;
                }
                Halley::Done(ab) => {
                    out[l] = ab;
                    live[l] = false;
                }
            }
        }
        if !any {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn many_disks_at_once_are_bitwise_the_one_disk_solve() {
        // States from fast sliding to nearly stopped (where the Halley stage gives up), in groups
        // that do not fill the lanes; the last 40 nearly pure sliding or nearly pure spinning,
        // so that the solve reads the z table's first and last rows.
        let c0 = 0.002;
        let n = 243;
        let (mut a0, mut b0, mut c) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            let spread = |k: usize| 10f64.powf(-0.3 + 3.0 * ((i * k) % 203) as f64 / 203.0);
            (a0[i], b0[i]) = (c0 * spread(37), c0 * spread(91));
            if i >= 203 {
                let tiny = 10f64.powf(-9.0 + 0.2 * (i % 20) as f64);
                let (big, small) = (c0 * (5.0 + (i % 7) as f64), c0 * tiny);
                (a0[i], b0[i]) = if i % 2 == 0 {
                    (big, small)
                } else {
                    (small, big)
                };
            }
            c[i] = c0 * (1.0 + 0.5 * ((i * 13) % 7) as f64 / 7.0);
        }
        let bits = |o: &[Option<(f64, f64)>]| -> Vec<_> {
            o.iter()
                .map(|x| x.map(|(a, b)| (a.to_bits(), b.to_bits())))
                .collect()
        };
        let one: Vec<_> = (0..n)
            .map(|i| super::super::slide_newton(a0[i], b0[i], c[i]))
            .collect();
        // The chosen build, then each build this CPU has, in groups of eight and fewer.
        let mut out = vec![None; n];
        slide_many(&a0, &b0, &c, &mut out);
        assert_eq!(bits(&out), bits(&one), "slide_many");
        let tab = ztable();
        for k in (0..n).step_by(LANES) {
            let r = k..(k + LANES).min(n);
            let (a, b, cc) = (&a0[r.clone()], &b0[r.clone()], &c[r.clone()]);
            let mut o = vec![Some((0.0, 0.0)); r.len()];
            lockstep(tab, a, b, cc, &mut o);
            assert_eq!(bits(&o), bits(&one[r.clone()]), "portable, disks {r:?}");
            #[cfg(target_arch = "x86_64")]
            if is_x86_feature_detected!("avx512f") {
                let mut o = vec![Some((0.0, 0.0)); r.len()];
                // SAFETY: the CPU has AVX-512F (and so AVX2); at most eight disks.
                unsafe { super::super::avx512::lockstep(tab, a, b, cc, &mut o) };
                assert_eq!(bits(&o), bits(&one[r.clone()]), "avx512, disks {r:?}");
            }
        }
        // The AVX2 build, up to 32 disks at a time, in groups that end in every lane.
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            for width in [1, 3, 4, 7, 8, 17, 32] {
                for k in (0..n).step_by(width) {
                    let r = k..(k + width).min(n);
                    let (a, b, cc) = (&a0[r.clone()], &b0[r.clone()], &c[r.clone()]);
                    let mut o = vec![Some((0.0, 0.0)); r.len()];
                    // SAFETY: the CPU has AVX2; at most 32 disks.
                    unsafe { super::super::avx2::lockstep(ztable_padded(), a, b, cc, &mut o) };
                    assert_eq!(bits(&o), bits(&one[r.clone()]), "avx2, disks {r:?}");
                }
            }
        }
        let settled = one.iter().filter(|o| o.is_some()).count();
        let failed = n - settled;
        assert!(
            settled > 150 && failed > 0,
            "settled {settled}, failed {failed}"
        );
    }
}
