"""Open traces: the trace pieces an ink plan leaves out, said as one summary.

A centre line (a trace narrower than the smallest pen) is cut where its ink would
join another copper island (plan/ink/narrow.py, keep_islands_apart): the board is
drawn with open nets there. Every front end (plot, getg, preview, convert, info)
says it the same way, from here: how many pieces, how long in all and the longest
(with its file line), and the widest pen that would draw every trace of the board.
"""

from __future__ import annotations

from dataclasses import dataclass

from galileo_cnc.errors import SourcePos
from galileo_cnc.plan.widths import mm_text

#: the widest pen is said to this step (0.01 mm), rounded down
PEN_STEP_NM = 10_000


@dataclass(frozen=True)
class OpenTraces:
    """What an ink plan leaves out of its traces (lengths in nm)."""

    pieces: int
    total_nm: int
    longest_nm: int
    longest_at: SourcePos           # the file line of the trace the longest piece is of
    pen_nm: int                     # the pen that draws the centre lines (the smallest)
    widest_pen_nm: int              # the widest pen that leaves no piece out (0: none)

    def text(self) -> str:
        """One paragraph for the user, in mm."""
        s = "s" * (self.pieces != 1)
        pen_nm = self.widest_pen_nm // PEN_STEP_NM * PEN_STEP_NM     # down: it must fit
        if pen_nm > 0:
            remedy = (f"a pen of {mm_text(pen_nm)} mm or thinner (--pens) "
                      "would draw every trace of this board")
        else:
            remedy = "no pen would draw every trace: some come closer than the ink's clearance"
        return (f"open traces: {self.pieces:,} trace piece{s} left out, "
                f"{mm_text(self.total_nm)} mm in all, the longest {mm_text(self.longest_nm)} mm "
                f"(at {self.longest_at}): the {mm_text(self.pen_nm)} mm pen's ink would join "
                f"another copper island there; {remedy}")


def open_traces(ink) -> OpenTraces | None:
    """The summary of an InkPlan's (or InkPaths') left-out pieces; None if it leaves
    none out (or there is no ink plan)."""
    bridges = getattr(ink, "bridges", None)
    if not bridges:
        return None
    longest = max(bridges, key=lambda bridge: bridge.left_out_nm)
    return OpenTraces(pieces=len(bridges),
                      total_nm=sum(bridge.left_out_nm for bridge in bridges),
                      longest_nm=longest.left_out_nm, longest_at=longest.feature.pos,
                      pen_nm=longest.feature.pen_nm,
                      widest_pen_nm=min(bridge.widest_pen_nm for bridge in bridges))


def ink_warnings(ink, verbose: bool = False) -> list[str]:
    """The ink plan's warnings for the user: one per left-out piece is the summary
    instead (every piece with `verbose`, then the summary)."""
    texts = [str(w) for w in ink.warnings]
    summary = open_traces(ink)
    if summary is None:
        return texts
    first, end = ink.bridge_warnings.start, ink.bridge_warnings.stop
    pieces = texts[first:end] if verbose else []
    return texts[:first] + pieces + [summary.text()] + texts[end:]
