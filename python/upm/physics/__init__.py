"""The forward model: what a vibrating plate does to the parts on it, with no motors and no loop.

- :mod:`~upm.physics.waveforms`, :mod:`~upm.physics.motion`: the plate's motion (chapters 2 and 4);
- :mod:`~upm.physics.feeding`, :mod:`~upm.physics.theory`: the one-dimensional drive (chapter 2);
- :mod:`~upm.physics.fields`, :mod:`~upm.physics.ppod`: the averaged fields of plane motions and the
  6-DOF plate's field library (chapters 4 and 5, SPEC §10);
- :mod:`~upm.physics.sim`, :mod:`~upm.physics.polygon`, :mod:`~upm.physics.orienting`: exact
  simulation of disks, points and convex parts, and their equilibria (SPEC §11);
- :mod:`~upm.physics.mchip`: the M-Chip array of resonators.

Every module here depends only on upm's foundation (``_core``, ``_arrays``, ``_errors``) and on its
siblings; ``pyproject.toml``'s import-linter contract checks it.
"""
