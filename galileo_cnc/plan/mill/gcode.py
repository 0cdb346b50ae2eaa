"""Isolation passes as G-code for a GRBL mill (or any sender): what `convert --mill
isolate` is to write.

`mill_gcode(program, mill)` isolates the copper (isolate.py), refuses shorts the user
has not accepted, proves that no pass enters the copper (proof.py) and writes:

- millimetres, absolute, XY plane, feed per minute (G21 G90 G17 G94); coordinates
  exact to the nanometre (readers/gcode/writer.mm), so the file holds the proven paths;
- the tool and its cut named in comments (GRBL has no tool change: the tool in the
  spindle is the profile's [mill] tool), the spindle on at the profile's speed (M3 S),
  off at the end (M5);
- every pass ring: a rapid at the safe height to its start, a plunge to the cut depth
  at the plunge feed (Z = 0 is the copper's top), the ring at the cutting feed back to
  its start, a rapid up to the safe height.

Passes are cut in order, the first (nearest the copper) everywhere before the second,
so each next pass cuts beside a groove already made; within a pass the next ring is
the one whose first vertex is nearest, entered at its vertex nearest the tool.
"""

from __future__ import annotations

import numpy as np

from galileo_cnc.config.mill import MillConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.mill.isolate import Isolation, isolate, refuse_shorts
from galileo_cnc.plan.mill.proof import prove
from galileo_cnc.program.ops import Program
from galileo_cnc.readers.gcode.writer import mm


class MillError(GalileoError):
    """Nothing to mill, or passes the proof does not clear: nothing is written."""


def mill_gcode(program: Program, mill: MillConfig, accept_shorts: bool = False) -> str:
    """The isolation G-code of a Gerber copper layer (module doc); ShortsError when it
    has shorts the user did not accept, MillError when it has no copper or a pass would
    enter the copper."""
    isolation = isolate(program, mill)
    if not isolation.islands.parts:
        raise MillError(f"{program.source}: no copper on this layer: nothing to isolate")
    refuse_shorts(isolation, accept_shorts)
    proof = prove(isolation, swept=False)
    if not proof.holds:
        raise MillError(f"{program.source}: {proof.describe()}; nothing written")
    return isolation_gcode(isolation, mill, [proof.describe()])


def isolation_gcode(isolation: Isolation, mill: MillConfig, notes: list[str] = ()) -> str:
    """The passes of `isolation` as G-code lines (module doc), `notes` as comments."""
    feed, plunge = mm(mill.feed_um_min * 1000), mm(mill.plunge_feed_um_min * 1000)
    safe, depth = mm(mill.safe_height_nm), mm(-mill.cut_depth_nm)
    lines = [f"(galileo-cnc mill: isolation of {_comment(isolation.source)})",
             f"(tool: {_comment(mill.describe())})"]
    lines += [f"({_comment(note)})" for note in notes]
    for short in isolation.shorts:
        lines.append(f"(short accepted: {_comment(short.describe())})")
    lines += ["G21 G90 G17 G94", f"G0 Z{safe}", f"M3 S{mill.spindle_rpm}"]
    at = np.zeros(2, dtype=np.int64)
    for rings in isolation.passes:
        for ring in _in_order(rings, at):
            lines.append(f"G0 X{mm(int(ring[0, 0]))} Y{mm(int(ring[0, 1]))}")
            lines.append(f"G1 Z{depth} F{plunge}")
            lines.append(f"G1 X{mm(int(ring[1, 0]))} Y{mm(int(ring[1, 1]))} F{feed}")
            lines += [f"X{mm(int(x))} Y{mm(int(y))}" for x, y in ring[2:].tolist()]
            lines.append(f"X{mm(int(ring[0, 0]))} Y{mm(int(ring[0, 1]))}")
            lines.append(f"G0 Z{safe}")
            at = ring[0]
    lines += ["M5", "M2"]
    return "\n".join(lines) + "\n"


def _in_order(rings: list[np.ndarray], start: np.ndarray) -> list[np.ndarray]:
    """The rings nearest first from `start` (module doc), each turned to begin at its
    vertex nearest the tool."""
    left = list(range(len(rings)))
    firsts = np.array([ring[0] for ring in rings], dtype=np.float64).reshape(-1, 2)
    at = start.astype(np.float64)
    ordered = []
    while left:
        k = left[int(np.argmin(np.hypot(*(firsts[left] - at).T)))]
        left.remove(k)
        ring = rings[k]
        entry = int(np.argmin(np.hypot(*(ring - at).T)))
        ring = np.roll(ring, -entry, axis=0)
        ordered.append(ring)
        at = ring[0].astype(np.float64)
    return ordered


def _comment(text: str) -> str:
    """Text a G-code comment can hold: no parentheses inside one."""
    return text.replace("(", "[").replace(")", "]")
