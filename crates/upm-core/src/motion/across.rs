//! The plate velocity of several motions of one timing side by side. A batch's small worlds run
//! in one register tile (`sim::group`), each vector under its own world's velocity; they read it
//! from one table whose rows (one a step and component) hold every world's value next to the
//! others. Each value is the one [`Phases::extend_steps`] gives its motion, to the bit (the same
//! operations in the same order), but where the motions' segments are alike (jets; harmonic
//! drives of as many harmonics: the planner's rollouts) eight motions are evaluated at once, in
//! one vector, instead of one after another (a table a world cost a tenth of a batch's time).

use std::ops::Range;

use super::{about, along, jet, At, Phases, Sample, Stint, Stretch};
use crate::motion::{PlateMotion, Segment};
use crate::waveform::{Harmonics, Waveform};

/// Motions evaluated together (one AVX-512 vector).
const LANES: usize = 8;

/// Harmonic drives with more harmonics than this are evaluated motion by motion.
const MAX_HARMONICS: usize = 8;

/// A table of `width` columns laid out step by step: component `c` of column `w` at the table's
/// `k`-th step is `values[(3 k + c) width + w]`.
pub(crate) struct Columns<'a> {
    pub values: &'a mut [f64],
    pub width: usize,
}

impl Columns<'_> {
    /// Writes `u(p)` for each of `samples` into the rows from `at.row` (one a sample) of the
    /// columns `at.col ..`, the first `n` lanes of each component.
    #[inline(always)]
    fn fill(
        &mut self,
        at: Place,
        n: usize,
        samples: &[Sample],
        u: impl Fn(&Sample) -> [[f64; LANES]; 3],
    ) {
        if samples.is_empty() {
            return;
        }
        let width = self.width;
        // one past the last value written (component 2 of the last row, column at.col + n - 1)
        let end = (3 * (at.row + samples.len()) - 1) * width + at.col + n;
        assert!(
            n <= LANES && at.col + n <= width && end <= self.values.len(),
            "{n} columns from {} of {} rows from {} in a table of {} values",
            at.col,
            samples.len(),
            at.row,
            self.values.len()
        );
        let values = self.values.as_mut_ptr();
        let row = |r: usize| 3 * (at.row + r) * width + at.col;
        if n == LANES {
            // (a vector's store a component)
            for (r, p) in samples.iter().enumerate() {
                let [u1, u2, u3] = u(p);
                // SAFETY: below `end` (checked above).
                unsafe {
                    let o = values.add(row(r));
                    o.cast::<[f64; LANES]>().write_unaligned(u1);
                    o.add(width).cast::<[f64; LANES]>().write_unaligned(u2);
                    o.add(2 * width).cast::<[f64; LANES]>().write_unaligned(u3);
                }
            }
            return;
        }
        for (r, p) in samples.iter().enumerate() {
            for (c, u) in u(p).iter().enumerate() {
                for (k, &v) in u.iter().enumerate().take(n) {
                    // SAFETY: below `end` (checked above).
                    unsafe { values.add(row(r) + c * width + k).write(v) };
                }
            }
        }
    }
}

impl Phases {
    /// The velocity of each of `motions` (of the timing these samples were taken for) at every
    /// step of `steps` (within the block), motion `j` in column `col + j` of `out`, whose first
    /// row is `steps.start`. Bitwise [`Phases::extend_steps`] of each motion.
    pub(crate) fn extend_across(
        &self,
        motions: &[&PlateMotion],
        steps: Range<usize>,
        out: &mut Columns,
        col: usize,
    ) {
        assert!(
            self.steps.start <= steps.start && steps.end <= self.steps.end,
            "steps {steps:?} outside the block {:?}",
            self.steps
        );
        assert!(
            col + motions.len() <= out.width && out.values.len() >= 3 * out.width * steps.len(),
            "columns {col}.. of {} motions outside a table of {} columns and {} values",
            motions.len(),
            out.width,
            out.values.len()
        );
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            /// The same loops with 8-wide vectors: the same operations, so the same bits.
            #[target_feature(enable = "avx512f")]
            unsafe fn wide(
                p: &Phases,
                m: &[&PlateMotion],
                s: Range<usize>,
                o: &mut Columns,
                col: usize,
            ) {
                p.across_with(m, s, o, col);
            }
            // SAFETY: the CPU has AVX-512F (checked just above).
            return unsafe { wide(self, motions, steps, out, col) };
        }
        self.across_with(motions, steps, out, col);
    }

    #[inline(always)]
    fn across_with(
        &self,
        motions: &[&PlateMotion],
        steps: Range<usize>,
        out: &mut Columns,
        col: usize,
    ) {
        for (st, first, samples) in self.pieces(steps.clone()) {
            for (k, some) in motions.chunks(LANES).enumerate() {
                let at = Place {
                    row: first - steps.start,
                    col: col + k * LANES,
                    first,
                };
                stint(st, some, samples, out, at);
            }
        }
    }
}

/// Where a stint's values go: its first row and column in the table, and its first step.
#[derive(Clone, Copy)]
struct Place {
    row: usize,
    col: usize,
    first: usize,
}

/// The values of `motions` (at most [`LANES`]) over `samples`, the steps of `st` from `at.first`.
#[inline(always)]
fn stint(st: &Stint, motions: &[&PlateMotion], samples: &[Sample], out: &mut Columns, at: Place) {
    let n = motions.len();
    let segment = |j: usize| &motions[j].items[st.item].segment;
    if st.stretch == Stretch::Off {
        out.fill(at, n, samples, |_| [[0.0; LANES]; 3]);
        return;
    }
    if let Some([k, ax, ay, cx, cy]) = jets(motions, st.item) {
        out.fill(at, n, samples, |p| {
            // (a component at a time: each a plain loop over the lanes, one vector's work)
            let u = |j: usize| jet(&[cx[j], cy[j]], (ax[j], ay[j]), p.feed, k[j] * p.spin);
            std::array::from_fn(|c| std::array::from_fn(|j| u(j)[c]))
        });
        return;
    }
    if let Some(d) = Drives::of(motions, st.item) {
        out.fill(at, n, samples, |p| d.velocity(p));
        return;
    }
    // Anything else motion by motion, as `Phases::extend_steps` takes it.
    let mut one = Vec::with_capacity(samples.len());
    for j in 0..n {
        one.clear();
        let first = At {
            first: at.first,
            ..st.at
        };
        first.extend(segment(j), st.stretch, samples, &mut one);
        for (r, u) in one.iter().enumerate() {
            for (c, &v) in u.iter().enumerate() {
                out.values[(3 * (at.row + r) + c) * out.width + at.col + j] = v;
            }
        }
    }
}

/// The coefficients of item `item` of `motions` (at most [`LANES`]) if every one is a jet, lane
/// by lane (zero past the motions): `k = 2A/rho`, `A d` and the focus `c`, as `At::extend` takes
/// them; a jet's velocity at a sample `p` is then `[ax g + w cy, ay g - w cx, w]` with
/// `g = p.feed` and `w = k p.spin` ([`jet`]).
pub(crate) fn jets(motions: &[&PlateMotion], item: usize) -> Option<[[f64; LANES]; 5]> {
    let [mut k, mut ax, mut ay, mut cx, mut cy] = [[0.0; LANES]; 5];
    for (j, m) in motions.iter().enumerate().take(LANES) {
        let Segment::Jet {
            center,
            direction,
            rho,
            amplitude,
            ..
        } = &m.items[item].segment
        else {
            return None;
        };
        k[j] = 2.0 * amplitude / rho;
        (ax[j], ay[j]) = (amplitude * direction[0], amplitude * direction[1]);
        [cx[j], cy[j]] = *center;
    }
    Some([k, ax, ay, cx, cy])
}

/// A stint of a piece of steps (see [`Phases::jets`]): its steps, each step's sample, and if
/// every motion plays a jet in it, the jets' coefficients ([`jets`]) of each set of eight
/// motions in turn.
pub(crate) struct JetStint<'a> {
    pub steps: Range<usize>,
    pub samples: &'a [Sample],
    pub coef: Option<Vec<[[f64; LANES]; 5]>>,
}

impl Phases {
    /// The stints of `steps` (within the block) for `motions` (of the timing these samples were
    /// taken for), in order: in those where every motion plays a jet (and the plate does not
    /// rest), what a kernel that evaluates the jets itself needs to give each lane the velocity
    /// [`Phases::extend_across`] tabulates, to the bit; no coefficients in the others.
    pub(crate) fn jets(&self, motions: &[&PlateMotion], steps: Range<usize>) -> Vec<JetStint<'_>> {
        assert!(
            self.steps.start <= steps.start && steps.end <= self.steps.end,
            "steps {steps:?} outside the block {:?}",
            self.steps,
        );
        self.pieces(steps)
            .map(|(st, first, samples)| {
                let coef = (st.stretch != Stretch::Off).then(|| {
                    let sets = motions.chunks(LANES).map(|set| jets(set, st.item));
                    sets.collect::<Option<_>>()
                });
                JetStint {
                    steps: first..first + samples.len(),
                    samples,
                    coef: coef.flatten(),
                }
            })
            .collect()
    }
}

/// Harmonic drives of up to [`LANES`] motions, all translations or all rotations, with as many
/// harmonics each: their coefficients side by side.
struct Drives {
    rotation: bool,
    harmonics: usize,
    /// The cosine and sine coefficients of harmonic `i` of every motion.
    cos: [[f64; LANES]; MAX_HARMONICS],
    sin: [[f64; LANES]; MAX_HARMONICS],
    scale: [f64; LANES],
    /// A rotation's centre, or a translation's direction.
    point: [[f64; LANES]; 2],
}

impl Drives {
    /// The drives of item `item` of `motions`, if they are alike.
    #[inline(always)]
    fn of(motions: &[&PlateMotion], item: usize) -> Option<Self> {
        fn drive(m: &PlateMotion, item: usize) -> Option<(bool, [f64; 2], &Harmonics)> {
            match &m.items[item].segment {
                Segment::Rotation {
                    center,
                    wave: Waveform::Harmonics(h),
                } => Some((true, *center, h)),
                Segment::Translation {
                    direction,
                    wave: Waveform::Harmonics(h),
                } => Some((false, *direction, h)),
                _ => None,
            }
        }
        let (rotation, _, h0) = drive(motions.first()?, item)?;
        let harmonics = h0.terms().0.len();
        if harmonics > MAX_HARMONICS {
            return None;
        }
        let mut d = Drives {
            rotation,
            harmonics,
            cos: [[0.0; LANES]; MAX_HARMONICS],
            sin: [[0.0; LANES]; MAX_HARMONICS],
            scale: [0.0; LANES],
            point: [[0.0; LANES]; 2],
        };
        for (j, m) in motions.iter().enumerate() {
            let (rot, point, h) = drive(m, item)?;
            let (cos, sin) = h.terms();
            if rot != rotation || cos.len() != harmonics || sin.len() != harmonics {
                return None;
            }
            for i in 0..harmonics {
                (d.cos[i][j], d.sin[i][j]) = (cos[i], sin[i]);
            }
            d.scale[j] = h.omega_scale().1;
            (d.point[0][j], d.point[1][j]) = (point[0], point[1]);
        }
        Some(d)
    }

    /// Every motion's velocity at the sample `p`: `Harmonics::value_of` summed in its order,
    /// the harmonics' phasors (shared) turned once for all.
    #[inline(always)]
    fn velocity(&self, p: &Sample) -> [[f64; LANES]; 3] {
        let (c1, s1) = (p.c, p.s);
        let (mut c, mut s) = (c1, s1);
        let mut v = [0.0; LANES];
        for (a, b) in self.cos.iter().zip(&self.sin).take(self.harmonics) {
            for ((v, a), b) in v.iter_mut().zip(a).zip(b) {
                *v += a * c + b * s;
            }
            let cn = c * c1 - s * s1;
            s = s * c1 + c * s1;
            c = cn;
        }
        let u = |j: usize| {
            let w = self.scale[j] * v[j] * p.env;
            let point = [self.point[0][j], self.point[1][j]];
            if self.rotation {
                about(&point, w)
            } else {
                along(&point, w)
            }
        };
        std::array::from_fn(|c| std::array::from_fn(|j| u(j)[c]))
    }
}
