"""The job's head path from its commands (galileo_cnc/preview/job_path.py), which
`preview` and `plot --preview` draw instead of stepping the job: every event the
reference machine steps lies within a step or so of it, the picture is the stepped
one's but for pixels an edge grazes, and each stroke gets the same pen."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from galileo_cnc.config.machine import MachineConfig, pen_widths_from_text
from galileo_cnc.job import ArcTo, Flash, Jog, LineTo, PenDown, PenUp, Rapid, SetFeed
from galileo_cnc.machine import simulate
from galileo_cnc.machine.blocks import Pause
from galileo_cnc.machine.planner import JobSteps, ReferenceMachine
from galileo_cnc.plan.pipeline import PlanOptions, plan_file
from galileo_cnc.preview import render
from galileo_cnc.preview.job_path import JobPath
from galileo_cnc.preview.render import pen_stretches, render_preview

REPO = Path(__file__).resolve().parents[2]
CONFIG = MachineConfig()

# Lines, arcs both ways (a full circle, one ending off its circle), a flash, a jog,
# a line that moves Z and XY together: every command the path turns into events.
COMMANDS = [
    SetFeed(800), Rapid(400, 300), PenDown(), LineTo(1000, 300), LineTo(1000, 777),
    ArcTo(1000, 777, -200, 0, cw=False),              # full circle, r 200 steps
    ArcTo(700, 1100, -310, 20, cw=True),              # ends off its circle
    ArcTo(900, 1300, 200, 0, cw=False),
    LineTo(650, 1250, -40),                           # a plunge while moving
    PenUp(), Rapid(1500, 200), Flash(), Jog(33, -17, 0), PenDown(), Jog(-400, 250, 0),
    PenUp(),
]


def stepped_positions(commands, config=CONFIG):
    """Per command, the head positions (x, y) after each of its trace events."""
    machine = ReferenceMachine(config, (0, 0, 0))
    counts = [sum(item.n for item in machine.plan([command]) if not isinstance(item, Pause))
              for command in commands]
    trace = simulate(commands, config)
    moved = np.zeros((len(trace.tick), 3), dtype=np.int64)
    moved[np.arange(len(trace.tick)), trace.axis] = trace.dir
    # steps sharing a tick are one event (a diagonal step goes straight)
    event = np.concatenate(([0], np.cumsum(trace.tick[1:] != trace.tick[:-1])))
    positions = np.zeros((event[-1] + 2 if len(event) else 1, 3), dtype=np.int64)
    np.add.at(positions[1:], event, moved)
    positions = np.cumsum(positions, axis=0)
    assert sum(counts) == len(positions) - 1
    bounds = np.cumsum([1] + counts)
    return [positions[a:b] for a, b in zip(bounds[:-1], bounds[1:])], positions[0]


def distance_to_polyline(points, polyline):
    """Distance (steps) from each of `points` to the nearest segment of `polyline`."""
    a, b = polyline[:-1].astype(float), polyline[1:].astype(float)
    if len(a) == 0:
        return np.hypot(*(points - polyline[0]).T)
    d = b - a
    length2 = np.maximum((d * d).sum(axis=1), 1e-12)
    p = points[:, None, :].astype(float) - a[None]
    t = np.clip((p * d[None]).sum(axis=2) / length2, 0, 1)
    nearest = p - t[..., None] * d[None]
    return np.sqrt((nearest ** 2).sum(axis=2)).min(axis=1)


def test_every_stepped_event_lies_within_a_step_of_the_path():
    path = JobPath(COMMANDS, CONFIG)
    xyz = np.stack([path.x, path.y, path.z], axis=1).astype(np.int64)
    per_command, start = stepped_positions(COMMANDS)
    assert tuple(xyz[0]) == tuple(start) == (0, 0, 0)
    ends = np.append(path.command_event[1:], len(xyz))
    worst = 0.0
    for c, stepped in enumerate(per_command):
        first, stop = path.command_event[c], ends[c]
        mine = xyz[first - 1:stop]            # from where the command starts
        if not len(stepped):
            assert len(mine) == 1, COMMANDS[c]        # no move: no event either
            continue
        # the command ends exactly where the machine's does
        assert tuple(mine[-1]) == tuple(stepped[-1]), COMMANDS[c]
        far = distance_to_polyline(stepped[:, :2], mine[:, :2])
        worst = max(worst, float(far.max()))
    # a line's staircase is within a step; an arc's points within half a step of
    # the circle, the path's chords within a quarter; rounded to whole steps
    assert worst <= 1.5
    assert worst > 0                          # the staircase is not the path itself


def test_the_full_circle_and_the_arc_off_its_circle():
    path = JobPath(COMMANDS[:6], CONFIG)
    first = path.command_event[5]
    x, y = path.x[first - 1:].astype(float), path.y[first - 1:].astype(float)  # from its start
    radius = np.hypot(x - 800, y - 777)
    assert np.all(abs(radius - 200) <= 0.75)          # on its circle, rounded to steps
    angle = np.unwrap(np.arctan2(y - 777, x - 800))
    assert angle[-1] - angle[0] == pytest.approx(2 * math.pi, abs=0.02)   # once round


def draw_both(tmp_path, planned, config, **options):
    pictures = {}
    for name, source in (("stepped", JobSteps(planned.job.commands, config)),
                         ("path", JobPath(planned.job.commands, config))):
        out = tmp_path / f"{name}.png"
        info = render_preview(planned.program, source, config, planned.offset_nm, out,
                              job=planned.job, copper=planned.copper, pygerber_limit=0,
                              **options)
        pictures[name] = info, np.asarray(Image.open(out).convert("RGB"))
    return pictures["stepped"], pictures["path"]


def edge_pixels(image) -> np.ndarray:
    """Pixels with a neighbour (of the 8) of another colour."""
    edge = np.zeros(image.shape[:2], dtype=bool)
    padded = np.pad(image, ((1, 1), (1, 1), (0, 0)), mode="edge")
    height, width = image.shape[:2]
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            shifted = padded[1 + dr:1 + dr + height, 1 + dc:1 + dc + width]
            edge |= np.any(shifted != image, axis=2)
    return edge


@pytest.mark.parametrize("name, pens", [("led-blinker.gbr", "0.3,0.8"),
                                        ("led-blinker.gbr", "0.5")])
def test_the_preview_from_the_path_is_the_stepped_one(tmp_path, name, pens):
    config = CONFIG.replace(pen_widths_mm=pen_widths_from_text(pens))
    planned = plan_file(REPO / "samples" / name, config, options=PlanOptions(mode="ink"))
    # travel left out of the pictures: a 1 px line along the steps' staircase and
    # one along the straight path light different pixels (its length is compared)
    (stepped, a), (path, b) = draw_both(tmp_path, planned, config, travel=False)
    assert (path.width_px, path.height_px, path.view_mm) == \
        (stepped.width_px, stepped.height_px, stepped.view_mm)
    assert path.strokes == stepped.strokes
    assert path.stroke_box_mm == pytest.approx(stepped.stroke_box_mm, abs=1e-9)
    differ = np.any(a != b, axis=2)
    inked = np.any(a != np.asarray(render.BACKGROUND, np.uint8), axis=2)
    assert differ.sum() <= 0.005 * inked.sum()
    assert np.all(edge_pixels(a)[differ])             # only pixels an edge grazes
    assert path.travel_mm == pytest.approx(stepped.travel_mm, rel=0.002)
    # the stepped length is taken every 16th event, cutting the fill's corners;
    # the path's is the commands' own, which the stepped one can only fall short of
    assert path.drawn_mm >= stepped.drawn_mm
    assert path.drawn_mm == pytest.approx(stepped.drawn_mm, rel=0.05)
    assert path.uninked_mm2 == pytest.approx(stepped.uninked_mm2, abs=0.1 + 0.1 *
                                             stepped.uninked_mm2)
    assert path.outside_mm2 == pytest.approx(stepped.outside_mm2, abs=0.1 + 0.1 *
                                             stepped.outside_mm2)


def test_each_stroke_gets_the_pen_the_stepped_trace_gives_it(tmp_path):
    config = CONFIG.replace(pen_widths_mm=pen_widths_from_text("0.3,0.8"))
    planned = plan_file(REPO / "samples" / "led-blinker.gbr", config,
                        options=PlanOptions(mode="ink"))
    job = planned.job
    assert len(job.pen_changes) >= 1
    keys = []
    for source in (JobSteps(job.commands, config), JobPath(job.commands, config)):
        runs = render._scan_runs(source, (0, 0, 0), config)
        keys.append(pen_stretches(job, config, (0, 0, 0), source).key_at(runs.strokes[:, 0]))
    assert keys[0] == keys[1]
    assert len(set(keys[1])) == 2                     # both pens draw


def test_a_path_starts_where_it_was_made_for():
    path = JobPath(COMMANDS, CONFIG, (5, 6, 0))
    with pytest.raises(ValueError, match="starts at"):
        list(path.events((0, 0, 0)))
    assert [len(chunk[1]) for chunk in path.events((5, 6, 0))][0] == 1
