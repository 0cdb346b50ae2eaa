"""A planned file as pen-plotter G-code: what `galileo-cnc convert` writes.

The seed's CAM program turned drawings into G-code for the plotter; this does the
same for any input, in the order the planner plots it (paths chained and ordered,
one pen at a time, the ink in ink mode) and with the offset applied, so the file
runs as it is on our machine and on a stock GRBL board:

- millimetres, absolute (G21 G90 G17), coordinates exact to the nanometre;
- the pen as the profile moves it ([grbl] pen, or `--pen`): "z", the Z axis at the
  profile's pen heights (pen_down_z_steps, + pen_lift_steps up) at its Z feed, as a
  GRBL plotter with its pen on Z needs (UGS, CNCjs and bCNC stream it as it is);
  "servo", `M3 S<down>` / `M5` (or `M3 S<up>`) with the servo's dwell after each
  change (GRBL does not wait for a servo); "spindle", M3 down and M5 up alone (a
  solenoid or a laser on the spindle output). A flash is a dot: down, the flash
  dwell, up;
- dwells in the unit the target reads: GRBL's (and LinuxCNC's) `G4 P` is seconds,
  this program's reader takes `P` as milliseconds (`--target galileo`);
- a pen change: pen up, `T<n>` with the pen named in a comment, then M0, which
  pauses GRBL until cycle start (our reader asks for the pen at the T word). Pens
  are numbered 1, 2, ... in the order they are first used (GRBL takes T up to 255;
  Gerber apertures go higher);
- one feed (F, mm/min) for drawing: the profile's, or the file's own F words; the
  Z moves of the pen at the profile's Z feed, the drawing feed given again after.

Reading the output back with our G-code reader and planning it with offset none in
file order gives the same pen-down paths, step for step (tests/cli/test_convert.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.errors import GalileoError
from galileo_cnc.plan.order.apertures import DRAWING_KINDS
from galileo_cnc.plan.pipeline import PlannedFile
from galileo_cnc.plan.planner import plotting_order
from galileo_cnc.program.ops import I, J, KIND, NM_PER_MM, NO_TOOL, TOOL, VALUE, X, Y, OpKind
from galileo_cnc.readers.gcode.writer import feed_text, mm
from galileo_cnc.readers.gerber.numbers import round_div


#: how the pen moves (docstring); "z" and "servo" are the profile's [grbl] pen
PEN_STYLES = ("z", "servo", "spindle")
#: who reads the file: a GRBL board's sender (G4 P in seconds) or galileo-cnc (ms)
TARGETS = ("grbl", "galileo")


@dataclass(frozen=True)
class PenMoves:
    """The G-code lines that lower and lift the pen, for one pen style and target."""

    down: tuple[str, ...]
    up: tuple[str, ...]
    #: the modal F the pen's lines leave behind ("" if they set none)
    feed: str = ""
    target: str = "grbl"

    def dwell(self, ms: int) -> str:
        """`G4 P` in the target's unit: seconds for GRBL, milliseconds for galileo-cnc."""
        if self.target == "galileo":
            return f"G4 P{ms}"
        return f"G4 P{_seconds(ms)}"


def _seconds(ms: int) -> str:
    whole, rest = divmod(ms, 1000)
    return f"{whole}.{rest:03d}".rstrip("0").rstrip(".")


def pen_moves(config: MachineConfig, style: str | None = None, target: str = "grbl"
              ) -> PenMoves:
    """The pen as `style` (None: the profile's [grbl] pen) moves it; GalileoError for
    an unknown style or target."""
    style = style or config.grbl_pen
    if style not in PEN_STYLES:
        raise GalileoError(f"--pen: expected {', '.join(PEN_STYLES)}, got {style!r}")
    if target not in TARGETS:
        raise GalileoError(f"--target: expected {', '.join(TARGETS)}, got {target!r}")
    if style == "spindle":
        return PenMoves(("M3",), ("M5",), target=target)
    if style == "servo":
        if target == "galileo" and config.servo_up_s:
            raise GalileoError("--pen servo --target galileo: this program reads every M3 "
                               "as pen down, so M3 S<up> cannot lift it (--pen z)")
        dwell = PenMoves((), (), target=target).dwell(config.servo_dwell_ms)
        up = f"M3 S{config.servo_up_s}" if config.servo_up_s else "M5"
        return PenMoves((f"M3 S{config.servo_down_s}", dwell), (up, dwell), target=target)
    feed = f"F{mm(round(config.z_feed_mm_s * 60 * NM_PER_MM))}"
    heights = [mm(round_div(z * config.pitch_nm, config.steps_per_rev))
               for z in (config.pen_down_z_steps, config.pen_up_z_steps)]
    return PenMoves((f"G1 Z{heights[0]} {feed}",), (f"G1 Z{heights[1]} {feed}",), feed,
                    target)


def converted_gcode(planned: PlannedFile, config: MachineConfig,
                    pen: PenMoves | None = None) -> Iterator[str]:
    """The planned file as G-code lines, in plotting order (see the module doc); `pen`:
    how the pen moves (pen_moves; None: the profile's pen, for GRBL)."""
    program, job = planned.plotted, planned.job
    pen = pen or pen_moves(config)
    ox, oy = planned.offset_nm
    rows, _grouped, _ordered = plotting_order(program, config, planned.offset_nm,
                                              group=job.grouped, optimize=job.ordered)
    source = " ".join(str(planned.artwork.program.source).split())
    yield f"; galileo-cnc convert of {source}"
    done = planned.artwork.transform.describe()
    yield (f"; {planned.mode} mode, offset {mm(ox)}, {mm(oy)} mm subtracted"
           + (f", {done}" if done else "")
           + (f", pens {', '.join(mm(w) for w in job.pens_nm)} mm" if job.pens_nm else ""))
    if getattr(planned, "side_line", ""):            # a board's side: which, and its axis
        yield f"; {planned.side_line}"
    yield "G21 G90 G17"
    yield from pen.up
    draw_feed = f"F{mm(round(config.feed_mm_s * 60 * NM_PER_MM))}"
    modal_feed = pen.feed
    several_pens = len({row[TOOL] for _i, row in rows
                        if row[KIND] in DRAWING_KINDS and row[TOOL] != NO_TOOL}) > 1
    pen_numbers: dict[int, int] = {}
    aperture = tool = NO_TOOL
    down = False
    at: tuple[int, int] | None = None

    def lift() -> Iterator[str]:
        nonlocal down, modal_feed
        if down:
            yield from pen.up
            modal_feed = pen.feed or modal_feed
            down = False

    def lower() -> Iterator[str]:
        nonlocal down, modal_feed
        if not down:
            yield from pen.down
            modal_feed = pen.feed or modal_feed
            down = True

    def feed_word() -> str:
        """The drawing feed on a draw line, when the modal F is another."""
        nonlocal modal_feed
        if modal_feed == draw_feed:
            return ""
        modal_feed = draw_feed
        return f" {draw_feed}"

    for _index, row in rows:
        kind = row[KIND]
        if kind == OpKind.SELECT:
            aperture = row[TOOL]
            continue
        if kind in DRAWING_KINDS and row[TOOL] != NO_TOOL:
            aperture = row[TOOL]
        if several_pens and (kind in DRAWING_KINDS or kind == OpKind.PEN_DOWN) \
                and aperture != tool and aperture != NO_TOOL:
            yield from lift()
            number = pen_numbers.setdefault(aperture, len(pen_numbers) + 1)
            label = job.pen_labels.get(aperture, f"pen {number}")
            yield f"T{number} ; insert {label}"
            yield "M0"
            tool = aperture
        point = (row[X] - ox, row[Y] - oy)
        if kind == OpKind.MOVE:
            if point != at:
                yield from lift()
                yield f"G0 X{mm(point[0])} Y{mm(point[1])}"
            at = point
        elif kind == OpKind.LINE:
            yield from lower()
            yield f"G1 X{mm(point[0])} Y{mm(point[1])}{feed_word()}"
            at = point
        elif kind in (OpKind.ARC_CW, OpKind.ARC_CCW):
            yield from lower()
            code = "G2" if kind == OpKind.ARC_CW else "G3"
            yield (f"{code} X{mm(point[0])} Y{mm(point[1])} I{mm(row[I])} J{mm(row[J])}"
                   f"{feed_word()}")
            at = point
        elif kind == OpKind.FLASH:
            yield from lift()
            if point != at:
                yield f"G0 X{mm(point[0])} Y{mm(point[1])}"
            yield from lower()
            if config.flash_dwell_ms > 0:
                yield pen.dwell(config.flash_dwell_ms)
            yield from lift()
            at = point
        elif kind == OpKind.PEN_DOWN:
            yield from lower()           # as the planner: lowered here, a dot if no draw follows
        elif kind == OpKind.PEN_UP:
            yield from lift()
        elif kind == OpKind.FEED and row[VALUE] > 0:
            draw_feed = f"F{feed_text(row[VALUE])}"
        elif kind == OpKind.DWELL and row[VALUE] >= 0:
            yield pen.dwell(row[VALUE])
        # regions, polarity and markers draw nothing by themselves
    yield from lift()
    yield "M2"
