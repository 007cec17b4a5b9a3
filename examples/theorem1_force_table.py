"""Theorem 1 (thesis 6.13): the force of two sinusoids is a triangle wave in their phase.

Compares the closed form with the exact root-based average over 100 001 phases.
"""

import math

import numpy as np

import upm

psi = np.linspace(0.0, 2.0 * np.pi, 100_001)
print(" n1 n2   peak      1/(n2^2-n1^2)   max |closed - exact|")
for n2 in range(2, 6):
    for n1 in range(1, n2):
        if math.gcd(n1, n2) != 1:
            continue
        exact = upm.force_table(n1, n2, psi)
        closed = upm.theorem1_force(n1, n2, psi)
        print(
            f" {n1:>2} {n2:>2}  {exact.max():.6f}  {1 / (n2 * n2 - n1 * n1):.6f}",
            f"       {np.abs(closed - exact).max():.1e}",
        )
