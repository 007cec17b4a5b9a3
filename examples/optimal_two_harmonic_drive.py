"""Find the best two-harmonic drive for a 35 Hz feeder and check it against the thesis.

The plate velocity is v(t) = A (sin wt + b sin(2wt + phi)); the feed rate is its median.
"""

import numpy as np

import upm

A, FREQUENCY = 0.02, 35.0  # 2 cm/s first-harmonic amplitude at the thesis's 35 Hz drive
b = np.linspace(0.0, 1.5, 151)[:, None]
phi = np.linspace(-np.pi, np.pi, 181)[None, :]
rates = upm.feed_rate(upm.TwoHarmonic(b, phi, amplitude=A, frequency=FREQUENCY))
i, j = np.unravel_index(np.argmax(rates), rates.shape)
print(f"best drive: b = {b[i, 0]:.2f}, phi = {phi[0, j]:.3f} rad -> {1000 * rates[i, j]:.2f} mm/s")
print(
    "thesis (3.17): b = 1/2, phi = pi/2 ->",
    f"{1000 * upm.theory.two_harmonic_feed_rate(0.5, np.pi / 2, A):.2f} mm/s",
)

best = upm.TwoHarmonic(0.5, np.pi / 2, amplitude=A, frequency=FREQUENCY)
v = np.linspace(-0.01, 0.01, 5)
for vp, f in zip(v, upm.mean_force(best, v), strict=True):
    print(f"  part at {1000 * vp:+6.1f} mm/s: average force {f:+.4f} mu m g")
