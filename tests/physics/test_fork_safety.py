"""A forked child (multiprocessing's default start method on Linux) can simulate after its parent
did: rayon's pools (the global one, and those kept for ``threads=``) do not survive fork(), so
the child must not wait on them."""

from __future__ import annotations

import multiprocessing as mp

import numpy as np

import upm


def _simulate(queue: mp.Queue) -> None:  # runs in the child
    motion = upm.PlateMotion.translation(
        (1.0, 0.0), upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.05, frequency=35)
    )
    for threads in (None, 1, 2):
        run = upm.simulate(motion, np.zeros((300, 2)), duration=0.01, dt=1e-4, mu=0.3, threads=threads)
        queue.put(float(run.positions[-1, 0, 0]))


def test_a_forked_child_simulates_after_its_parent() -> None:
    motion = upm.PlateMotion.translation(
        (1.0, 0.0), upm.TwoHarmonic(0.5, np.pi / 2, amplitude=0.05, frequency=35)
    )
    here = upm.simulate(motion, np.zeros((300, 2)), duration=0.01, dt=1e-4, mu=0.3)  # the global pool starts
    for threads in (1, 2):  # and pools of one and two threads are kept for this thread
        upm.simulate(motion, np.zeros((300, 2)), duration=0.01, dt=1e-4, mu=0.3, threads=threads)
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_simulate, args=(queue,))
    child.start()
    child.join(timeout=60)
    hung = child.is_alive()
    if hung:
        child.kill()
    assert not hung, "the forked child hung in the simulation"
    assert child.exitcode == 0
    assert [queue.get(timeout=5) for _ in range(3)] == [float(here.positions[-1, 0, 0])] * 3
