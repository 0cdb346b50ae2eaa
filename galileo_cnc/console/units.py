"""Units at the console's edge: mm and the seed's jog units in, integers inside."""

from __future__ import annotations

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.protocol import Status

#: The seed's jog distance unit: 1000 units = 1 cm, so one unit is 10 um.
NM_PER_JOG_UNIT = 10_000


def jog_units_to_steps(units: int, config: MachineConfig) -> int:
    return config.nm_to_steps(units * NM_PER_JOG_UNIT)


def steps_to_mm(steps: int, config: MachineConfig) -> float:
    return steps / config.steps_per_mm


def position_mm_text(status: Status, config: MachineConfig) -> str:
    return (f"X {steps_to_mm(status.x_steps, config):.3f}  "
            f"Y {steps_to_mm(status.y_steps, config):.3f}  "
            f"Z {steps_to_mm(status.z_steps, config):.3f} mm")
