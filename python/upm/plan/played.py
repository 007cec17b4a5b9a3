"""A pulse as the drive plays it: the board envelopes each motor's *force*, not the plate's velocity.

:meth:`upm.plate.pulses.Pulse.motion` is the plate velocity the pulse asks for, every harmonic
under the raised-cosine envelope. The board multiplies the motors' forces by that envelope, and the
plate answers through its suspension (:meth:`upm.plate.drive.DriveLimits.respond`, the plant's own
model): on the ramps its velocity is not the enveloped one (on a free plate it is ``e u - integral
of e' u``, and the flexures then pull on the drift). Rotations and translations barely notice; a
jet's large 2f/3 rotation term sweeps the parts far from its focus in constant slip, and the ramps'
slight asymmetry feeds them millimetres that ``Pulse.motion()`` says they do not move
(``bench/prediction.py``: 4.9 mm median error for 6.9 mm moves on the plant, 0.4 mm on an ideal
plate; 0.5 mm on the plant with this correction).

:func:`drive_shift` is the difference, for point parts: where each part ends under the plate's
velocity as the drive plays the pulse (sampled at the board's rate, from the plate's present state)
less where it ends under ``Pulse.motion()``, both at the samples' step. The predictive planner adds
it to where it expects a pulse planned afresh to leave the parts (``PredictivePlanner(drive=True)``):
the tracker's guide, and the layout a plan made ahead starts from and is held against (a plan made
ahead and kept is expected by the planner's own model, restarted where the parts are seen). It does not
choose by it: the ranking of every candidate would need the drive's correction inside the core's
motion (a sampled motion needs ten integrator steps a sample), and the few re-ranked candidates
alone chose worse (sort32 4/5 against 5/5).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..physics.motion import PlateMotion
from ..physics.sim import simulate_batch
from ..plate.drive import DriveLimits, envelope
from ..plate.pulses import Pulse
from .sizing import slide_to_rest

__all__ = ["RATE", "as_played", "drive_shift", "drive_velocity"]

FloatArray = NDArray[np.float64]

#: Samples per second of the drive's forces: the board's rate (``SimulatedUPM.sample_rate``).
RATE = 5000.0

#: The kinds of pulse the four motors play (a 6-DOF field pulse is not theirs).
PLAYED = ("translation", "rotation", "jet")


def drive_velocity(
    limits: DriveLimits, pulse: Pulse, state: Any = None, rate: float = RATE
) -> tuple[FloatArray, FloatArray]:
    """Times ``(T,)`` [s] and the plate's velocity ``(T, 3)`` while the motors play ``pulse`` with
    their forces enveloped (the board's way), from the plate's ``state`` ``(3, 2)`` (per axis
    position, velocity; default at rest at home): what :class:`upm.plate.plant.SimulatedUPM` does
    with the pulse's channels."""
    channels = pulse.channels(limits.plate, limits.axes, limits.force)
    t = np.arange(max(round(pulse.on_time * rate), 2)) / rate
    forces = np.stack([c.force(t) for c in channels], axis=1)
    forces *= envelope(t, pulse.attack, pulse.sustain, pulse.decay)[:, None]
    _, vel, _, _ = limits.respond_motors(forces, 1.0 / rate, state)
    return t, vel


def drive_shift(
    limits: DriveLimits,
    pulses: Sequence[Pulse],
    positions: FloatArray,
    *,
    mu: Any,
    mu_s: Any = None,
    state: Any = None,
    rate: float = RATE,
) -> FloatArray:
    """``(K, M, 2)``: where point parts at ``positions (M, 2)`` end (slid to rest) as the drive
    plays each pulse, less where they end under ``Pulse.motion()``; zero for pulses the motors do
    not play (a field) and for parts that leave the plate under either."""
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    out = np.zeros((len(pulses), len(pos), 2))
    todo = [k for k, p in enumerate(pulses) if p.kind in PLAYED]
    if not todo or not len(pos):
        return out
    dt = 1.0 / (21.0 * 0.5 * rate)  # the integrator's 20 steps per period of the samples' Nyquist rate
    finals = []
    for motions in (
        [
            PlateMotion.from_samples(t, *v.T)
            for t, v in (drive_velocity(limits, pulses[k], state, rate) for k in todo)
        ],
        [pulses[k].motion(rest=False) for k in todo],
    ):
        durations = [float(m.duration or 0.0) for m in motions]
        run = simulate_batch(motions, pos, duration=max(durations), dt=dt, mu=mu, mu_s=mu_s,
                             record_every=2**40)  # fmt: skip
        at_rest, _ = slide_to_rest(run.positions[:, -1], run.velocities[:, -1], mu)
        finals.append(at_rest)
    shift = finals[0] - finals[1]
    out[todo] = np.where(np.isfinite(shift), shift, 0.0)
    return out


def as_played(planner: Any, pulse: Pulse, positions: FloatArray, final: Any) -> FloatArray:
    """Where ``planner`` (a :class:`~upm.plan.PredictivePlanner`) predicted ``pulse`` leaves the
    parts at ``positions``, ``final``, plus :func:`drive_shift` by its limits, friction estimate
    and plate state when its ``drive`` is on."""
    out = np.array(final, dtype=np.float64)
    if planner.drive:
        mu = planner.mu_estimate
        out += drive_shift(planner.limits, [pulse], positions, mu=mu, mu_s=mu * planner._static,
                           state=planner._plate)[0]  # fmt: skip
    return out
