"""A mill job (plan/mill/'s G-code: isolation, drilling, cut-out, or all three) run on a
GRBL board, as grbl/job.py runs a plot (docs/mill.md, "Running a mill job on GRBL").

- The G-code goes to GRBL as written, less its comments (GRBL drops them anyway), each
  line numbered by its line in the file, so a refusal names `board (--mill all):123`.
- `M0` (a tool change, the probe clipped on, the touch-off): every move before it runs
  to its end, then GRBL holds (Hold:0) on the M0; the user is asked what the M0 line's
  comment says (`on_pause`, the machine interface's pen change: a MillPause, whose
  prompt is "paused for a bit change: put in the 1.000 mm bit"), and when the front end
  says go on, cycle start `~`: GRBL answers the M0 and goes on.
- `G38.2`: a probe that touches nothing (ALARM:5) or touches before it moves (ALARM:4)
  stops the job with the place in mm (work); the alarm is cleared with `$X` (the probe
  cycle ended, so GRBL's position holds) and the journal keeps the job: a resume does
  the tool change again.
- The spindle: M3 S / M5 as written. A stop (feed hold, then a soft reset: GRBL's
  position kept, its queue dropped, the spindle stopped) lifts the tool by the safe
  height, relative: after a tool change only the reset-dropped G92 knew the new bit's Z.
- The journal: journal-mill.json (stream/journal.py's format, counting G-code lines)
  with the G-code kept beside it (mill-job.nc), so a resume sends the same lines
  without planning anything again; a job cut by a height map keeps the map there too,
  and a resume corrects the kept G-code by that map, never a new one.
- A resume goes on after the last line GRBL confirmed (or, when the stop cut GRBL's
  queue short, from the first line that may not have run: `mill_rewind`), after the
  lead-in `mill_lead_in`: the modes, the G92 offset cleared, then with no tool change
  before, up to the safe height; after one, that change's re-zero again where it was
  done (its M0 naming the tool in the spindle now, the probe or the touch-off), so the
  old bit's Z zero is never used; then over the place at the safe height, the spindle
  on and up to speed, down to the cut's Z at the plunge feed, the cut's feed. A resume
  inside a tool change does the whole change again.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field

from galileo_cnc.config.userdirs import data_dir
from galileo_cnc.errors import GalileoError
from galileo_cnc.grbl.estimate import PLANNER_BLOCKS, Machine, estimate
from galileo_cnc.grbl.gcode import GcodeLine
from galileo_cnc.grbl.job import JobProgress, go_on_in, link_scale, run_journalled
from galileo_cnc.grbl.link import CYCLE_START
from galileo_cnc.grbl.reports import GrblError
from galileo_cnc.grbl.resume import PREAMBLE_TEXT, STEPPER_BLOCKS, GrblResumeError
from galileo_cnc.grbl.session import hold_and_reset, stream_piece
from galileo_cnc.grbl.stream import GrblStreamError
from galileo_cnc.grbl.travel import applies, check_travel
from galileo_cnc.plan.mill.drill import SPIN_UP, TOOL_CHANGE
from galileo_cnc.plan.mill.heightmap import HeightCorrector, HeightMap
from galileo_cnc.program.ops import NM_PER_MM
from galileo_cnc.stream.journal import Journal, JournalEntry, file_digest
from galileo_cnc.stream.streamer import PenChange, StreamResult

MILL_JOURNAL_NAME = "journal-mill.json"
#: The running mill job's G-code, kept beside its journal for a resume.
MILL_GCODE_NAME = "mill-job.nc"
#: How long GRBL may take to stand in Hold:0 on an M0 once its moves ran.
HOLD_WAIT_S = 10.0
#: GRBL's probe alarms: touched before moving, touched nothing.
PROBE_ALARMS = (4, 5)
_MOTION = ("G0", "G1", "G2", "G3")
#: Lines GRBL answers only once every move before them has run.
_SYNCING = ("G4", "M3", "M4", "M5", "M0", "G38.2")
_COMMENT = re.compile(r"\(([^)]*)\)")
_PROBE_TARGET = re.compile(r"'G38\.2[^']*Z(-?[0-9.]+)")


@dataclass(frozen=True)
class MillProgram:
    """A mill job's G-code and what it needs to go on after a stop; stands where a
    PlannedFile does in a MachineJob (`program.source`)."""

    text: str
    source: str                 # what it was made from (the board), for messages
    name: str                   # how messages name its lines: "{name}:{line}"
    safe_mm: str                # the safe height, as the G-code writes it ("2")
    plunge_mm_min: str          # the plunge feed, mm/min
    #: the probed surface the cuts follow (plan/mill/heightmap.py), None: a flat board
    height_map: HeightMap | None = None

    @property
    def program(self) -> "MillProgram":
        return self


@dataclass
class MillPause(PenChange):
    """GRBL holds on an M0 of a mill job; `message` is the M0 line's comment. A pen
    change to every front end (they show `prompt` and wait for the user)."""

    message: str = ""

    @property
    def prompt(self) -> str:
        if self.message.startswith(TOOL_CHANGE):
            return f"paused for a bit change: {self.message[len('TOOL CHANGE: '):]}"
        return f"paused (M0): {self.message}"


def height_corrected(lines: list[GcodeLine], pauses: dict[int, str], height_map: HeightMap,
                     name: str) -> tuple[list[GcodeLine], dict[int, str]]:
    """`lines` with Z following `height_map` (each cut split where the map bends, the
    pieces keeping their file line) and the pauses moved with their lines."""
    corrector = HeightCorrector(height_map, name)
    corrected: list[GcodeLine] = []
    moved: dict[int, str] = {}
    for index, line in enumerate(lines):
        if index in pauses:
            moved[len(corrected)] = pauses[index]
        corrected += [GcodeLine(text, line.command) for text in corrector.line(line.text)]
    return corrected, moved


def mill_lines(text: str) -> tuple[list[GcodeLine], dict[int, str]]:
    """The lines GRBL is sent (comments left out, blank lines skipped; `command` the
    line's index in `text`) and, for each M0 among them, its comment."""
    lines: list[GcodeLine] = []
    pauses: dict[int, str] = {}
    for number, raw in enumerate(text.splitlines()):
        code = " ".join(_COMMENT.sub(" ", raw).split(";")[0].split())
        if not code:
            continue
        if code.split()[0] in ("M0", "M00"):
            pauses[len(lines)] = "; ".join(c.strip() for c in _COMMENT.findall(raw)) or "M0"
        lines.append(GcodeLine(code, number))
    return lines, pauses


def is_tool_change(pauses: dict[int, str], index: int) -> bool:
    return pauses.get(index, "").startswith(TOOL_CHANGE)


@dataclass
class MillState:
    """What the lines before a given one leave: positions (the job's own texts, None
    when unknown), the modal feed and motion, the spindle, and the last tool change."""

    axes: list = field(default_factory=lambda: [None, None, None])
    feed: str | None = None
    motion: str | None = None
    spindle: str | None = None          # "M3 S10000" while it turns
    change: int | None = None           # the index of the last tool change's M0


def mill_state(lines: list[GcodeLine], pauses: dict[int, str], index: int) -> MillState:
    state = MillState()
    for i, line in enumerate(lines[:index]):
        words = line.text.split()
        head = words[0]
        if head in ("M3", "M4"):
            state.spindle = line.text
        elif head == "M5":
            state.spindle = None
        elif is_tool_change(pauses, i):
            state.change = i
        if head in ("G92", "G92.1", "G38.2", *_MOTION) or head[0] in "XYZF":
            if head in _MOTION or head == "G38.2":
                state.motion = head
            if head == "G38.2":             # the probe stops where it touches
                state.axes[2] = None
            for word in words:
                if word[0] in "XYZ" and head != "G38.2":
                    state.axes["XYZ".index(word[0])] = word[1:]
                elif word[0] == "F":
                    state.feed = word[1:]
    return state


def change_end(lines: list[GcodeLine], change: int) -> int:
    """The first line after a tool change's re-zero: the M3 that turns the spindle on
    again (the end of the job if none)."""
    return next((i for i in range(change + 1, len(lines)) if lines[i].text.split()[0]
                 in ("M3", "M4")), len(lines))


def restart_at(lines: list[GcodeLine], pauses: dict[int, str], start: int) -> int:
    """`start`, unless it lies inside a tool change (after its M0, up to its M3): then
    the change's M0, so the change is done whole again."""
    change = mill_state(lines, pauses, start).change
    if change is not None and change < start <= change_end(lines, change):
        return change
    return start


def mill_lead_in(lines: list[GcodeLine], pauses: dict[int, str], start: int,
                 program: MillProgram) -> tuple[list[GcodeLine], dict[int, str]]:
    """The lines that take a GRBL whose position is known (kept, homed or re-zeroed)
    to where the job stood before lines[start], and the M0s among them (module doc)."""
    if start <= 0:
        return [], {}
    state = mill_state(lines, pauses, start)
    command = lines[start].command if start < len(lines) else lines[-1].command
    out = [PREAMBLE_TEXT, "G92.1"]
    lead_pauses: dict[int, str] = {}
    starts_change = is_tool_change(pauses, start)
    x, y, z = state.axes
    if state.change is None:
        out.append(f"G0 Z{program.safe_mm}")
    elif not starts_change:
        # the bit in the spindle was zeroed by its change: zero it again, there
        cx, cy, _ = mill_state(lines, pauses, state.change).axes
        if cx is not None and cy is not None:
            out.append(f"G0 X{cx} Y{cy}")
        for i in range(state.change, change_end(lines, state.change)):
            if i in pauses:
                lead_pauses[len(out)] = pauses[i] + (" (the tool the job goes on with)"
                                                     if i == state.change else "")
            out.append(lines[i].text)
    if x is not None and y is not None:
        out.append(f"G0 X{x} Y{y}")
    elif start < len(lines) and _cuts(lines[start].text):
        raise GrblResumeError(f"{program.name}:{command + 1}: {lines[start].text!r} cuts "
                              f"from a place the lines before it do not name: the job "
                              f"cannot be resumed there")
    if state.spindle is not None:
        out += [state.spindle, spin_up(lines)]
    frame_known = state.change is None or not starts_change
    if frame_known and z is not None and z != program.safe_mm:
        out.append(f"G1 Z{z} F{program.plunge_mm_min}")
    if state.feed is not None:
        out.append(f"G1 F{state.feed}" if state.motion == "G1" else f"F{state.feed}")
    return [GcodeLine(text, command) for text in out], lead_pauses


def _cuts(text: str) -> bool:
    """A line that moves the tool from where it stands: G1/G2/G3, or axis words alone
    (the modal motion)."""
    head = text.split()[0]
    return head in ("G1", "G2", "G3") or head[0] in "XYZ"


def spin_up(lines: list[GcodeLine]) -> str:
    """The job's own dwell after switching the spindle on (drill.SPIN_UP if none)."""
    for before, line in zip(lines, lines[1:]):
        if before.text.split()[0] in ("M3", "M4") and line.text.split()[0] == "G4":
            return line.text
    return SPIN_UP


def mill_rewind(lines: list[GcodeLine], confirmed: int, floor: int, queue_blocks: int) -> int:
    """The first line that may not have run when GRBL's queue was cut short: up to
    `queue_blocks` moves (every line at least one block) before the last confirmed
    line may have been dropped; a line GRBL answers only after its moves ran (M0,
    G38.2, a dwell, the spindle) means all before it ran. Never before `floor`."""
    counted = 0
    index = confirmed
    while index >= max(floor, 0):
        words = lines[index].text.split()
        if words[0] in _SYNCING:
            return index + 1
        if not words[0].startswith("G92") and any(w[0] in "XYZ" for w in words):
            counted += 1
            if counted > queue_blocks:
                return index + 1
        index -= 1
    return max(floor, 0)


def touch_zero(text: str, overshoot_nm: int) -> str:
    """A `G92 Z<v>` line after a probe, for a tool that stands `overshoot_nm` below
    where it touched: Z <v - overshoot>, so the touch is Z v. Other words as written."""
    words = []
    for word in text.split():
        if word[0] == "Z":
            value = float(word[1:]) - overshoot_nm / NM_PER_MM
            word = "Z" + (f"{value:.6f}".rstrip("0").rstrip(".") or "0")
        words.append(word)
    return " ".join(words)


# ---- the journal ------------------------------------------------------------------------

def mill_journal() -> Journal:
    """The mill job journal (beside the plot journals): stream/journal.py's format,
    counting G-code lines; its `source` is the G-code kept for the resume, `board`
    holds what the job was made from, its name and heights."""
    return Journal(data_dir() / MILL_JOURNAL_NAME)


def pending_mill_job(journal: Journal) -> tuple[JournalEntry, MillProgram]:
    """The interrupted mill job and its G-code (unchanged since: SHA-256); GalileoError
    saying why there is none to resume."""
    entry = journal.pending()
    if entry is None or not entry.board or "mill" not in entry.board:
        raise GalileoError(f"no interrupted mill job to resume (journal {journal.path})")
    try:
        text = open(entry.source, encoding="ascii").read()
    except OSError as problem:
        raise GrblResumeError(f"{entry.source}: the interrupted mill job's G-code cannot "
                              f"be read: {problem.strerror}") from None
    if file_digest(entry.source) != entry.digest:
        raise GrblResumeError(f"{entry.source} changed since the mill job ran: it cannot "
                              f"be resumed; run the job again")
    board = entry.board
    return entry, MillProgram(text, board["mill"], board["name"], board["safe_mm"],
                              board["plunge_mm_min"], journal.height_map(entry))


# ---- the job ----------------------------------------------------------------------------

class GrblMillJob:
    """A MillProgram's lines streamed from `start` (after a resume's lead-in) by `run`,
    stopped by `stop` (from any thread); journalled once `begin_journal` was called."""

    def __init__(self, link, port, program: MillProgram):
        self.link = link
        self.port = port
        self.program = program
        self.planned = program
        self.config = None
        self.scale = link_scale(link)
        self.lines, self.pauses = mill_lines(program.text)
        if program.height_map is not None:
            self.lines, self.pauses = height_corrected(self.lines, self.pauses,
                                                       program.height_map, program.name)
        if not self.lines:
            raise GalileoError(f"{program.name}: no G-code lines to run")
        self.start = 0
        self.lead: list[GcodeLine] = []
        self.lead_pauses: dict[int, str] = {}
        self.journal: Journal | None = None
        self.entry: JournalEntry | None = None
        self.port_name = ""
        self.lift_failed = ""
        self.stopped_at_rest = False
        self.estimate_s = self._estimate()

    def where(self, command: int) -> str:
        return f"{self.program.name}:{command + 1}"

    def go_on_from(self, start: int) -> None:
        """Stream from line `start` (from its tool change when inside one), after the
        lead-in that brings GRBL there."""
        self.start = restart_at(self.lines, self.pauses, start)
        self.lead, self.lead_pauses = mill_lead_in(self.lines, self.pauses, self.start,
                                                   self.program)
        self.estimate_s = self._estimate()

    def resume_point(self, entry: JournalEntry, cut_short: str | None) -> tuple[int, str]:
        """(the line to go on from, why there) for the interrupted `entry`."""
        acked = entry.confirmed + 1
        if cut_short is None:
            start, why = acked, "after the last line GRBL confirmed"
        else:
            depth = (self.link.build.planner_blocks or PLANNER_BLOCKS) + STEPPER_BLOCKS
            start = mill_rewind(self.lines, entry.confirmed, entry.first_index, depth)
            why = (f"{cut_short}, so the lines GRBL had queued before line {acked + 1} "
                   f"may not have run")
        start = restart_at(self.lines, self.pauses, start) if start < len(self.lines) \
            else start
        if start < len(self.lines):
            why += f"; {self.where(self.lines[start].command)}"
            if is_tool_change(self.pauses, start):
                why += " is a tool change: done again"
            elif mill_state(self.lines, self.pauses, start).change is not None:
                why += " comes after a tool change: its Z re-zero is done again first"
        return start, f"resuming at G-code line {start + 1} of {len(self.lines)}: {why}"

    def check_travel(self) -> None:
        """TravelError (the file line, the axis, the limit) before the first byte, when
        GRBL knows where its travel is ($20 or $22) and X or Y would leave it. Z is not
        checked: every tool change zeroes it where the bit touches."""
        settings = self.link.settings
        if applies(settings):
            check_travel(self.rest, settings, self.link.tracker.wco_nm,
                         self.link.status().mpos_nm, where=self.where, axes=(0, 1))

    @property
    def rest(self) -> list[GcodeLine]:
        """What is still to send: the resume's lead-in and lines[start:] (as GrblJob's)."""
        return self.lead + self.lines[self.start:]

    def _estimate(self) -> float:
        machine = Machine.from_settings(self.link.settings, self.link.build.planner_blocks)
        # G38.2 runs its whole reach at most; the estimate takes the line as a G1
        return estimate([line.text.replace("G38.2", "G1") for line in self.rest],
                        machine).seconds

    def begin_journal(self, journal: Journal, entry: JournalEntry | None = None) -> None:
        """A new job in `journal` (its G-code kept beside it), or the interrupted
        `entry` going on as a new session from line `start`."""
        self.journal = journal
        if entry is not None:
            go_on_in(journal, entry, self.start)
            return
        kept = journal.path.parent / MILL_GCODE_NAME
        kept.parent.mkdir(parents=True, exist_ok=True)
        kept.write_text(self.program.text, encoding="ascii")
        program = self.program
        journal.begin(JournalEntry(
            str(kept), file_digest(str(kept)), (0, 0), "", False, len(self.lines), -1, 0, 0,
            board={"mill": program.source, "name": program.name,
                   "safe_mm": program.safe_mm, "plunge_mm_min": program.plunge_mm_min}),
            height_map=program.height_map)

    def stop(self) -> None:
        """From another thread: feed hold now; the streaming thread's next read raises
        JobInterrupted."""
        from galileo_cnc.grbl.link import FEED_HOLD
        if self.port is not None:
            self.port.write(FEED_HOLD)
            self.port.interrupt()

    def run(self, on_progress=None, on_pause=None) -> StreamResult:
        """The job streamed, the journal ended with how it went (as GrblJob.run): a
        stop holds and resets GRBL, lifts the tool and returns; a probe alarm is
        cleared and raised as GrblStreamError naming the place in mm."""
        progress = JobProgress(len(self.lines), self.start, self.estimate_s, on_progress,
                               lambda index: self.lines[index].command + 1)
        confirm = self.journal.confirm if self.journal is not None else None

        def replied(number: int, reply) -> None:
            if reply.ok and confirm is not None:
                confirm(number)

        return run_journalled(self, lambda: self._stream(progress.show, replied,
                                                         progress.seen, on_pause), progress)

    def explain(self, stopped: GrblStreamError) -> GrblStreamError:
        """A probe alarm cleared and named in mm (`_probe_failed`); other errors as
        they are."""
        if stopped.alarm and stopped.code in PROBE_ALARMS:
            return self._probe_failed(stopped)
        return stopped

    def _stream(self, show, replied, seen, on_pause) -> None:
        """The lead-in and lines[start:] in pieces that end at each M0 (`_pause`) and
        each G38.2 (`_probe`); the G92 after a probe set from where it touched."""
        sequence = [(line, None, self.lead_pauses.get(k)) for k, line in enumerate(self.lead)]
        sequence += [(self.lines[i], i, self.pauses.get(i))
                     for i in range(self.start, len(self.lines))]
        chunk: list[GcodeLine] = []
        numbers: list[int | None] = []
        overshoot_nm = None
        for line, number, pause in sequence:
            head = line.text.split()[0]
            if overshoot_nm is not None and head == "G92":
                line = GcodeLine(touch_zero(line.text, overshoot_nm), line.command)
            overshoot_nm = None
            if pause is None and head != "G38.2":
                chunk.append(line)
                numbers.append(number)
                continue
            stream_piece(self.link, chunk, numbers, self.where, show, replied, seen)
            chunk, numbers = [], []
            if pause is not None:
                self._pause(line, number, pause, show, replied, on_pause)
            else:
                overshoot_nm = self._probe(line, number, show, replied)
        stream_piece(self.link, chunk, numbers, self.where, show, replied, seen)

    def _probe(self, line: GcodeLine, number: int | None, show, replied) -> int:
        """G38.2 with every move before it run; how far GRBL went on past the touch
        (nm, down): it decelerates through the moves it had prepared, 0.6 mm at
        600 mm/min in simavr, so the G92 after it is set from the touch ([PRB:])."""
        link = self.link
        name = f"G-code line {number + 1}" if number is not None else \
            "the resume's lead-in"
        try:
            reply = link.command(line.text)
        except GrblError as problem:
            if not problem.alarm:
                raise
            raise GrblStreamError(f"{self.where(line.command)}: {problem} (at {name} "
                                  f"{line.text!r})", [], 0, code=problem.code,
                                  alarm=True) from None
        if not reply.ok:
            raise GrblStreamError(f"GRBL refused a line: {self.where(line.command)}: "
                                  f"{reply.text} in {name} {line.text!r}", [], 0,
                                  code=reply.code)
        touched = next((text for text in reply.lines if text.startswith("[PRB:")), None)
        if touched is None or not touched.rstrip("]").endswith(":1"):
            raise GrblError(f"{self.where(line.command)}: GRBL reported no touch of the "
                            f"probe ({touched or 'no [PRB:] line'})")
        prb_z_nm = round(float(touched[5:].split(":")[0].split(",")[2]) * NM_PER_MM)
        if number is not None:
            replied(number, reply)
            show(number + 1)
        return prb_z_nm - link.status().mpos_nm[2]

    def _pause(self, line: GcodeLine, number: int | None, message: str, show, replied,
               on_pause) -> None:
        """M0 sent with every move before it run: GRBL holds; the user is asked; cycle
        start; GRBL's `ok` of the M0."""
        link = self.link
        link.write_line(line.text)
        deadline = time.monotonic() + HOLD_WAIT_S
        while True:
            status = link.status()
            if status.state == "Hold" and status.substate == 0:
                break
            if time.monotonic() > deadline:
                raise GrblError(f"{self.where(line.command)}: GRBL did not hold on the M0 "
                                f"within {HOLD_WAIT_S:g} s (it stands in {status.state})")
        if on_pause is not None:
            on_pause(MillPause(-1, message, line.command, message))
        link.realtime(CYCLE_START)
        reply = link.wait_reply()
        if not reply.ok:
            raise GrblError(f"{self.where(line.command)}: GRBL refused the M0: {reply.text}")
        if number is not None:
            replied(number, reply)
            show(number + 1)

    def _probe_failed(self, stopped: GrblStreamError) -> GrblStreamError:
        """GRBL's probe alarm: what GRBL still sends read, the alarm cleared ($X: the
        probe cycle ran to its end, the position holds), the error in mm."""
        link = self.link
        while True:
            line = link.read_line(0.3)
            if line is None:
                break
            try:
                link.classify(line)
            except GrblError:
                pass
        cleared = "GRBL's alarm was cleared ($X)"
        try:
            link.command_checked("$X")
            status = link.status()
            x, y, z = (f"{nm / NM_PER_MM:.3f}" for nm in status.wpos_nm)
            here = f"the tool stands at X {x} Y {y} Z {z} mm (work), the spindle off"
        except GrblError as problem:
            cleared = f"GRBL's alarm could not be cleared ({problem}): unlock it with $X"
            here = "its position was not reported"
        reach = _PROBE_TARGET.search(str(stopped))
        if stopped.code == 4:
            what = "the probe touched before it moved (is the clip on the plate?)"
        elif reach is not None:
            what = (f"the probe went down to Z {float(reach[1]):.3f} mm (work) and touched "
                    f"nothing")
        else:
            what = "the probe touched nothing"
        return GrblStreamError(
            f"{stopped}: {what}; {cleared}, {here}. Check the probe's clip and the touch "
            f"plate, then resume: the tool change is done again", stopped.errors,
            stopped.acked, code=stopped.code, alarm=False)

    def _stop_and_lift(self) -> None:
        """Decelerate, drop GRBL's queue (its position kept), lift the tool to the
        safe height of the frame it cut in: relative, as the reset took the G92 offset
        (a changed bit's Z zero) with it."""
        link = self.link
        safe_nm = round(float(self.program.safe_mm) * NM_PER_MM)
        status = hold_and_reset(link)
        self.stopped_at_rest = status is not None
        # no report at rest: the lift takes the whole height
        lift_nm = safe_nm if status is None else max(0, safe_nm - status.wpos_nm[2])
        try:
            if lift_nm:
                link.command_checked(f"G91 G0 Z{lift_nm / NM_PER_MM:.3f}")
            link.command_checked("G90")
            link.wait_idle()
        except GrblError as problem:
            self.lift_failed = f"the tool could not be lifted: {problem}"

    def _disarm(self) -> None:
        if self.port is not None:
            self.port.disarm()
