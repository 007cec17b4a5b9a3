"""Threads: identical results for any thread count, the GIL released, Ctrl-C honoured."""

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import upm

SCRIPT = """
import numpy as np, upm, sys
psi = np.linspace(-3, 3, 20011)
rates = upm.feed_rate(upm.TwoHarmonic(np.linspace(0, 2, 101)[:, None], np.linspace(-3, 3, 97)))
drive = upm.TwoHarmonic(0.5, 1.5707963, amplitude=0.05, frequency=35.0)
motion = upm.PlateMotion.rotation((0.01, 0.02), drive)
parts = np.random.default_rng(5).uniform(-0.1, 0.1, (1000, 2))
run = upm.simulate(motion, parts, duration=0.05, dt=1e-4, mu=0.3, mu_s=0.4, record_every=100)
rng = np.random.default_rng(6)
plans = upm.solve_rotations_batch(rng.uniform(-0.1, 0.1, (5000, 3, 2)), rng.normal(0, 1, (5000, 3, 2)),
                                  upm.ring_centers(8, 0.2))
sys.stdout.buffer.write(upm.force_table(2, 7, psi).tobytes() + rates.tobytes() + run.positions.tobytes()
                        + plans.strengths.tobytes())
"""


def test_bitwise_identical_for_one_and_two_threads():
    outputs = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        run = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, check=True)
        outputs.append(run.stdout)
    assert len(outputs[0]) == 8 * (20011 + 101 * 97 + 6 * 1000 * 2 + 5000 * 8)
    assert outputs[0] == outputs[1]


def test_the_gil_is_released_during_a_long_call():
    # While a worker thread is inside one long Rust call, this thread must keep running Python.
    started, progress = threading.Event(), []
    psi = np.linspace(0, 2 * np.pi, 400_000)

    def worker():
        started.set()
        upm.force_table(3, 7, psi)

    thread = threading.Thread(target=worker)
    thread.start()
    started.wait()
    for i in range(50_000):
        progress.append(i)
    still_running = thread.is_alive()
    thread.join()
    # 50 000 appends take milliseconds; the call takes far longer. Had the call held the GIL,
    # this thread could only have finished its loop after the call returned.
    assert still_running
    assert len(progress) == 50_000


def _calls_completed_before_ctrl_c(call):
    """Sends SIGINT after 0.2 s while ``call`` runs (up to three times); returns how many calls
    finished before the KeyboardInterrupt, which must come.

    Python's own SIGINT handler is installed for the duration: a process started in the background
    by a non-interactive shell inherits SIGINT ignored, and the signal would never arrive."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT))
    completed = 0
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            for _ in range(3):
                call()
                completed += 1
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    return completed


def test_ctrl_c_interrupts_a_long_call():
    psi = np.linspace(0, 2 * np.pi, 20_000_000)
    # Each call takes far longer than 0.2 s, so the interrupt must have stopped the first one.
    assert _calls_completed_before_ctrl_c(lambda: upm.force_table(2, 7, psi)) == 0


def test_ctrl_c_interrupts_a_long_simulation():
    motion = upm.PlateMotion.translation((1, 0), upm.TwoHarmonic(0.5, 1.0, amplitude=0.02, frequency=35.0))
    parts = np.zeros((20_000, 2))
    # 2e10 part-steps: minutes of work unless the interrupt stops it between blocks.
    run = lambda: upm.simulate(motion, parts, duration=70.0, dt=7e-5, mu=0.3, record_every=10**6)  # noqa: E731
    assert _calls_completed_before_ctrl_c(run) == 0


def test_ctrl_c_interrupts_a_simulation_on_its_own_pool():
    # With ``threads=`` the work runs on a pool worker, where CPython never acts on signals: the
    # calling thread has to watch for them. Uninterrupted, this call is about 4e10 part-steps
    # (over a minute of CPU time); an interrupt at 0.2 s must stop it long before. Measured in
    # this process's CPU time (the work done, not the machine's load), with a 10x margin.
    motion = upm.PlateMotion.translation((1, 0), upm.TwoHarmonic(0.5, 1.0, amplitude=0.02, frequency=35.0))
    parts = np.zeros((20_000, 2))
    run = lambda: upm.simulate_batch([motion, motion], parts, duration=70.0, dt=7e-5, mu=0.3,  # noqa: E731
                                     record_every=10**6, threads=2)  # fmt: skip
    cpu = time.process_time()
    assert _calls_completed_before_ctrl_c(run) == 0
    assert time.process_time() - cpu < 8.0


def test_ctrl_c_interrupts_a_simulation_on_one_thread():
    # One thread runs on the calling thread itself (no pool), which checks for signals between
    # blocks as the global pool's caller does.
    motion = upm.PlateMotion.translation((1, 0), upm.TwoHarmonic(0.5, 1.0, amplitude=0.02, frequency=35.0))
    parts = np.zeros((20_000, 2))
    run = lambda: upm.simulate(motion, parts, duration=70.0, dt=7e-5, mu=0.3, record_every=10**6,  # noqa: E731
                               threads=1)  # fmt: skip
    cpu = time.process_time()
    assert _calls_completed_before_ctrl_c(run) == 0
    assert time.process_time() - cpu < 8.0


OTHERS = """
import os, numpy as np, upm

def others():  # CPU ticks of every thread but this one
    ticks = 0
    for tid in os.listdir("/proc/self/task"):
        if int(tid) != os.getpid():
            with open(f"/proc/self/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            ticks += int(fields[11]) + int(fields[12])
    return ticks
"""

ONE_THREAD = """
spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
parts = [upm.Disk((0.01 * i, 0.0), 0.002) for i in range(40)]
parts += [upm.Polygon.regular(6, 0.01, position=(0.0, 0.05 + 0.001 * i)) for i in range(20)]
parts += [upm.Point(tuple(p)) for p in np.random.default_rng(3).uniform(-0.1, 0.1, (20_000, 2))]
calls = (lambda t: upm.simulate(spin, parts, duration=0.02, dt=1e-4, mu=0.3, threads=t),
         lambda t: upm.simulate_batch([spin] * 300, parts[-8:], duration=0.2, dt=1e-4, mu=0.3, threads=t),
         lambda t: upm.feed_rate(upm.TwoHarmonic(np.linspace(0.1, 1.0, 300), np.pi / 2), threads=t))
before = others()
for call in calls:
    call(1)
alone = others()
for _ in range(3):  # three times over: the pool's share holds a margin on a loaded machine
    for call in calls:
        call(None)
print(alone - before, others() - alone)
"""


def _other_threads(script: str, pool: int) -> list[int]:
    """The CPU ticks of threads other than its own that ``script`` prints (after ``OTHERS``), run
    in a fresh process whose global pool has ``pool`` threads."""
    env = dict(os.environ, RAYON_NUM_THREADS=str(pool))
    run = subprocess.run(
        [sys.executable, "-c", OTHERS + script], capture_output=True, text=True, check=True, env=env
    )
    return [int(t) for t in run.stdout.split()]


def test_one_thread_runs_on_the_calling_thread():
    # threads=1 runs every parallel section on the calling thread: no pool, no hand-off to wait
    # for. The global pool's threads do the same calls' work with threads=None.
    alone, pooled = _other_threads(ONE_THREAD, 3)
    assert alone <= 1
    assert pooled >= 10


LITTLE = """
spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
small = np.random.default_rng(4).uniform(-0.1, 0.1, (8, 2))
upm.simulate(spin, small, duration=0.01, dt=1e-4, mu=0.3)  # (the global pool started)
before = others()
for _ in range(3000):
    upm.simulate_batch([spin] * 20, small, duration=0.01, dt=1e-4, mu=0.3, record_every=100)
little = others() - before
before = others()
for _ in range(1000):
    upm.simulate_batch([spin] * 20, small, duration=0.01, dt=1e-4, mu=0.3, record_every=100, threads=2)
kept_pool = others() - before
before = others()
upm.simulate(spin, np.random.default_rng(5).uniform(-0.1, 0.1, (20_000, 2)), duration=0.5, dt=1e-4, mu=0.3,
             record_every=5000)
print(little, kept_pool, others() - before)
"""


def test_little_work_runs_on_the_calling_thread():
    # A run of little work (20 worlds of 8 points through 100 steps) stays on the calling thread
    # on the global pool too, and with threads=2 (before: a job on a kept pool of two, about 90 us
    # of hand-off for 17 of work): handing it to a pool's threads cost more than they saved. A
    # large run still spreads over them.
    little, kept_pool, large = _other_threads(LITTLE, 2)
    assert little <= 1
    assert kept_pool <= 1
    assert large >= 2


def test_ctrl_c_stops_many_disks_on_a_rotating_plate_within_a_block():
    # Disks on a rotating plate cost hundreds of ns a step: a fixed block of 4096 steps of 4000
    # disks was about 5 s of CPU before the check between blocks (measured 3.2 s with 2000). Blocks
    # are now sized by their work (about 0.1 s); CPU time, not wall-clock, with a wide margin.
    spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
    rng = np.random.default_rng(5)
    disks = [upm.Disk(tuple(p), 0.002) for p in rng.uniform(-0.15, 0.15, (4000, 2))]
    run = lambda: upm.simulate(spin, disks, duration=60.0, dt=1e-4, mu=0.3, record_every=10**6)  # noqa: E731
    cpu = time.process_time()
    assert _calls_completed_before_ctrl_c(run) == 0
    assert time.process_time() - cpu < 2.5


def test_threads_option_everywhere_gives_identical_results():
    # Before: only simulate_batch took threads= (RAYON_NUM_THREADS was the undocumented way).
    drive = upm.TwoHarmonic(np.linspace(0.1, 1.0, 300), np.pi / 2)
    spin = upm.PlateMotion.rotation((0.0, 0.0), upm.Harmonics([2.0, -1.0], frequency=35.0))
    points = np.random.default_rng(2).uniform(-0.1, 0.1, (200, 2))
    calls = {
        "feed_rate": lambda t: upm.feed_rate(drive, threads=t),
        "mean_force": lambda t: upm.mean_force(drive, 0.1, threads=t),
        "force_table": lambda t: upm.force_table(2, 5, np.linspace(0, np.pi, 500), threads=t),
        "jet_field": lambda t: upm.jet_field(points, (0.0, 0.0), (0.0, 1.0), 0.05, threads=t),
        "average_field": lambda t: upm.average_field(spin, points[:50], threads=t),
        "simulate": lambda t: upm.simulate(spin, points, duration=0.05, dt=1e-4, mu=0.3, threads=t).positions,
    }
    for name, call in calls.items():
        one, two, default = call(1), call(2), call(None)
        np.testing.assert_array_equal(one, two, err_msg=name)
        np.testing.assert_array_equal(one, default, err_msg=name)
        with pytest.raises(upm.ParameterError, match=r"threads must be an integer in \[1, 4096\]"):
            call(0)
