"""Probing a height map on a GRBL board: G38.2 at every node of a grid, `[PRB:]` collected.

GRBL runs a G38.2 to its end before it answers `ok` (mc_probe_cycle synchronises the
buffer), and prints the contact as `[PRB:x,y,z:1]` in machine coordinates just before
that `ok`. A node's height is the contact's Z less the work offset (WCO: the active
G54..G59 offset plus G92 and the tool length offset, read once with `$G` and `$#`), so
heights are work Z, the frame the job's lines use.

A probe that finds nothing within its travel ends in GRBL's ALARM:5, one already
touching where it starts in ALARM:4: both raise ProbeError naming the node in mm
(work), the travel, and that GRBL waits in alarm for an unlock ($X) once the user has
looked. plan/mill/heightmap.py has the grid, the lines and the map; docs/mill.md.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from galileo_cnc.grbl.link import GrblLink, Reply
from galileo_cnc.grbl.numbers import decimal_text_to_nm
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.plan.mill.heightmap import (HeightMap, ProbeGrid, mm_text, parse_prb,
                                             probe_lines)

#: GRBL's alarms of a probe cycle (codes.ALARMS): 4 the probe touched before it moved,
#: 5 it moved its whole travel without contact
ALARM_ALREADY_TOUCHING = 4
ALARM_NO_CONTACT = 5
_SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59")


class ProbeError(GrblError):
    """A probe of the height map failed: where, and what the user can do (mm, work)."""


def work_offset_nm(link: GrblLink) -> tuple[int, int, int]:
    """GRBL's work coordinate offset (machine = work + WCO): the active system's offset
    (`$G`), plus G92's, plus the tool length offset on Z (`$#`)."""
    modes = [word for line in link.command_checked("$G").lines if line.startswith("[GC:")
             for word in line[4:].rstrip("]").split()]
    active = next((name for name in _SYSTEMS if name in modes), "G54")
    offsets = {}
    for line in link.command_checked("$#").lines:
        if line.startswith("[") and ":" in line:
            name, _, value = line[1:].rstrip("]").partition(":")
            offsets[name] = value.split(":")[0]
    try:
        system = [decimal_text_to_nm(v) for v in offsets[active].split(",")]
        shift = [decimal_text_to_nm(v) for v in offsets["G92"].split(",")]
        tool = decimal_text_to_nm(offsets.get("TLO", "0"))
    except (KeyError, ValueError):
        raise GrblError(f"GRBL's $# reply lacks the {active}, G92 or TLO offset: "
                        f"{sorted(offsets)}") from None
    return system[0] + shift[0], system[1] + shift[1], system[2] + shift[2] + tool


def probe_height_map(link: GrblLink, grid: ProbeGrid,
                     on_point: Callable[[int, int, tuple[int, int], int], None] | None = None
                     ) -> HeightMap:
    """Probes every node of `grid` (ProbeGrid.points order) and returns the map of the
    surface's work Z there. `on_point(done, total, (x, y), z)` (nm) after each node.
    The lines are streamed with character counting, as grbl/stream.py streams a job:
    GRBL holds the next node's lines while it probes, so no round trip waits between
    two probes. A reply may wait a whole probe, at its feed.
    ProbeError when a probe fails; GrblError for any other refusal or alarm."""
    offset = work_offset_nm(link)
    points = grid.points()
    lines = [("G21 G90", None)] + [(text, node) for node, texts in enumerate(probe_lines(grid))
                                    for text in texts]
    heights: list[int] = []
    budget = link.rx_buffer_bytes - 1
    in_flight: deque[tuple[str, int | None, int]] = deque()     # (line, node, bytes)
    used = sent = 0
    contact = None
    patience_s = link.reply_timeout_s + 60 * (grid.clearance_nm + grid.depth_nm) \
        / (grid.feed_um_min * 1000)
    while sent < len(lines) or in_flight:
        while sent < len(lines) and used + len(lines[sent][0]) + 1 <= budget:
            used += link.write_line(lines[sent][0])
            in_flight.append((*lines[sent], len(lines[sent][0]) + 1))
            sent += 1
        line = link.read_line(patience_s)
        if line is None:
            raise GrblError(f"GRBL gave no reply within {patience_s:.0f} s while probing "
                            f"the height map ({in_flight[0][0]!r})")
        text, node, size = in_flight[0]
        try:
            reply = link.classify(line)
        except GrblError as exc:
            _answered(link, len(in_flight))
            raise _failed(exc, grid, points[node] if node is not None else None) from None
        if reply is None or line.startswith("<"):
            continue
        if not isinstance(reply, Reply):
            found = parse_prb(line)
            if found is not None:
                contact = found
            continue
        in_flight.popleft()
        used -= size
        if not reply.ok:
            _answered(link, len(in_flight))
            raise GrblError(f"GRBL refused {text!r} while probing the height map: "
                            f"{reply.text}", reply.code)
        if text.startswith("G38.2"):
            heights.append(_height(contact, offset, grid, points[node]))
            contact = None
            if on_point is not None:
                on_point(len(heights), len(points), points[node], heights[-1])
    link.wait_idle()
    return HeightMap.from_points(grid, heights)


def _answered(link: GrblLink, lines: int) -> None:
    """Reads the replies GRBL still owes the lines in flight after an alarm (the probe's
    own, then error:9 for each behind it), so the next command reads its own reply."""
    while lines > 0:
        line = link.read_line()
        if line is None:
            return
        try:
            reply = link.classify(line)
        except GrblError:
            continue
        lines -= isinstance(reply, Reply)


def _where(at: tuple[int, int]) -> str:
    return f"X {mm_text(at[0])} Y {mm_text(at[1])} mm (work)"


def _height(contact, offset: tuple[int, int, int], grid: ProbeGrid, at: tuple[int, int]) -> int:
    """The work Z of one probe's contact, or ProbeError when it reported none."""
    if contact is None:
        raise ProbeError(f"height map: GRBL sent no [PRB:] report for the probe at "
                         f"{_where(at)}")
    position, touched = contact
    if not touched:
        raise ProbeError(f"height map: the probe touched nothing at {_where(at)} from Z "
                         f"{mm_text(grid.clearance_nm)} down to Z {mm_text(-grid.depth_nm)} "
                         f"mm (work)")
    return position[2] - offset[2]


def _failed(exc: GrblError, grid: ProbeGrid, at: tuple[int, int] | None) -> GrblError:
    """GRBL's alarm during a probe in the user's words (mm, work), else itself."""
    if at is None or not exc.alarm:
        return exc
    where = _where(at)
    if exc.code == ALARM_NO_CONTACT:
        return ProbeError(
            f"height map: the probe touched nothing at {where} from Z "
            f"{mm_text(grid.clearance_nm)} down to Z {mm_text(-grid.depth_nm)} mm (work): the "
            f"board lies deeper there than probe_depth_mm = {mm_text(grid.depth_nm)} reaches, "
            f"or the probe is not wired (GRBL ALARM:5: it waits for an unlock, $X, once you "
            f"have looked)", exc.code, alarm=True)
    if exc.code == ALARM_ALREADY_TOUCHING:
        return ProbeError(
            f"height map: the probe already touched at {where}, Z "
            f"{mm_text(grid.clearance_nm)} mm (work), before it moved: the board lies higher "
            f"there than probe_clearance_mm = {mm_text(grid.clearance_nm)}, or the probe's "
            f"clip touches the plate (GRBL ALARM:4: it waits for an unlock, $X)",
            exc.code, alarm=True)
    return exc
