//! Pressure that varies linearly across a part's footprint, `p(r) = (N / A) (1 + k . r)` with
//! `r` from the centroid: the load of a part on a plate that rocks (docs/spec.md §10, each
//! element pressed by `g + a_z` where it lies, `k` the gradient of `a_z` over `g + a_z` at the
//! centroid). `∫ p dA = N` still, since `∫ r dA = 0` about the centroid.
//!
//! About the instantaneous centre `r0`, with `d = r - r0`, `rho = |d|`, the weight is
//! `w = w0 + k . d`, `w0 = 1 + k . r0`, and the fan's integrals gain the terms of `k . d`:
//!
//! ```text
//! ∫ w d/rho dA      = w0 ∫ d/rho dA      + (∫ d d^T / rho dA) k
//! ∫ w rho dA        = w0 ∫ rho dA        + k . ∫ d rho dA
//! ∫ w d d^T/rho³ dA = w0 ∫ d d^T/rho³ dA + ∫ (k . d) d d^T / rho³ dA
//! ```
//!
//! Each new integral has a closed form over each triangle fanning from `r0` to an edge: with the
//! edge at signed distance `h` from `r0` (unit normal `n`, direction `t`, from `t1` to `t2`
//! along it), its points are `s (h n + t tau)`, `dA = s h ds dt`, and a term homogeneous of
//! degree `m` in `d` integrates to `h / (m + 2)` times its integral along the edge; those are
//! `∫ t^j / rho^q dt` for `q = -1, 1, 3`, in `rho`, `t` and `asinh(t / |h|)`.

use super::lanes::{self, ln_1p, LANES};
use super::Polygon;

/// The terms a pressure gradient `k` adds to the fan about `r0` (module docs), unscaled by `w0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Linear {
    /// `(∫ d d^T / rho dA) k` [m⁴·k].
    pub unit: [f64; 2],
    /// `k . ∫ d rho dA`.
    pub dist: f64,
    /// `∫ (k . d) d d^T / rho³ dA` as `(xx, xy, yy)` (zero unless asked for).
    pub curvature: [f64; 3],
}

/// One third (a product with it costs less than a division by 3).
const THIRD: f64 = 1.0 / 3.0;

/// The terms of the gradient `k` about `r0` (relative to the centroid); the curvature's only if
/// `CURVATURE`. Each edge's directions and length come from the fan's lanes ([`lanes::Edges`]),
/// and its differences between the ends (`rho`, `t rho`, `rho³`, `asinh(t / |h|)`) are formed
/// without cancellation, as the fan forms them.
pub(super) fn linear<const CURVATURE: bool>(p: &Polygon, r0: [f64; 2], k: [f64; 2]) -> Linear {
    let mut out = Linear::default();
    for e in &p.lanes {
        for l in (0..LANES).filter(|&l| e.live[l]) {
            let a = [e.ax[l] - r0[0], e.ay[l] - r0[1]];
            let b = [e.bx[l] - r0[0], e.by[l] - r0[1]];
            let (tau, len) = ([e.ex[l], e.ey[l]], e.len[l]);
            // the right normal: outward for a counter-clockwise outline
            let nrm = [tau[1], -tau[0]];
            let h = a[0] * nrm[0] + a[1] * nrm[1];
            if h == 0.0 {
                continue; // r0 on the edge's line: the triangle has no area
            }
            let t1 = a[0] * tau[0] + a[1] * tau[1];
            let t2 = t1 + len;
            let r1 = (a[0] * a[0] + a[1] * a[1]).sqrt();
            let r2 = (b[0] * b[0] + b[1] * b[1]).sqrt();
            // r2 - r1, t2 r2 - t1 r1 and asinh(t2/|h|) - asinh(t1/|h|)
            let dr = len * (t1 + t2) / (r1 + r2);
            let dtr = len * r2 + t1 * dr;
            let (a1, a2) = lanes::asinh_args(h, t1, t2, r1, r2, len, dr, false);
            let asinh = ln_1p((a1 + a2) + a1 * a2);
            let h2 = h * h;
            let (kn, kt) = (k[0] * nrm[0] + k[1] * nrm[1], k[0] * tau[0] + k[1] * tau[1]);
            // ∫ d d^T / rho dA (degree 1): h/3 ∫ (h² n n^T + h t (n tau^T + tau n^T) + t² tau tau^T) / rho
            let i2 = 0.5 * (dtr - h2 * asinh);
            let (snn, snt, stt) = (h * h2 * asinh * THIRD, h2 * dr * THIRD, h * i2 * THIRD);
            let (cn, ct) = (snn * kn + snt * kt, snt * kn + stt * kt);
            out.unit[0] += cn * nrm[0] + ct * tau[0];
            out.unit[1] += cn * nrm[1] + ct * tau[1];
            // ∫ d rho dA (degree 2): h/4 ∫ (h n + t tau) rho dt
            let j0 = 0.5 * (dtr + h2 * asinh);
            let j1 = dr * (r1 * r1 + r1 * r2 + r2 * r2) * THIRD;
            out.dist += 0.25 * h * (h * kn * j0 + kt * j1);
            if CURVATURE {
                // ∫ (k . d) d d^T / rho³ dA (degree 0): h/2 ∫ (h kn + t kt) p p^T / rho³ dt
                let inv = 1.0 / (r1 * r2);
                let q = (len * r1 - t1 * dr) * inv; // t2/r2 - t1/r1
                let k0 = q / h2;
                let k1 = dr * inv; // 1/r1 - 1/r2
                let k2 = asinh - q;
                let k3 = dr - h2 * k1;
                let cnn = 0.5 * h * (h2 * h * kn * k0 + h2 * kt * k1);
                let cnt = 0.5 * h * (h2 * kn * k1 + h * kt * k2);
                let ctt = 0.5 * h * (h * kn * k2 + kt * k3);
                out.curvature[0] +=
                    cnn * nrm[0] * nrm[0] + 2.0 * cnt * nrm[0] * tau[0] + ctt * tau[0] * tau[0];
                out.curvature[1] += cnn * nrm[0] * nrm[1]
                    + cnt * (nrm[0] * tau[1] + tau[0] * nrm[1])
                    + ctt * tau[0] * tau[1];
                out.curvature[2] +=
                    cnn * nrm[1] * nrm[1] + 2.0 * cnt * nrm[1] * tau[1] + ctt * tau[1] * tau[1];
            }
        }
    }
    out
}
