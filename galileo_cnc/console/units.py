"""Units at the console's edge: mm and the seed's jog units in, integers inside."""

from __future__ import annotations

from galileo_cnc import protocol as P
from galileo_cnc.config.machine import MachineConfig

#: The seed's jog distance unit: 1000 units = 1 cm, so one unit is 10 um.
NM_PER_JOG_UNIT = 10_000


def jog_units_to_steps(units: int, config: MachineConfig) -> int:
    return config.nm_to_steps(units * NM_PER_JOG_UNIT)


def refusal_text(error: Exception, config: MachineConfig) -> str:
    """What the machine refused, with a soft limit said in mm rather than steps."""
    reply = getattr(error, "reply", None)
    limit = P.parse_soft_limit(reply.text) if reply is not None and reply.code == \
        P.ERROR_BY_NAME["SOFT_LIMIT"].code else None
    if limit is None:
        return str(error)
    return f"refused: {config.travel_refusal(*limit)}"


