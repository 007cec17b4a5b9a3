"""The machine: motors, suspension, wrench and limits, the pulses a board plays, and the simulated
plate behind them.

- :mod:`~upm.plate.actuation`: the motors' axes, the plate's mass and the wrench (5.8);
- :mod:`~upm.plate.pulses`: one enveloped pulse and programs of them;
- :mod:`~upm.plate.drive`: force and stroke limits, the envelope, the driven plate's response;
- :mod:`~upm.plate.plate6`: the 6-DOF plate's drive (SPEC §10);
- :mod:`~upm.plate.plant`: the simulated UPM (plate, parts, and an overhead camera).

The layer sits on :mod:`upm.physics`; nothing here plans, sees or talks to a board.
"""
