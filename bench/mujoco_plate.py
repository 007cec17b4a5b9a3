"""The MuJoCo peer's plate, shared by ``bench/integrator.py`` and ``bench/contacts.py``.

A massive plate on slide/slide/hinge joints whose joint velocities are prescribed open-loop each
step, with the parts (boxes: spheres would roll instead of sliding) lying on it. Elliptic friction
cones, impratio 100, solref 0.001. Needs the optional ``mujoco`` package.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np


def plate_world(
    parts: str, *, half: float, dt: float, mu: float, g: float, settle: int, fixed: str = "", plate: str = ""
) -> tuple[Any, Any]:
    """Model and data of the plate (half-side ``half`` [m], extra geom attributes ``plate``), the
    ``parts`` bodies and the ``fixed`` world geoms, after ``settle`` steps on the still plate."""
    import mujoco

    xml = f"""
    <mujoco>
      <option timestep="{dt}" cone="elliptic" impratio="100" gravity="0 0 -{g}"/>
      <default><geom solref="0.001 1" friction="{mu} 0.005 0.0001" condim="3"/></default>
      <worldbody>
        {fixed}
        <body name="plate">
          <joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 1 0"/>
          <joint type="hinge" axis="0 0 1"/>
          <geom type="box" size="{half} {half} 0.01" mass="10000" {plate}/>
        </body>
        {parts}
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for _ in range(settle):
        mujoco.mj_step(model, data)
    return model, data


def drive(model: Any, data: Any, u: np.ndarray) -> float:
    """Steps with the plate's (u1, u2, u3) prescribed from the rows of ``u``; the seconds taken."""
    import mujoco

    start = time.perf_counter()
    for k in range(len(u)):
        data.qvel[:3] = u[k]
        mujoco.mj_step(model, data)
    return time.perf_counter() - start
