"""The G and M codes the reader knows: what each one is, and what it refuses.

Keys are canonical code numbers as `lexer.code_number` makes them ('1', '92.1').
Codes in one modal group may not share a line (two motions, G90 with G91, ...).
"""

from __future__ import annotations

# G code -> modal group. The reader dispatches on the group, then on the code.
G_GROUPS = {
    "0": "motion", "1": "motion", "2": "motion", "3": "motion",
    "4": "non-modal", "28": "non-modal", "92": "non-modal", "92.1": "non-modal",
    "17": "plane",
    "20": "units", "21": "units",
    "90": "distance", "91": "distance",
    "90.1": "arc-distance", "91.1": "arc-distance",
    # Defaults that CAM programs state in their preamble; they change nothing here.
    "40": "no-op",   # cutter compensation off
    "49": "no-op",   # tool length offset off
    "54": "no-op",   # first work coordinate system (the only one)
    "61": "no-op",   # exact path
    "64": "no-op",   # path blending: the planner decides
    "80": "no-op",   # canned cycle off
    "94": "no-op",   # feed in units per minute
}

# Known G codes that this plotter cannot honour, with the reason the user sees.
G_REFUSED = {
    "18": "G18 (XZ plane) is not supported: this machine draws in the XY plane only",
    "19": "G19 (YZ plane) is not supported: this machine draws in the XY plane only",
    "41": "G41 (cutter radius compensation) is not supported: offset the path in the CAM",
    "42": "G42 (cutter radius compensation) is not supported: offset the path in the CAM",
    "43": "G43 (tool length offset) is not supported",
    "55": "G55 (second work coordinate system) is not supported: use G92",
    "56": "G56 (work coordinate system) is not supported: use G92",
    "57": "G57 (work coordinate system) is not supported: use G92",
    "58": "G58 (work coordinate system) is not supported: use G92",
    "59": "G59 (work coordinate system) is not supported: use G92",
    "93": "G93 (inverse time feed) is not supported: give F in units per minute (G94)",
}

MOTION_RAPID, MOTION_LINE, MOTION_CW, MOTION_CCW = "0", "1", "2", "3"

# M code -> what it does. Unknown M codes are warnings, not errors.
M_PEN_DOWN = ("3", "4")   # spindle on (either direction) = pen down
M_PEN_UP = ("5",)
M_END = ("2", "30")
M_TOOL_CHANGE = ("6",)    # the T word already selected the pen
M_MOTORS = ("17", "18", "84")  # the planner powers the motors for each job
M_PAUSE = ("0", "1")      # GRBL waits for cycle start; the plotter asks at pen changes (T)
M_PEN = M_PEN_DOWN + M_PEN_UP
M_KNOWN = set(M_PEN_DOWN + M_PEN_UP + M_END + M_TOOL_CHANGE + M_MOTORS + M_PAUSE)

# Parameter letters the reader accepts besides G, M and N.
# S (spindle speed, or a servo pen's angle) is accepted and ignored.
PARAMETER_LETTERS = frozenset("XYZIJRFPTS")
