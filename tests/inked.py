"""What a job drew, whatever the order: the set of XY points where a step left the
head at the drawing height. A stopped and resumed job retraces part of a command
and travels pen up to it, so its trace differs from an uninterrupted one, but the
points it inked must be exactly the same."""

from __future__ import annotations

from galileo_cnc.config.machine import MachineConfig


def inked_points(trace, config: MachineConfig | None = None,
                 start: tuple[int, int, int] = (0, 0, 0)) -> set[tuple[int, int]]:
    config = config or MachineConfig()
    where = trace.positions(start)
    down = where[:, 2] == config.pen_down_z_steps
    return set(map(tuple, where[down, :2].tolist()))


def ink_of_trace(trace, config: MachineConfig, offset_nm: tuple[int, int],
                 widths_nm: list[int], start: tuple[int, int, int] = (0, 0, 0)) -> list:
    """The area the pens inked, from the steps: each pen-down run of the trace as a
    polyline in program nm, swept by the pen's disc (pyclipper polygon set). With
    several widths the narrowest is used for every run (a lower bound of the ink)."""
    from galileo_cnc.plan.ink import clip

    where = trace.positions(start)
    down = where[:, 2] == config.pen_down_z_steps
    runs, current = [], []
    for point, is_down in zip(where[:, :2].tolist(), down.tolist()):
        if is_down:
            current.append(point)
        elif current:
            runs.append(current)
            current = []
    if current:
        runs.append(current)
    step = config.nm_per_step
    paths = [[[x * step + offset_nm[0], y * step + offset_nm[1]] for x, y in run]
             for run in runs]
    return clip.stroke(paths, min(widths_nm) // 2, 1000)


def joined_islands(ink: list, copper: list, gap_nm: int) -> list[list[int]]:
    """Groups of copper islands that the ink joins or brings within `gap_nm` of each
    other although the copper alone keeps them that far apart: both sets grown by
    gap / 2, the islands (numbered as clip.components(copper) gives them) grouped by
    the piece of grown copper | ink they fall in. Empty when the ink bridges nothing."""
    import shapely

    from galileo_cnc.plan.ink import clip

    islands = [shapely.Polygon(outer, holes) for outer, holes in clip.components(copper)]
    points = [island.representative_point() for island in islands]

    def group(polygons):
        pieces = [shapely.Polygon(o, h) for o, h in
                  clip.components(clip.offset(polygons, gap_nm // 2, 1000))]
        tree = shapely.STRtree(pieces)
        where, which = tree.query(points, predicate="intersects")
        label = [-1] * len(points)
        for k, piece in zip(where.tolist(), which.tolist()):
            label[k] = piece
        return label

    alone, inked = group(copper), group(clip.union(copper, ink) if ink else copper)
    groups: dict[int, set[int]] = {}
    for k, piece in enumerate(inked):
        groups.setdefault(piece, set()).add(alone[k])
    return [sorted(k for k, piece in enumerate(inked) if piece == p)
            for p, apart in groups.items() if len(apart) > 1]


def plan_and_ink(path, pen_nm: int, config: MachineConfig):
    """(planned job, ink from the steps, copper) of a Gerber file planned in ink mode
    with one pen and stepped by the reference machine."""
    from galileo_cnc.machine.planner import simulate
    from galileo_cnc.plan.pipeline import PlanOptions, plan_file

    planned = plan_file(path, config, "auto",
                        options=PlanOptions(mode="ink", pens_nm=(pen_nm,)))
    trace = simulate(planned.job.commands, config)
    ink = ink_of_trace(trace, config, planned.offset_nm, [pen_nm])
    return planned, ink, planned.ink.copper.native


def box(x0: int, y0: int, x1: int, y1: int) -> list:
    """The rectangle as a polygon set (nm)."""
    return [[[x0, y0], [x1, y0], [x1, y1], [x0, y1]]]


def bare_within(copper: list, ink: list, area: list) -> float:
    """The copper inside `area` that the ink leaves bare (nm²)."""
    from galileo_cnc.plan.ink import clip

    return clip.area_nm2(clip.difference(clip.intersection(copper, area), ink))
