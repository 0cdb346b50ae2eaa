"""Feeds checked before planning, for every front end (issue 31, item 12).

The seed warned above 6.25 mm/s (the motors may stall and lose steps) when the
user set the feed in `setup`; a job's feeds were not looked at. Here, before a job
is planned:

- a feed the machine cannot run (above its fastest step rate, or below its
  slowest) is refused, naming the file line and the F word as the file wrote it,
  in mm/s and mm/min, steps/s only in brackets;
- a feed above the profile's warning feed (`feed_warn_mm_s`, 6.25 mm/s by default)
  is a warning: the profile's own feeds (`feed_mm_s`, `rapid_feed_mm_s`,
  `z_feed_mm_s`) one line each, the file's in one line (how many, the first, the
  fastest), never a line per F word.
"""

from __future__ import annotations

import re
from itertools import islice
from typing import Callable

import numpy as np

from galileo_cnc.config.machine import MIN_FEED_STEPS_PER_S, MachineConfig
from galileo_cnc.errors import GalileoError, SourcePos
from galileo_cnc.program.ops import COL, KIND, LINE, NM_PER_MM, VALUE, OpKind, Program

#: the profile's feeds a job runs at, by their key
PROFILE_FEEDS = ("feed_mm_s", "rapid_feed_mm_s", "z_feed_mm_s")
#: the F word at an op's column: how the file wrote the feed
_F_WORD = re.compile(r"[Ff]\s*[-+]?[0-9]*\.?[0-9]*")


class FeedError(GalileoError):
    """A feed of the file the machine cannot run; names the file line."""

    def __init__(self, message: str, pos: SourcePos):
        self.pos = pos
        self.message = message
        super().__init__(f"{pos}: {message}")


def rate_text(nm_per_s: int | float) -> str:
    """'10 mm/s (600 mm/min)', to 5 significant digits (a feed is kept in whole nm/s)."""
    mm_s = nm_per_s / NM_PER_MM
    return f"{_digits(mm_s)} mm/s ({_digits(mm_s * 60)} mm/min)"


def _digits(value: float) -> str:
    return f"{float(f'{value:.5g}'):g}"


def check_feeds(program: Program, config: MachineConfig) -> list[str]:
    """The warnings for `program` on the machine `config` (one line each); FeedError
    for a feed of the file the machine cannot run."""
    warn_nm_s = round(config.feed_warn_mm_s * NM_PER_MM)
    warn = (f"the warning feed {config.feed_warn_mm_s:g} mm/s ({config.feed_warn_mm_s * 60:g} "
            f"mm/min, feed_warn_mm_s in the profile): the motors may stall and lose steps")
    warnings = [f"warning: the profile's {key} = {getattr(config, key):g} mm/s "
                f"({getattr(config, key) * 60:g} mm/min) is above {warn}"
                for key in PROFILE_FEEDS if getattr(config, key) > config.feed_warn_mm_s]
    rows = np.flatnonzero(program.table[:, KIND] == OpKind.FEED)
    if not len(rows):
        return warnings
    values = program.table[rows, VALUE]
    steps = config.nm_to_steps_array(values)
    too_fast = steps > config.max_feed_steps_per_s
    too_slow = steps < MIN_FEED_STEPS_PER_S
    if too_fast.any() or too_slow.any():
        row = int(rows[np.flatnonzero(too_fast | too_slow)[0]])
        fast = bool(steps[rows == row][0] > config.max_feed_steps_per_s)
        raise _refusal(program, config, row, fast)
    over = np.flatnonzero(values > warn_nm_s)
    if len(over):
        first, fastest = int(rows[over[0]]), int(rows[over[np.argmax(values[over])]])
        words = _written(program, (first, fastest))
        text = f"warning: {_where(program, first)}: {words[first]} is " \
            f"{rate_text(int(program.table[first, VALUE]))}, above {warn}"
        if len(over) > 1:
            text += (f"; {len(over)} feeds of the file are above it, the fastest "
                     f"{words[fastest]} at line {int(program.table[fastest, LINE])} "
                     f"({rate_text(int(program.table[fastest, VALUE]))})")
        warnings.append(text)
    return warnings


def machine_refusal(program: Program, config: MachineConfig,
                    feed_refusal: Callable[[MachineConfig, float], str | None]) -> str | None:
    """The job's fastest drawing feed (the profile's `feed_mm_s`, or the file's fastest
    F word) as the connected machine judges it (`Machine.feed_refusal`: a GRBL board
    by its $110/$111), the refusal naming where that feed comes from; None if it runs."""
    fastest, where = round(config.feed_mm_s * NM_PER_MM), f"the profile's feed_mm_s = " \
        f"{config.feed_mm_s:g} mm/s ({config.feed_mm_s * 60:g} mm/min)"
    rows = np.flatnonzero(program.table[:, KIND] == OpKind.FEED)
    if len(rows):
        row = int(rows[np.argmax(program.table[rows, VALUE])])
        if int(program.table[row, VALUE]) > fastest:
            fastest = int(program.table[row, VALUE])
            where = f"{_where(program, row)}: {_written(program, (row,))[row]} is " \
                f"{rate_text(fastest)}"
    refusal = feed_refusal(config, fastest / NM_PER_MM)
    return f"{where}: {refusal}" if refusal is not None else None


def _refusal(program: Program, config: MachineConfig, row: int, fast: bool) -> FeedError:
    value = int(program.table[row, VALUE])
    word = _written(program, (row,))[row]
    steps = config.nm_to_steps(value)
    if fast:
        bound = config.max_feed_steps_per_s
        why = f"faster than the machine's limit of {_steps_rate(bound, config)}"
        bracket = f"[{steps} steps/s, at most {bound}]"
    else:
        bound = MIN_FEED_STEPS_PER_S
        why = f"slower than the machine's slowest feed of {_steps_rate(bound, config)}"
        bracket = f"[{steps} steps/s, at least {bound}]"
    pos = SourcePos(program.source, int(program.table[row, LINE]), int(program.table[row, COL]))
    return FeedError(f"{word} is {rate_text(value)}, {why} {bracket}", pos)


def _steps_rate(steps_per_s: int, config: MachineConfig) -> str:
    return rate_text(steps_per_s / config.steps_per_mm * NM_PER_MM)


def _where(program: Program, row: int) -> str:
    return f"{program.source}:{int(program.table[row, LINE])}"


def _written(program: Program, rows: tuple[int, ...]) -> dict[int, str]:
    """The F word of each row as its line of the file wrote it ('F600'); the feed in
    mm/min when the file cannot be read again (a Program made in memory)."""
    last = max(int(program.table[row, LINE]) for row in rows)
    words = {row: f"F{int(program.table[row, VALUE]) * 60 / NM_PER_MM:g}" for row in rows}
    try:
        with open(program.source, encoding="utf-8", errors="replace") as lines:
            for number, text in enumerate(islice(lines, last), start=1):
                for row in rows:
                    if int(program.table[row, LINE]) == number:
                        found = _F_WORD.match(text, max(int(program.table[row, COL]) - 1, 0))
                        if found:
                            words[row] = found.group(0).replace(" ", "")
    except OSError:
        pass
    return words
