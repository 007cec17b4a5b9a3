//! The state arrays of a chunk of point parts, as the kernels address them: their order
//! ([`ARRAYS`]) and their base addresses shared by the chunk tasks ([`Base`]).

use super::kernel::Lanes;
use super::lift::Air;

/// The arrays of the state, in the order of [`Points::arrays`]: x, y, vx, vy, stuck, active,
/// left (steps done when the part left the plate, [`NEVER`](super::kernel::NEVER) while on it), slide (`mu g dt`),
/// hold (`mu_s g dt`), and on a plate that moves out of its plane the height above the plate,
/// its rate and the steps spent in flight.
pub(super) const ARRAYS: usize = 12;
pub(super) const PLANAR: usize = 9;
/// The stuck flags' array among them.
pub(super) const STUCK: usize = 4;
/// The `slide` array among them (`hold` follows it).
pub(super) const SLIDE: usize = 7;

/// The arrays' base addresses, shared by the chunk tasks (each reads and writes only its own
/// range).
#[derive(Clone, Copy)]
pub(super) struct Base(pub(super) [*mut f64; ARRAYS]);

// SAFETY: the chunk tasks address disjoint ranges of the arrays, which outlive them.
unsafe impl Send for Base {}
unsafe impl Sync for Base {}

impl Base {
    /// A chunk's own buffer (or a group's, of `N` lanes).
    pub(super) fn local<const N: usize>(local: &mut [[f64; N]; ARRAYS]) -> Self {
        Base(std::array::from_fn(|i| local[i].as_mut_ptr()))
    }

    /// A group's buffer (`sim::group`): [`PLANAR`] arrays of `lanes` lanes each, one after the
    /// other (a group's points stay on the plane: the arrays of the air point nowhere, and
    /// [`Base::chunk`] must not be asked for them).
    pub(super) fn planar(buf: &mut [f64], lanes: usize) -> Self {
        assert!(
            buf.len() >= PLANAR * lanes,
            "a buffer of {PLANAR} x {lanes} lanes"
        );
        let p = buf.as_mut_ptr();
        // SAFETY: within the buffer (checked).
        Base(std::array::from_fn(|i| {
            if i < PLANAR {
                unsafe { p.add(i * lanes) }
            } else {
                std::ptr::null_mut()
            }
        }))
    }

    /// The lanes (and air state) of the `k` points from `at` on.
    ///
    /// # Safety
    /// The range is within every array's capacity and initialised, and no other live borrow
    /// overlaps it.
    pub(super) unsafe fn chunk<'c>(
        &self,
        at: usize,
        k: usize,
        spatial: bool,
    ) -> (Lanes<'c>, Option<Air<'c>>) {
        let a = |i: usize| std::slice::from_raw_parts_mut(self.0[i].add(at), k);
        let lanes = Lanes {
            x: a(0),
            y: a(1),
            vx: a(2),
            vy: a(3),
            stuck: a(4),
            active: a(5),
            left: a(6),
            slide: a(7),
            hold: a(8),
            kick: [0.0; 2],
        };
        let air = spatial.then(|| Air {
            h: a(9),
            hv: a(10),
            flight: a(11),
        });
        (lanes, air)
    }
}
