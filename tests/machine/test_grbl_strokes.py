"""GRBL blends a stroke's corners with its own planner only if nothing in the stroke
makes it sync (docs/grbl.md, "Corners"): between the pen going down and going up the
G-code has motion lines only, on the pen as a Z axis and as a servo."""

from pathlib import Path

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.grbl.gcode import AxisScale, job_to_gcode, pen_from_config
from galileo_cnc.plan.pipeline import PlanOptions, plan_file

REPO = Path(__file__).resolve().parents[2]
SYNCS = ("G4", "M3", "M5", "G10", "$")


def strokes(lines, pen_down_text: str, pen_up_text: str) -> list[list[str]]:
    """The G-code lines of each stroke: after a pen-down line, up to a pen-up line."""
    out, current = [], None
    for text in (line.text for line in lines):
        if text.startswith(pen_up_text):
            if current:
                out.append(current)
            current = None
        elif current is not None:
            current.append(text)
        if text.startswith(pen_down_text):
            current = []
    return out


def test_a_stroke_has_motion_lines_only():
    job = plan_file(REPO / "samples" / "led-blinker.gbr", MachineConfig(), "auto",
                    options=PlanOptions(mode="ink")).job
    scale = AxisScale.from_texts(["160", "160", "160"])
    for pen, down, up in (("z", "G1 Z0", "G1 Z1.875"), ("servo", "M3 S1000", "M5")):
        config = MachineConfig(grbl_pen=pen)
        lines = job_to_gcode(job, scale, pen_from_config(config),
                             feed_steps_per_s=config.feed_steps_per_s)
        found = strokes(lines, down, up)
        if pen == "servo":      # the servo's dwell belongs to the pen change
            found = [s[1:] if s and s[0].startswith("G4") else s for s in found]
        assert len(found) >= 8 and sum(map(len, found)) > 400
        for stroke in found:
            assert all(text.split()[0] in ("G1", "G2", "G3") and "S" not in text
                       and not text.startswith(SYNCS) for text in stroke), stroke
