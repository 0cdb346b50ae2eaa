"""The planner: Program ops in nm -> machine commands in steps (docs/plan.md)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.job import ArcTo, Dwell, EndJob, Flash, LineTo, PenDown, PenUp, Rapid, SetFeed
from galileo_cnc.job import NO_OP
from galileo_cnc.machine import simulate
from galileo_cnc.plan.offsets import proposed_offset
from galileo_cnc.plan.planner import PlanError, plan_program
from galileo_cnc.program.ops import OpKind, ProgramBuilder
from galileo_cnc.readers import read_file

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "led-blinker.gbr"
CFG = MachineConfig()          # 160 steps/mm: 6250 nm per step
MM = 1_000_000
END = [PenUp(), EndJob()]


def program(*ops):
    """ops: (kind, x, y, i, j, tool, value); line numbers are 1, 2, 3, ..."""
    b = ProgramBuilder("t.gbr")
    for line, op in enumerate(ops, start=1):
        kind, *rest = op
        rest = list(rest) + [0] * (6 - len(rest))
        x, y, i, j, tool, value = rest
        b.emit(int(kind), x, y, i, j, tool if tool else -1, value, line=line, col=1)
    return b.build("gerber", "mm")


def plan(*ops, offset=(0, 0)):
    return plan_program(program(*ops), CFG, offset)


def test_move_line_flash_mapping_and_bookkeeping():
    job = plan((OpKind.SELECT, 0, 0, 0, 0, 11),
               (OpKind.MOVE, 1 * MM, 1 * MM),
               (OpKind.LINE, 2 * MM, 1 * MM, 0, 0, 11),
               (OpKind.LINE, 2 * MM, 3 * MM, 0, 0, 11),
               (OpKind.SELECT, 0, 0, 0, 0, 12),
               (OpKind.FLASH, 5 * MM, 5 * MM, 0, 0, 12))
    # two apertures: the pen is lifted before the second, and both are pen changes
    assert job.commands == [Rapid(160, 160), PenDown(), LineTo(320, 160), LineTo(320, 480),
                            PenUp(), Rapid(800, 800), Flash()] + END
    assert job.op_index == [1, 2, 2, 3, 5, 5, 5, NO_OP, NO_OP]
    assert job.aperture == [11, 11, 11, 11, 12, 12, 12, 12, 12]
    assert job.pen_changes == {1: 11, 5: 12}


def test_gerber_work_is_grouped_by_aperture_one_pen_change_each():
    job = plan((OpKind.SELECT, 0, 0, 0, 0, 10),
               (OpKind.FLASH, 1 * MM, 1 * MM, 0, 0, 10),
               (OpKind.SELECT, 0, 0, 0, 0, 11),
               (OpKind.MOVE, 2 * MM, 2 * MM),
               (OpKind.LINE, 3 * MM, 2 * MM, 0, 0, 11),
               (OpKind.SELECT, 0, 0, 0, 0, 10),
               (OpKind.FLASH, 4 * MM, 4 * MM, 0, 0, 10),
               (OpKind.SELECT, 0, 0, 0, 0, 11),
               (OpKind.LINE, 3 * MM, 5 * MM, 0, 0, 11))     # draws from the flash at (4, 4)
    assert job.grouped
    assert job.commands == [PenUp(), Rapid(160, 160), Flash(), Rapid(640, 640), Flash(),
                            # D11: the path, then the line that started at the D10 flash
                            Rapid(320, 320), PenDown(), LineTo(480, 320),
                            Rapid(640, 640), PenDown(), LineTo(480, 800)] + END
    assert job.pen_changes == {1: 10, 6: 11}   # D11 is inserted over its first stroke
    assert job.op_index[:5] == [1, 1, 1, 6, 6]
    # the file's order on request: four pen changes
    in_order = plan_program(job_program := program(
        (OpKind.SELECT, 0, 0, 0, 0, 10), (OpKind.FLASH, 1 * MM, 1 * MM, 0, 0, 10),
        (OpKind.SELECT, 0, 0, 0, 0, 11), (OpKind.MOVE, 2 * MM, 2 * MM),
        (OpKind.LINE, 3 * MM, 2 * MM, 0, 0, 11), (OpKind.SELECT, 0, 0, 0, 0, 10),
        (OpKind.FLASH, 4 * MM, 4 * MM, 0, 0, 10)), CFG, group=False)
    assert not in_order.grouped and len(in_order.pen_changes) == 3
    assert len(job_program) == 7


def test_runs_of_draws_keep_their_pen_changes_and_drop_draws_that_go_nowhere():
    # plan_program copies a run of draws of one aperture (or of none) in whole: the
    # draw of another aperture inside it still lifts the pen for the change, a draw
    # without an aperture keeps the one in force, a draw to where it is makes nothing
    job = plan_program(program((OpKind.SELECT, 0, 0, 0, 0, 10),
                               (OpKind.MOVE, 1 * MM, 1 * MM),
                               (OpKind.LINE, 2 * MM, 1 * MM, 0, 0, 10),
                               (OpKind.LINE, 2 * MM, 1 * MM, 0, 0, 10),
                               (OpKind.ARC_CW, 3 * MM, 2 * MM, 1 * MM, 0, 10),
                               (OpKind.LINE, 3 * MM, 3 * MM, 0, 0, 11),
                               (OpKind.LINE, 4 * MM, 3 * MM),
                               (OpKind.LINE, 5 * MM, 3 * MM, 0, 0, 11)), CFG, group=False)
    assert job.commands == [Rapid(160, 160), PenDown(), LineTo(320, 160),
                            ArcTo(480, 320, 160, 0, cw=True), PenUp(), PenDown(),
                            LineTo(480, 480), LineTo(640, 480), LineTo(800, 480)] + END
    assert job.op_index == [1, 2, 2, 4, 5, 5, 5, 6, 7, NO_OP, NO_OP]
    assert job.aperture == [10, 10, 10, 10, 11, 11, 11, 11, 11, 11, 11]
    assert job.pen_changes == {1: 10, 5: 11}           # asked for after the PenUp


def test_a_long_run_of_draws_reports_progress_every_so_many_ops():
    from galileo_cnc.plan.planner import PROGRESS_OPS

    count = 2 * PROGRESS_OPS + 500
    rows = [(OpKind.MOVE, 0, 0)] + [(OpKind.LINE, (k % 2) * MM, k * 10_000, 0, 0, 10)
                                    for k in range(1, count)]
    marks = []
    job = plan_program(program(*rows), CFG, on_progress=lambda done, total: marks.append(
        (done, total)))
    assert marks == [(done, count) for done in (0, PROGRESS_OPS, 2 * PROGRESS_OPS, count)]
    assert sum(isinstance(c, LineTo) for c in job.commands) == count - 1


def test_region_outlines_draw_with_the_selected_aperture_and_one_pen_needs_no_change():
    job = plan((OpKind.SELECT, 0, 0, 0, 0, 12),
               (OpKind.REGION_BEGIN,), (OpKind.MOVE, 1 * MM, 1 * MM),
               (OpKind.LINE, 2 * MM, 1 * MM), (OpKind.LINE, 1 * MM, 1 * MM),
               (OpKind.REGION_END,),
               (OpKind.FLASH, 5 * MM, 5 * MM, 0, 0, 12))
    assert job.pen_changes == {} and not job.grouped
    assert set(job.aperture) == {12}


def test_gcode_keeps_its_order():
    b = ProgramBuilder("t.nc")
    b.emit(int(OpKind.SELECT), tool=1, line=1)
    b.emit(int(OpKind.MOVE), 1 * MM, 1 * MM, line=2)
    b.emit(int(OpKind.LINE), 2 * MM, 1 * MM, tool=1, line=3)
    b.emit(int(OpKind.SELECT), tool=2, line=4)
    b.emit(int(OpKind.LINE), 2 * MM, 2 * MM, tool=2, line=5)
    b.emit(int(OpKind.SELECT), tool=1, line=6)
    b.emit(int(OpKind.LINE), 1 * MM, 2 * MM, tool=1, line=7)
    job = plan_program(b.build("gcode", "mm"), CFG)
    assert not job.grouped
    assert [c for c in job.commands if isinstance(c, LineTo)] == [
        LineTo(320, 160), LineTo(320, 320), LineTo(160, 320)]
    assert list(job.pen_changes.values()) == [1, 2, 1]


def test_pen_ops_dwell_feed_and_markers():
    job = plan((OpKind.POLARITY, 0, 0, 0, 0, 0, 1),
               (OpKind.FEED, 0, 0, 0, 0, 0, 10 * MM),            # 10 mm/s = 1600 steps/s
               (OpKind.PEN_DOWN,), (OpKind.DWELL, 0, 0, 0, 0, 0, 150), (OpKind.PEN_UP,),
               (OpKind.REGION_BEGIN,),
               (OpKind.MOVE, 1 * MM, 1 * MM),
               (OpKind.LINE, 2 * MM, 1 * MM),
               (OpKind.LINE, 1 * MM, 1 * MM),
               (OpKind.REGION_END,))
    assert job.commands == [SetFeed(1600), PenDown(), Dwell(150), PenUp(), Rapid(160, 160),
                            PenDown(), LineTo(320, 160), LineTo(160, 160)] + END


def test_arcs_round_the_centre_and_keep_the_direction():
    # start (2 mm, 2 mm) = (320, 320); centre x = 3.01 mm = 481.6 -> 482 steps, so
    # i = 162; the end 4.02 mm = 643.2 -> 643, so on the way back i = 482 - 643 = -161
    # (rounding i itself would give -162: the centre would move by a step).
    job = plan((OpKind.MOVE, 2 * MM, 2 * MM),
               (OpKind.ARC_CCW, 4_020_000, 2 * MM, 1_010_000, 0),
               (OpKind.ARC_CW, 2 * MM, 2 * MM, -1_010_000, 0))
    assert job.commands == [Rapid(320, 320), PenDown(),
                            ArcTo(643, 320, 162, 0, cw=False),
                            ArcTo(320, 320, -161, 0, cw=True)] + END
    # The end misses the rounded circle by a step: the machine corrects (motion.md §4.6).
    simulate(job.commands, CFG)


def test_full_circle_stays_a_full_circle():
    job = plan((OpKind.MOVE, 4 * MM, 4 * MM), (OpKind.ARC_CW, 4 * MM, 4 * MM, -2 * MM, 0))
    assert job.commands[2] == ArcTo(640, 640, -320, 0, cw=True)
    trace = simulate(job.commands, CFG)
    assert len(trace.tick) > 4 * 320


def test_offset_is_subtracted_and_rounding_is_the_configs():
    offset = (10 * MM, 20 * MM)
    # 3125 nm is half a step: away from zero; 3124 rounds down.
    job = plan((OpKind.MOVE, 11 * MM + 3125, 21 * MM + 3124),
               (OpKind.LINE, 12 * MM - 3125, 21 * MM), offset=offset)
    assert job.commands[0] == Rapid(161, 160)
    assert job.commands[2] == LineTo(CFG.nm_to_steps(2 * MM - 3125), 160) == LineTo(320, 160)


def test_zero_length_moves_are_dropped_but_a_dot_still_lowers_the_pen():
    job = plan((OpKind.MOVE, 1 * MM, 1 * MM), (OpKind.MOVE, 1 * MM + 1000, 1 * MM),
               (OpKind.LINE, 1 * MM, 1 * MM + 2000), (OpKind.LINE, 2 * MM, 1 * MM),
               (OpKind.FLASH, 2 * MM, 1 * MM))
    assert job.commands == [Rapid(160, 160), PenDown(), LineTo(320, 160), Flash()] + END


def test_soft_limit_refuses_the_job_and_names_the_op():
    with pytest.raises(PlanError) as info:
        plan((OpKind.MOVE, 1 * MM, 1 * MM), (OpKind.LINE, 5 * MM, 1 * MM),
             (OpKind.LINE, 5 * MM, -1 * MM), (OpKind.LINE, 1 * MM, 1 * MM))
    err = info.value
    assert (err.axis, err.op_index, err.pos.line) == ("Y", 2, 3)
    assert str(err).startswith("t.gbr:3:1: the line from X 5 Y 1 to X 5 Y -1 mm (file coordinates): ")
    assert "Y would reach -1.000 mm, below the travel's start at 0.000 mm [-160 steps]" in str(err)
    with pytest.raises(PlanError) as info:
        plan((OpKind.MOVE, 100 * MM, 100 * MM),
             (OpKind.ARC_CW, 100 * MM, 100 * MM, 0, 60 * MM))   # circle reaches Y = 220 mm
    assert (info.value.axis, info.value.pos.line) == ("Y", 2)
    assert "Y would reach 220.000 mm, beyond the travel's end at 200.000 mm [35200 steps]" in str(info.value)


def test_sample_board_with_the_proposed_offset_simulates_and_ends_pen_up():
    program = read_file(SAMPLE)
    job = plan_program(program, CFG, proposed_offset(program))
    assert job.commands[-2:] == END
    assert sum(isinstance(c, Flash) for c in job.commands) == 10
    assert sum(isinstance(c, ArcTo) for c in job.commands) == 3
    trace = simulate(job.commands, CFG)
    assert trace.final_position[2] == CFG.pen_up_z_steps
    assert len(job.op_index) == len(job.aperture) == len(job.commands)
    # 10 mm off in X puts the ground region (X = 6 mm, file line 70) out of the travel.
    with pytest.raises(PlanError) as info:
        plan_program(program, CFG, (10 * MM, 0))
    assert info.value.axis == "X" and info.value.pos.line == 70


def test_an_arc_beyond_the_machines_arc_range_is_drawn_as_chords_within_half_a_step():
    from galileo_cnc.job import ArcTo, LineTo
    from galileo_cnc.machine.arcs import MAX_ARC_COORD
    from galileo_cnc.readers.gcode import read_gcode

    config = MachineConfig()
    radius_mm = 300                                   # 48,000 steps: past 32,767
    assert radius_mm * config.steps_per_mm > MAX_ARC_COORD
    # a 20 degree piece of a 300 mm circle (centre far above), and a small arc after it
    program = read_gcode("flat.nc", "G21 G90\nG0 X10 Y5\nM3\n"
                         "G3 X112.606043 Y23.092214 I0 J300\nG2 X114.606043 Y23.092214 I1 J0\n")
    job = plan_program(program, config)
    chords = [c for c in job.commands if isinstance(c, LineTo)]
    arcs = [c for c in job.commands if isinstance(c, ArcTo)]
    assert len(arcs) == 1 and len(chords) > 10
    centre = (10 * config.steps_per_mm, 305 * config.steps_per_mm)
    for chord in chords:                            # every chord end on the circle
        distance = math.hypot(chord.x_steps - centre[0], chord.y_steps - centre[1])
        assert abs(distance - radius_mm * config.steps_per_mm) <= 1.0
    end = (config.nm_to_steps(112_606_043), config.nm_to_steps(23_092_214))
    assert (chords[-1].x_steps, chords[-1].y_steps) == end


def test_an_arc_within_half_a_step_of_its_chord_is_sent_as_a_line():
    # 1-step pieces of a 12.5 mm circle (sagitta 0.00006 step) become lines to the same
    # end step; a semicircle of one step's radius, a quarter of a 2-step circle
    # (sagitta 0.59 step) and a full circle stay arcs
    from galileo_cnc.readers.gcode import read_gcode

    def on_circle(k):                   # 5 mm + a point of the circle round (-7.5, 5) mm
        return 12.5 * math.cos(k / 2000) - 7.5, 5 + 12.5 * math.sin(k / 2000)

    pieces = []
    for k in range(1, 6):
        (x0, y0), (x, y) = on_circle(k - 1), on_circle(k)
        pieces.append(f"G3 X{x:.6f} Y{y:.6f} I{-7.5 - x0:.6f} J{5 - y0:.6f}")
    text = ("G21 G90\nG0 X5 Y5\nM3\n" + "\n".join(pieces)
            + "\nG0 X20 Y5\nM3\nG2 X20.0125 Y5 I0.00625 J0\n"
            + "G0 X30 Y5\nM3\nG3 X30.0125 Y5.0125 I0 J0.0125\n"
            + "G0 X40 Y5\nM3\nG2 X40 Y5 I1 J0\n")
    job = plan_program(read_gcode("short-arcs.nc", text), CFG)
    drawn = [c for c in job.commands if isinstance(c, (LineTo, ArcTo))]
    assert [type(c).__name__ for c in drawn] == ["LineTo"] * 5 + ["ArcTo"] * 3
    assert [(c.x_steps, c.y_steps) for c in drawn[:5]] == \
        [(round(160 * on_circle(k)[0]), round(160 * on_circle(k)[1])) for k in range(1, 6)]
    simulate(job.commands, CFG)


def test_an_arc_whose_ends_round_to_one_step_is_a_point_unless_it_goes_the_long_way(tmp_path):
    # LimeSDR's top layer (Altium) has 0.4 um arcs on a 0.88 mm radius: both ends round
    # to one step, and an arc ending where it starts is a whole circle to the machine,
    # so each one drew a 1.76 mm ring of ink across other copper. The short way round
    # is a point; the long way (end 0.4 um behind the start) is still the circle.
    path = tmp_path / "slivers.gbr"
    path.write_text("%FSLAX44Y44*%\n%MOMM*%\n%ADD13C,0.2*%\nG75*\nD13*\n"
                    "X479328Y288650D02*\nG03*\nX479332Y288650I4J8812D01*\n"
                    "G01*\nX489328Y288650D02*\nG03*\nX489324Y288650I4J8812D01*\nM02*\n")
    job = plan_program(read_file(path), CFG)
    drawn = [c for c in job.commands if isinstance(c, (LineTo, ArcTo))]
    assert len(drawn) == 1 and isinstance(drawn[0], ArcTo)
    start = job.commands[job.commands.index(drawn[0]) - 2]           # Rapid, PenDown, ArcTo
    assert (drawn[0].x_steps, drawn[0].y_steps) == (start.x_steps, start.y_steps) == \
        (round(48.9328 * 160), round(28.865 * 160))
    without = [c for c in job.commands if c is not drawn[0]]
    circle = (simulate(job.commands, CFG).steps_per_axis()[:2].sum()
              - simulate(without, CFG).steps_per_axis()[:2].sum())
    assert circle == 8 * round(0.8812 * 160)      # X and Y each go 4 radii round a circle


def test_centre_mode_keeps_one_pen_per_d_code_under_load_transforms(tmp_path):
    # D10 flashed plain, turned by %LR30 and plain again: three dots, one pen (a dot is
    # a dot at any angle); the reader's derived aperture must not ask for a second pen.
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file
    path = tmp_path / "turned.gbr"
    path.write_text("%FSLAX26Y26*%\n%MOMM*%\n%ADD10R,1X0.5*%\nD10*\nX0Y0D03*\n%LR30*%\n"
                    "X5000000Y0D03*\n%LR0*%\nX9000000Y0D03*\nM02*\n")
    planned = plan_file(path, MachineConfig(), options=PlanOptions(mode="centre"))
    assert list(planned.job.pen_labels) == [10]
    assert sum(isinstance(c, Flash) for c in planned.job.commands) == 3


def test_what_the_wire_cannot_carry_is_refused_while_planning_with_its_line(tmp_path):
    # G4 P1000000000 used to be planned and then refused by the link after the
    # machine had drawn the first line; now the plan refuses it, naming line 3.
    from galileo_cnc.plan.pipeline import plan_file
    path = tmp_path / "long-dwell.nc"
    path.write_text("G21 G90\nG1 X1 F100\nG4 P1000000000\nG1 X2\nM2\n")
    with pytest.raises(PlanError, match=r"a dwell of 1000000 s is longer than a machine command "
                       r"carries \(2000 s at most\) \[ms=1000000000 outside 0\.\.2000000\]") as refused:
        plan_file(path, MachineConfig())
    assert refused.value.pos.line == 3
    path.write_text("G21 G90\nG1 X1 F100\nG4 P2000\nG1 X2\nM2\n")     # 2000 s: the limit
    assert plan_file(path, MachineConfig()).job


def test_the_quick_travel_check_never_passes_a_job_the_machine_refuses():
    # check_job skips stepping the reference machine when every point and every arc's
    # circle lies inside the travel (planner._surely_inside): on random jobs of lines
    # and arcs (ends on and off their circles) near the travel's edges, whenever it
    # says inside, the machine must agree; and it must say inside often enough to matter
    import random

    from galileo_cnc.job import MachineError
    from galileo_cnc.machine import ReferenceMachine
    from galileo_cnc.plan.planner import _surely_inside

    rng = random.Random(7)
    (x_min, y_min, _), (x_max, y_max, _) = CFG.travel_min_steps, CFG.travel_max_steps
    quick = 0
    for _ in range(400):
        x = y = 0
        commands = []
        for _ in range(6):
            if rng.random() < 0.5:
                x = rng.randint(x_min, x_max)
                y = rng.choice([rng.randint(y_min, y_max), rng.randint(y_min, y_min + 40),
                                rng.randint(y_max - 40, y_max)])
                commands.append(LineTo(x, y))
            else:
                r = rng.randint(1, 60)
                cx = rng.randint(x - 2 * r, x + 2 * r)
                cy = rng.randint(y - 2 * r, y + 2 * r)
                angle = rng.uniform(0, 2 * math.pi)
                radius = math.hypot(x - cx, y - cy) + rng.choice([0, 0, 1, -1, 3])
                end = (round(cx + radius * math.cos(angle)), round(cy + radius * math.sin(angle)))
                commands.append(ArcTo(end[0], end[1], cx - x, cy - y, cw=rng.random() < 0.5))
                x, y = end
        commands = [PenDown(), *commands, *END]
        if not _surely_inside(commands, CFG):
            continue
        quick += 1
        try:
            ReferenceMachine(CFG).plan(commands)
        except MachineError as problem:
            raise AssertionError(f"passed quickly, refused by the machine: {problem}; "
                                 f"{commands}") from None
    assert quick > 50


def test_the_rows_verdict_passes_only_jobs_the_command_walks_pass():
    # plan_program skips check_job when the rows' arrays say the job surely passes
    # (planner._rows_surely_fine): on random programs of moves, lines, arcs and
    # flashes near the travel's edges, offset at random, whenever the rows say so the
    # job's own commands pass both of check_job's walks; and it says so often enough
    import random

    from galileo_cnc.plan.planner import _machine_points, _surely_inside
    from galileo_cnc.protocol.codec import first_range_problem

    rng = random.Random(11)
    step = CFG.nm_per_step
    (x_min, y_min, _), (x_max, y_max, _) = CFG.travel_min_steps, CFG.travel_max_steps
    fine = refused = 0
    for _ in range(800):
        ops = [(OpKind.SELECT, 0, 0, 0, 0, 10)]
        for number in range(rng.randint(1, 6)):
            kind = rng.choice([OpKind.MOVE, OpKind.LINE, OpKind.LINE, OpKind.ARC_CW,
                               OpKind.ARC_CCW, OpKind.FLASH])
            if number == 0 and kind in (OpKind.ARC_CW, OpKind.ARC_CCW):
                kind = OpKind.MOVE
            edge = rng.choice([x_min, x_max]), rng.choice([y_min, y_max])
            nx = rng.choice([rng.randint(x_min, x_max), edge[0] + rng.randint(-30, 30)]) * step
            ny = rng.choice([rng.randint(y_min, y_max), edge[1] + rng.randint(-30, 30)]) * step
            if kind in (OpKind.ARC_CW, OpKind.ARC_CCW):
                r = rng.randint(2, 80) * step
                angle = rng.uniform(0, 2 * math.pi)
                i, j = round(r * math.cos(angle)), round(r * math.sin(angle))
                ops.append((kind, nx, ny, i, j, 10))
            else:
                ops.append((kind, nx, ny, 0, 0, 10))
        offset = (rng.randint(-40, 40) * step, rng.randint(-40, 40) * step)
        built = program(*ops)
        verdict = _machine_points(built.table, CFG, offset).surely_fine
        try:
            job = plan_program(built, CFG, offset)
        except PlanError:
            refused += 1
            assert not verdict, f"the rows passed a job check_job refuses: {ops}, {offset}"
            continue
        if verdict:
            fine += 1
            assert _surely_inside(job.commands, CFG), (ops, offset)
            assert first_range_problem(job.commands) is None
    assert fine > 50 and refused > 20


def test_a_job_too_big_names_the_axis_and_the_profile_key_that_sets_the_travel(tmp_path):
    from dataclasses import replace

    from galileo_cnc.plan.pipeline import load_artwork

    tall = tmp_path / "tall.nc"                 # 10 mm wide, 150 mm tall
    tall.write_text("G21 G90\nG0 X0 Y0\nM3\nG1 X10 Y150\nM5\n")
    artwork = load_artwork(tall)
    assert artwork.misfit(MachineConfig()) is None
    narrow = replace(MachineConfig(), x_travel_mm=8.0)
    assert artwork.misfit(narrow).endswith(
        "the job is 10.0 mm wide (with its travel moves); the machine's travel is 8 mm "
        "(x_travel_mm in the profile)")
    short = replace(MachineConfig(), y_travel_mm=100.0)
    assert artwork.misfit(short).endswith(
        "the job is 150.0 mm tall (with its travel moves); the machine's travel is 100 mm "
        "(y_travel_mm in the profile)")
