"""Inking the copper, measured from the machine's steps against pygerber's raster of
every copper layer of the corpus, ink mode beside centre mode, in one run.

    python3 bench/bench_ink.py                    # every copper layer, ink and centre
    python3 bench/bench_ink.py --quick            # a handful of small copper layers
    python3 bench/bench_ink.py --selftest         # check the measurement itself
    python3 bench/bench_ink.py --files 'kicad/*' --pens 0.3,0.8 --modes ink
    python3 bench/bench_ink.py --modes centre --jobs 2 --png /tmp/ink --json /tmp/ink.json

Copper layers: those bench_ink_union.py takes (`looks_like_copper` on the 'real' and
'derived' files of the manifest). Each file is measured in its own child process
(`--jobs` at a time, `--timeout` s and `--max-gb` of address space each), so one
failure, hang or memory blow-up costs that file only; failures are printed with the
reason. Numbers are printed, never asserted. `--png DIR` saves an overlay per file and
mode (copper inked green, missed red, ink outside in the allowance orange, the rest
blue; row 0 at the grid's top, `grid_left_top_mm` in the --json records).

What is measured, per file and mode
-----------------------------------
Planning: `plan_file(path, config, "auto", options=PlanOptions(mode=...))` (ink:
`pens_nm` from `--pens`); when the checkout has no PlanOptions, centre mode only
through the old `plan_file(path, config, "auto")`, and one line says so. The machine
is the default MachineConfig with 2 m of travel, so every board fits. Timed: the
whole `plan_file` from the path (reading included), wall and CPU; "read" is
`load_artwork` alone, for scale. The planning target is judged on the wall time of
the largest layer planned alone after the run (`--alone` times, each in a fresh
process with nothing else running: the median), since with `--jobs 2` the run's own
planning shares both cores with another file; the CPU time counts the planner's
forked helpers too (the fill's gap tests).

The ink comes from the STEPS, not from the planned paths. The job is cut into parts
at its pen changes (`job.pen_changes`) and wherever the pen key of a drawing command
(`job.aperture[i]`) changes; one ReferenceMachine plans the parts in turn (each part
continues from the state the last one left: position, feed) and the vectorised
reference steps them. Each stretch of events with Z == config.pen_down_z_steps is
one pen-down stretch (a lift follows it); one that never moves is a dot (a Flash).
Its events are thinned to chords that stay within `--tol` steps (0.5 = 3.1 um) of
every step position, and the pen's disc is swept along the chords: a pixel is inked
when its centre is within the pen's radius of a chord (solved exactly per row). The
pen's diameter: `job.pen_widths_nm[key]`; without that table, the aperture's circle
diameter, the smaller side of a rectangle/obround, a polygon's outer diameter, 0
for a macro (0 = no ink; such stretches are counted). The pen resting where the
machine starts (Z = 0 is pen-down) is not a dot.

- inked: copper pixels inked / copper pixels;
- outside, as % of the copper: (a) ink outside the copper within the narrow-feature
  allowance: each narrow feature's centre line (`planned.ink.narrow[k]`, and the necks
  drawn as spurs of the walks, `planned.ink.necks`: its
  `.pieces` drawn by `.pen_nm`, or `.path_nm` drawn by `.width_nm`) swept by that
  pen's disc, plus one pixel; (b) the rest;
- bridges: components (8-connected) of ink | copper that hold 2 or more copper
  islands (components of the reference copper, with the pieces of one island of our
  exact geometry joined: copper thinner than a pixel, a fiducial's 10 um ring,
  samples as separate dots; and islands under the planner's TOUCH_NM apart, 5 um,
  joined, as copper that meets at a vertex is one); "merged" adds up islands - 1; the
  report says where (boxes round the ink outside the copper that touches 2+ islands,
  and in the --json records `bridge_touches_mm`: per box, one point of that ink next
  to each island it touches, to look the islands up in the planner's geometry);
- pen-down length (along the chords), lifts (pen-down stretches), pen changes,
  planning time. Totals add areas in mm2 (files differ in resolution).

The copper (the reference)
--------------------------
P: pygerber 2.4's RasterRenderer2 at `--px-per-mm` (default 40: 4 steps a pixel;
whole dots per mm, fewer on boards whose grid would pass `--max-mpx`; printed per
file). Our grid is pygerber's pixel grid, extended by whole pixels to hold the ink.

What --selftest found about pygerber's raster: it is NOT pixel-centre sampling.
Coordinates become pixels by int((x - min_x) * dpmm - 0.5) (truncation); a flash is
drawn once into an aperture image int(size * dpmm) px wide and pasted at the
truncated corner, so a rectangle flash lands exactly 1 px left of and 1 px below
pixel-centre sampling (unless an edge falls on a pixel edge); circles up to 35 px
across get pygerber's own +1 px workaround on top of PIL's inclusive ellipse box (a
0.3 mm pad: +9.6 % at 40 px/mm); regions get PIL's extra boundary pixel on their low
side; lines are PIL wide lines of int(w * dpmm) px, no caps, between end flashes
(0.5 mm traces: -5..-4 % at 40 px/mm, -6..+4 % at 20). Net: about half to all of a
shape's boundary pixels are wrong (P^E ~ 0.5..1 x its perimeter in pixels), in
directions that depend on the shape; no global shift fixes it, and one pixel (25 um)
is 10 % of a 0.25 mm trace, far above the 1 % and 0.5 % targets.

pygerber 2.4's grammar also rejects many files as written (39 of the 100 corpus
layers: several parameters in one %...% block, %IC/%IN/%LN, deprecated IR0/IPPOS/OF/
MI/SF that change nothing, G54/G55 prefixes, D010, '-' in macro names, N2 in FS):
those get `ink_raster.pygerber_text(text)`, the same image in its dialect (see there;
parameters that would change the image are kept, so a misread shows as disputed
pixels). What it still cannot read (a malformed %ADD in ekf2, P-CAD's moire primitive)
is measured against our geometry alone, and so is what it reads otherwise than we do
on more than `--max-disagree` % of the copper (trailing-zero FS, incremental
coordinates, the Mentor pours whose contours run over themselves).

So the boundary comes from our exact geometry and pygerber is the independent check:
D = `dark_geometry` (1 um tolerance, pyclipper) filled at pixel centres (even-odd
scanline). Where P and D agree, or differ within `--band` px (default 2) of P's
boundary (pygerber's own errors; the selftest's shapes all fall inside 2 px), the
copper is D's. Where they differ further out, the pixel is "disputed": neither copper
nor background, left out of every figure, and reported (disp% of the copper, and
whose copper it is): copper only one of the two readers sees. A file whose disputed
share passes `--max-disagree` % (default 5) is taken to be misread by pygerber and
measured against D alone ("ours", also when pygerber cannot read it; listed with the
reason). Selftest: with the reference so built, synthetic ink equal to each shape
measures 100 % inked and 0..0.3 % outside (a few pixel centres within D's 1 um chord
tolerance of the boundary); the disc/capsule painter matches the shapes' definition
pixel for pixel; bridges and the allowance split come out as built.

Memory: bool arrays (1 byte/px: P, D, reference, disputed, ink, allowance, union),
one int32 difference image for the spans (4 bytes/px), connected components on runs
(no label image); pygerber's RGBA render (4 bytes/px, twice while it flips it) and
its parse tree are the peak. `--max-mpx` 60 keeps every corpus layer at 40 px/mm but
the 255 x 253 mm OrCAD boards (30 px/mm); the highest child peak RSS on the corpus
is 1.7 GB (hellboard.group1.gbr: mostly pygerber's parse tree and RGBA render).
"""

from __future__ import annotations

import argparse
import dataclasses
import fnmatch
import gc
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import ink_raster as R  # noqa: E402
from corpus import CORPUS  # noqa: E402

MB = 2 ** 20
NM_PER_MM = 1_000_000
TARGET_INKED = 99.0          # % of the copper
TARGET_OUTSIDE = 0.5         # % of the copper, beyond the narrow-feature allowance
TARGET_PLAN_S = 5.0          # largest copper layer


# ---- planning --------------------------------------------------------------------------------
def cpu_s() -> float:
    """CPU seconds of this process and of its children that have ended (the fill's
    forked gap tests, plan/ink/background.py)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system



def touch_nm() -> float:
    """Islands closer than this are one to the planner (0 in checkouts before it)."""
    try:
        from galileo_cnc.plan.ink.islands import TOUCH_NM
    except ImportError:
        return 0.0
    return float(TOUCH_NM)


def plan_options_class():
    """PlanOptions when the checkout has it (ink mode), else None."""
    try:
        from galileo_cnc.plan.pipeline import PlanOptions
    except ImportError:
        return None
    return PlanOptions


def bench_config():
    from galileo_cnc.config.machine import MachineConfig

    return dataclasses.replace(MachineConfig(), x_travel_mm=2000.0, y_travel_mm=2000.0)


def plan(path: Path, config, mode: str, pens_nm: tuple[int, ...]):
    from galileo_cnc.plan.pipeline import plan_file

    options = plan_options_class()
    if options is None:
        if mode != "centre":
            raise RuntimeError("ink mode is not available in this checkout (no PlanOptions)")
        return plan_file(path, config, "auto")
    if mode == "ink":
        planned = plan_file(path, config, "auto", options=options(mode="ink", pens_nm=pens_nm))
        # plot prints the share of the copper inked before it streams: the planning a
        # user waits for includes it (worked out in the background while path order
        # runs, plan/ink/inking.py)
        _ = planned.ink.inked_nm2
        return planned
    return plan_file(path, config, "auto", options=options(mode=mode))


def aperture_width_nm(aperture) -> int:
    """The pen width centre mode draws an aperture with, when the job has no table."""
    p = aperture.params_nm
    if aperture.shape in ("circle", "polygon") and p:
        return int(p[0])
    if aperture.shape in ("rectangle", "obround") and len(p) >= 2:
        return int(min(p[0], p[1]))
    return 0


def pen_widths(planned) -> tuple[dict, str]:
    table = getattr(planned.job, "pen_widths_nm", None)
    if table is not None:
        return {k: int(v or 0) for k, v in dict(table).items()}, "job"
    return {code: aperture_width_nm(ap) for code, ap in planned.program.apertures.items()}, \
        "apertures"


def narrow_paths(planned) -> list[tuple[np.ndarray, int]]:
    """(centre line in program nm (n, 2), pen width nm) of every narrow feature the ink
    plan draws as a line or a dot: `planned.ink.narrow[k]` with `.path_nm` and
    `.width_nm` (the pen), or, as the checkout has it, `.pieces` drawn by `.pen_nm`."""
    ink = getattr(planned, "ink", None)
    if ink is None:
        return []
    out = []
    # the necks drawn as spurs of the walks (necks.py) overdraw as centre lines do
    narrow = list(getattr(ink, "narrow", None) or ())
    drawn = {id(item) for item in narrow}
    narrow += [neck for neck in getattr(ink, "necks", None) or () if id(neck) not in drawn]
    for item in narrow:
        pieces = item.pieces if hasattr(item, "pieces") else [item.path_nm]
        width = getattr(item, "pen_nm", None) or item.width_nm
        out.extend((np.asarray(piece, dtype=np.int64).reshape(-1, 2), int(width))
                   for piece in pieces if len(piece))
    return out


# ---- rasters ---------------------------------------------------------------------------------

def paint_strokes(canvas: R.SpanCanvas, grid: R.Grid, strokes: R.StrokeSet, offset_nm,
                  nm_per_step: int) -> None:
    for width in strokes.by_width:
        ax, ay, bx, by = strokes.arrays(width)
        u0, v0 = grid.u(ax * nm_per_step + offset_nm[0]), grid.v(ay * nm_per_step + offset_nm[1])
        u1, v1 = grid.u(bx * nm_per_step + offset_nm[0]), grid.v(by * nm_per_step + offset_nm[1])
        for spans in R.capsule_spans(u0, v0, u1, v1, width / 2 * grid.scale):
            canvas.add(*spans)


def paint_paths(canvas: R.SpanCanvas, grid: R.Grid, paths, extra_px: float = 0.0) -> None:
    """Each (path_nm (n, 2), width_nm) swept by a disc of that width (+ extra_px on the radius)."""
    if not paths:
        return
    points = np.concatenate([p for p, _ in paths])
    sizes = np.array([len(p) for p, _ in paths])
    radius = np.repeat(np.array([w for _, w in paths], dtype=np.float64) / 2 * grid.scale
                       + extra_px, sizes)
    owner = np.repeat(np.arange(len(paths)), sizes)
    u, v = grid.u(points[:, 0]), grid.v(points[:, 1])
    same = owner[1:] == owner[:-1]
    a = np.flatnonzero(same)
    single = np.flatnonzero(sizes == 1)
    dots = (np.cumsum(sizes) - sizes)[single]
    a_idx = np.concatenate((a, dots))
    b_idx = np.concatenate((a + 1, dots))
    for spans in R.capsule_spans(u[a_idx], v[a_idx], u[b_idx], v[b_idx], radius[a_idx]):
        canvas.add(*spans)


def reference(grid: R.Grid, dark_rings, pyg: np.ndarray | None, pyg_at, band: int,
              canvas: R.SpanCanvas):
    """(reference copper, disputed pixels or None, D, P placed or None): see the module doc.

    Where pygerber (P) and our exact geometry (D) agree, or differ only within `band`
    pixels of pygerber's boundary (its own rasterisation errors), the copper is D's.
    Where they differ further out, the pixel is disputed: judged neither copper nor
    background."""
    canvas.clear()
    ours = None
    if dark_rings is not None:
        for spans in R.polygon_spans(dark_rings, grid):
            canvas.add(*spans)
        ours = canvas.mask()
    canvas.clear()
    placed = None
    if pyg is not None:
        placed = np.zeros((grid.height, grid.width), dtype=bool)
        col, row = pyg_at
        r0, c0 = max(row, 0), max(col, 0)
        r1, c1 = min(row + pyg.shape[0], grid.height), min(col + pyg.shape[1], grid.width)
        placed[r0:r1, c0:c1] = pyg[r0 - row:r1 - row, c0 - col:c1 - col]
    if placed is None or ours is None:
        only = ours if ours is not None else placed
        return only, None, ours, placed
    disputed = placed ^ ours
    disputed &= R.erode(placed, band) | ~R.dilate(placed, band)
    return ours & ~disputed, disputed, ours, placed


def measure_ink(copper, disputed, copper_runs, copper_labels, ink, allowance,
                grid: R.Grid | None = None) -> dict:
    """Pixel counts of the ink against the reference; disputed pixels are not judged.
    With the grid, where the bridges are: boxes (x0, y0, x1, y1, program mm) round the
    ink outside the copper that touches two or more islands."""
    outside = ink & ~copper
    if disputed is not None:
        outside &= ~disputed
    out_a = int(np.count_nonzero(outside & allowance)) if allowance is not None else 0
    bridged, merged = R.bridges(copper_runs, copper_labels, ink | copper)
    places, touches = [], []
    if bridged and grid is not None:
        for (r0, c0, r1, c1), points in R.bridge_touches(copper_runs, copper_labels, outside):
            places.append(((grid.left_nm + c0 * grid.pitch_nm) / NM_PER_MM,
                           (grid.top_nm - (r1 + 1) * grid.pitch_nm) / NM_PER_MM,
                           (grid.left_nm + (c1 + 1) * grid.pitch_nm) / NM_PER_MM,
                           (grid.top_nm - r0 * grid.pitch_nm) / NM_PER_MM))
            touches.append([((grid.left_nm + (c + 0.5) * grid.pitch_nm) / NM_PER_MM,
                             (grid.top_nm - (r + 0.5) * grid.pitch_nm) / NM_PER_MM)
                            for r, c in points])
    return {"ink_px": int(np.count_nonzero(ink)),
            "inked_px": int(np.count_nonzero(ink & copper)),
            "out_a_px": out_a, "out_b_px": int(np.count_nonzero(outside)) - out_a,
            "ink_disputed_px": int(np.count_nonzero(ink & disputed)) if disputed is not None else 0,
            "bridges": bridged, "merged": merged, "bridges_at_mm": places,
            "bridge_touches_mm": touches}


def save_overlay(out: Path, copper, ink, allowance) -> None:
    """Copper inked green, copper missed red, ink outside in the allowance orange,
    the rest of the ink outside blue."""
    from PIL import Image

    out.parent.mkdir(parents=True, exist_ok=True)
    rgb = np.full(copper.shape + (3,), 255, dtype=np.uint8)
    rgb[copper & ~ink] = (220, 50, 50)
    rgb[copper & ink] = (60, 170, 60)
    outside = ink & ~copper
    if allowance is not None:
        rgb[outside & allowance] = (240, 170, 0)
        outside &= ~allowance
    rgb[outside] = (40, 60, 210)
    Image.fromarray(rgb).save(out)


# ---- one file (in a child) -------------------------------------------------------------------

def _peak_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure_file(path: Path, opts: dict) -> dict:
    from galileo_cnc.plan.ink import dark_geometry
    from galileo_cnc.plan.pipeline import load_artwork

    record: dict = {"bytes": path.stat().st_size, "modes": {}}
    config = bench_config()
    nps = config.nm_per_step
    pens_nm = tuple(int(round(p * NM_PER_MM)) for p in opts["pens"])

    planned_modes = {}
    program = None
    for mode in opts["modes"]:
        if mode == "ink" and plan_options_class() is None:
            record["modes"][mode] = {"skipped": "ink mode not in this checkout"}
            continue
        try:
            gc.collect()
            start = time.perf_counter()
            load_artwork(path)
            read_s = time.perf_counter() - start
            start, cpu = time.perf_counter(), cpu_s()
            planned = plan(path, config, mode, pens_nm)
            plan_s, plan_cpu_s = time.perf_counter() - start, cpu_s() - cpu
            widths, widths_from = pen_widths(planned)
            start = time.perf_counter()
            strokes = R.steps_segments(planned.job, config, widths, opts["tol"])
            walk_s = time.perf_counter() - start
        except Exception as problem:  # noqa: BLE001 (a failure is a result too)
            record["modes"][mode] = {"error": f"{type(problem).__name__}: {problem}"[:300]}
            continue
        program = planned.program
        planned_modes[mode] = (planned.offset_nm, strokes, narrow_paths(planned))
        record["modes"][mode] = {
            "read_s": read_s, "plan_s": plan_s, "plan_cpu_s": plan_cpu_s, "walk_s": walk_s,
            "commands": len(planned.job), "pen_changes": len(planned.job.pen_changes),
            "pens": sorted({int(widths.get(k, 0)) for k in set(planned.job.aperture)}),
            "widths_from": widths_from, "lifts": strokes.stretches,
            "length_m": strokes.length_steps * nps / 1e9, "events": strokes.events,
            "segments": sum(len(p[0]) for ps in strokes.by_width.values() for p in ps),
            "zero_width": strokes.zero_width_stretches,
            "narrow": len(planned_modes[mode][2])}
        del planned
    if program is None:
        from galileo_cnc.readers import read_file
        program = read_file(path)

    # pygerber after the planning: its millions of live objects slow Python's garbage
    # collector, and so anything timed after it
    start = time.perf_counter()
    try:
        parsed, pyg_box, record["pyg_input"] = R.pygerber_parse(path)
        pyg_why = None
    except Exception as problem:  # noqa: BLE001 (pygerber fails in many ways)
        parsed, pyg_box, pyg_why = None, None, f"{type(problem).__name__}: {problem}"
    record["pyg_parse_s"] = time.perf_counter() - start

    # our exact copper
    start = time.perf_counter()
    try:
        image = dark_geometry(program)
        dark_polygons = image.polygons()
        dark_rings = R.rings_of(dark_polygons)
        dark_box = image.bounds()
        record["dark_mm2"] = image.area_nm2() / 1e12
    except Exception as problem:  # noqa: BLE001
        dark_polygons, dark_rings, dark_box = None, None, None
        record["dark_error"] = f"{type(problem).__name__}: {problem}"[:200]
    record["dark_s"] = time.perf_counter() - start
    del program

    # the grid: copper, ink and allowance, on pygerber's pixel phase
    boxes = [b for b in (pyg_box, dark_box) if b is not None]
    for offset, strokes, narrow in planned_modes.values():
        box = strokes.box_nm(offset, nps)
        if box is not None:
            boxes.append(box)
        for path_nm, width in narrow:
            lo, hi = path_nm.min(axis=0), path_nm.max(axis=0)
            boxes.append((lo[0] - width, lo[1] - width, hi[0] + width, hi[1] + width))
    if not boxes:
        record["error"] = "nothing to measure (no copper, no ink)"
        return record
    box = (min(b[0] for b in boxes), min(b[1] for b in boxes),
           max(b[2] for b in boxes), max(b[3] for b in boxes))
    anchor = (pyg_box[0], pyg_box[1]) if pyg_box is not None else (box[0], box[1])
    grid = R.grid_for(box, opts["px_per_mm"], int(opts["max_mpx"] * 1e6), anchor, pad_px=4)
    record.update(dpmm=grid.dpmm, grid=[grid.width, grid.height],
                  grid_left_top_mm=[grid.left_nm / NM_PER_MM, grid.top_nm / NM_PER_MM])

    pyg, pyg_at = None, None
    if parsed is not None:
        start = time.perf_counter()
        try:
            pyg = R.pygerber_mask(parsed, grid.dpmm)
            top = pyg_box[1] + pyg.shape[0] * grid.pitch_nm
            pyg_at = grid.place(pyg_box[0], top)
        except Exception as problem:  # noqa: BLE001
            pyg_why = f"render: {type(problem).__name__}: {problem}"
        record["pyg_render_s"] = time.perf_counter() - start
        del parsed

    start = time.perf_counter()
    canvas = R.SpanCanvas(grid.height, grid.width)
    copper, disputed, ours, placed = reference(grid, dark_rings, pyg, pyg_at, opts["band"],
                                               canvas)
    del pyg, dark_rings
    ref = "pygerber+ours" if disputed is not None else \
        ("pygerber" if placed is not None else "ours")
    if disputed is not None:
        record["disputed_px"] = int(np.count_nonzero(disputed))
        record["pyg_xor_ours_px"] = int(np.count_nonzero(placed ^ ours))
        record["pyg_only_px"] = int(np.count_nonzero(disputed & placed))
        share = 100.0 * record["disputed_px"] / max(1, int(np.count_nonzero(ours)))
        if share > opts["max_disagree"]:
            ref, copper, disputed = "ours", ours, None
            pyg_why = f"pygerber and our geometry differ on {share:.1f} % of the copper " \
                      f"(more than --max-disagree {opts['max_disagree']:g} %)"
    del placed, ours
    record.update(ref=ref, pyg_why=pyg_why)
    if copper is None:
        record["error"] = f"no reference raster: pygerber: {pyg_why}; ours: " \
                          f"{record.get('dark_error')}"
        return record
    record["copper_px"] = int(np.count_nonzero(copper))
    copper_runs, copper_labels, record["raster_islands"] = R.islands(copper)
    if dark_polygons is not None:
        copper_labels = R.join_by_outline(copper_runs, copper_labels, grid, dark_polygons,
                                          touch_nm=touch_nm())
    del dark_polygons
    record["islands"] = int(len(np.unique(copper_labels)))
    record["reference_s"] = time.perf_counter() - start

    for mode, (offset, strokes, narrow) in planned_modes.items():
        start = time.perf_counter()
        canvas.clear()
        paint_strokes(canvas, grid, strokes, offset, nps)
        clipped = canvas.clipped
        ink = canvas.mask()
        allowance = None
        if narrow:
            canvas.clear()
            paint_paths(canvas, grid, narrow, extra_px=1.0)
            allowance = canvas.mask()
        result = measure_ink(copper, disputed, copper_runs, copper_labels, ink, allowance,
                             grid)
        if opts.get("png"):
            save_overlay(Path(opts["png"]) / f"{path.name}.{mode}.png", copper, ink, allowance)
        del ink, allowance
        result.update(raster_s=time.perf_counter() - start, clipped=clipped)
        record["modes"][mode].update(result)
    record["peak_mb"] = _peak_mb()
    return record


def child_main(rel: str, opts: dict) -> None:
    path = Path(rel) if Path(rel).is_absolute() else CORPUS / rel
    try:
        record = measure_file(path, opts)
    except MemoryError:
        record = {"error": "out of memory (--max-gb)"}
    except Exception as problem:  # noqa: BLE001
        import traceback

        record = {"error": f"{type(problem).__name__}: {problem}"[:300],
                  "trace": traceback.format_exc()[-1500:]}
    record["path"] = rel
    print(json.dumps(record), flush=True)


def time_plan_main(rel: str, opts: dict) -> None:
    """One planning of `rel` per mode, timed as measure_file times it, after a read
    that loads the reader (the child of `time_alone`)."""
    from galileo_cnc.plan.pipeline import load_artwork

    path = Path(rel) if Path(rel).is_absolute() else CORPUS / rel
    config = bench_config()
    pens_nm = tuple(int(round(p * NM_PER_MM)) for p in opts["pens"])
    times = {}
    for mode in opts["modes"]:
        gc.collect()
        load_artwork(path)
        start, cpu = time.perf_counter(), cpu_s()
        plan(path, config, mode, pens_nm)
        times[mode] = {"plan_s": time.perf_counter() - start, "plan_cpu_s": cpu_s() - cpu}
    print(json.dumps(times), flush=True)


# ---- the parent -------------------------------------------------------------------------------

def time_alone(rel: str, opts: dict, runs: int) -> dict[str, list[float]]:
    """Per mode, the wall seconds of `runs` plannings of `rel`, each in a child process of
    its own with nothing else running: the planning target is a user's wait on an idle
    machine, and with --jobs 2 the file in the pool shared both cores with another."""
    found: dict[str, list[float]] = {}
    for _ in range(runs):
        done = subprocess.run([sys.executable, __file__, "--time-plan", rel, "--opts",
                               json.dumps(opts)], capture_output=True, text=True, check=False)
        lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
        if not lines:
            print(f"timing {rel} alone failed: {(done.stderr.strip().splitlines() or ['?'])[-1]}",
                  file=sys.stderr)
            return found
        for mode, times in json.loads(lines[-1]).items():
            found.setdefault(mode, []).append(times["plan_s"])
    return found


def copper_files(args) -> list[str]:
    from bench_ink_union import copper_layers

    files = copper_layers()
    if args.files:
        files = [f for f in files if fnmatch.fnmatch(f, args.files)]
    if args.quick:
        files = [f for f in files if (CORPUS / f).stat().st_size <= 40_000][:6]
    return files[:args.limit] if args.limit else files


def run_child(rel: str, opts: dict, timeout: float, max_gb: float) -> dict:
    def limit():
        import resource

        cap = int(max_gb * 2 ** 30)
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    command = [sys.executable, __file__, "--child", rel, "--opts", json.dumps(opts)]
    started = time.perf_counter()
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout,
                              preexec_fn=limit if max_gb > 0 else None, check=False)
    except subprocess.TimeoutExpired:
        return {"path": rel, "error": f"timed out after {timeout:.0f} s"}
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if lines:
        record = json.loads(lines[-1])
    else:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        record = {"path": rel, "error": f"child exited {done.returncode}: {tail}"[:300]}
    record["wall_s"] = time.perf_counter() - started
    return record


def pct(part: float, whole: float) -> float:
    return 100.0 * part / whole if whole else float("nan")


def report(records: list[dict], modes: list[str], opts: dict, wall: float,
           alone: dict[str, list[float]] | None = None) -> None:
    """The table, the totals and the targets; `alone`: per mode, the largest layer's
    plannings timed alone (time_alone), which judge the planning target when given."""
    head = f"{'file':46} {'kB':>5} {'px/mm':>5} {'Cu mm2':>8} {'ref':>4} {'disp%':>5}"
    for mode in modes:
        head += f" | {mode[:6]:6} {'inked%':>6} {'outA%':>6} {'outB%':>6} {'brdg':>4} " \
                f"{'pen m':>6} {'lifts':>6} {'chg':>4} {'plan s':>6}"
    print(head)
    print("-" * len(head))
    failures = []
    for r in records:
        name = r["path"][-46:]
        if "error" in r:
            print(f"{name:46} FAILED: {r['error']}")
            failures.append(r)
            continue
        px = 1.0 / r["dpmm"] ** 2
        copper = r["copper_px"]
        ref = {"pygerber+ours": "pyg", "pygerber": "pyg!", "ours": "ours"}[r["ref"]]
        dis = f"{pct(r['disputed_px'], copper):5.2f}" if "disputed_px" in r and \
            r["ref"] == "pygerber+ours" else "    -"
        line = f"{name:46} {r['bytes'] / 1000:5.0f} {r['dpmm']:5d} {copper * px:8.1f} " \
               f"{ref:>4} {dis}"
        for mode in modes:
            m = r["modes"].get(mode, {})
            if "inked_px" not in m:
                why = m.get("error") or m.get("skipped") or "not run"
                line += f" | {mode[:6]:6} {why[:60]:60}"
                if "error" in m:
                    failures.append({"path": r["path"], "error": f"{mode}: {m['error']}"})
                continue
            line += f" | {mode[:6]:6} {pct(m['inked_px'], copper):6.2f} " \
                    f"{pct(m['out_a_px'], copper):6.2f} {pct(m['out_b_px'], copper):6.2f} " \
                    f"{m['bridges']:4d} {m['length_m']:6.2f} {m['lifts']:6d} " \
                    f"{m['pen_changes']:4d} {m['plan_s']:6.2f}"
        print(line)
    good = [r for r in records if "error" not in r]
    print()
    print(f"{len(records)} copper layers, {len(good)} measured, {len(records) - len(good)} "
          f"failed; wall {wall:.0f} s; pens {','.join(f'{p:g}' for p in opts['pens'])} mm "
          f"(ink mode); ink chords within {opts['tol']:g} step; reference band {opts['band']} px")
    resolutions = sorted({r["dpmm"] for r in good})
    used = ", ".join(f"{d} px/mm ({sum(r['dpmm'] == d for r in good)} files)" for d in resolutions)
    peak = max((r.get("peak_mb", 0) for r in good), default=0)
    print(f"resolution: {used}; highest child peak RSS {peak:.0f} MB")
    refs = {k: [r["path"] for r in good if r["ref"] == k]
            for k in ("pygerber+ours", "pygerber", "ours")}
    normalised = sum(r.get("pyg_input") == "normalised" for r in good if r["ref"] != "ours")
    print(f"reference: pygerber with our boundary on {len(refs['pygerber+ours'])} files "
          f"({normalised} of them read by pygerber after pygerber_text()), pygerber alone on "
          f"{len(refs['pygerber'])}, ours alone on {len(refs['ours'])}")
    for r in good:
        if r["ref"] != "pygerber+ours":
            print(f"    {r['path']}: reference {r['ref']}: {r.get('pyg_why') or r.get('dark_error')}")
    hybrid = [r for r in good if r["ref"] == "pygerber+ours"]
    if hybrid:
        disputed = sorted(((pct(r["disputed_px"], r["copper_px"]), r) for r in hybrid),
                          key=lambda p: -p[0])
        total = sum(r["disputed_px"] / r["dpmm"] ** 2 for r in hybrid)
        copper = sum(r["copper_px"] / r["dpmm"] ** 2 for r in hybrid)
        raw = sum(r["pyg_xor_ours_px"] / r["dpmm"] ** 2 for r in hybrid)
        print(f"disputed (pygerber and ours differ beyond {opts['band']} px of pygerber's "
              f"boundary; not judged): {total:.2f} mm2 = {pct(total, copper):.3f} % of "
              f"{copper:.0f} mm2 of copper, {sum(r['disputed_px'] > 0 for r in hybrid)} files "
              f"(pygerber's raw raster differs from ours on {pct(raw, copper):.2f} %, nearly "
              f"all boundary pixels); most: " + ", ".join(
                  f"{Path(r['path']).name} {d:.2f} % ({pct(r['pyg_only_px'], r['disputed_px']):.0f}"
                  f" % pygerber's)" for d, r in disputed[:5] if d > 0))

    for mode in modes:
        rows = [r for r in good if "inked_px" in r["modes"].get(mode, {})]
        if not rows:
            reason = next((r["modes"][mode].get("skipped") for r in good
                           if "skipped" in r["modes"].get(mode, {})), "no file measured")
            print(f"\n[{mode}] {reason}")
            continue
        area = lambda key: sum(r["modes"][mode][key] / r["dpmm"] ** 2 for r in rows)  # noqa: E731
        copper = sum(r["copper_px"] / r["dpmm"] ** 2 for r in rows)
        m = [r["modes"][mode] for r in rows]
        inked, out_a, out_b = pct(area("inked_px"), copper), pct(area("out_a_px"), copper), \
            pct(area("out_b_px"), copper)
        bridges = sum(x["bridges"] for x in m)
        print(f"\n[{mode}] {len(rows)} files, copper {copper:.1f} mm2: inked {inked:.2f} %, "
              f"outside {out_a + out_b:.2f} % = (a) narrow-feature overdraw {out_a:.2f} % + "
              f"(b) rest {out_b:.2f} %; bridges {bridges} "
              f"({sum(x['merged'] for x in m)} islands merged, {sum(x['bridges'] > 0 for x in m)} "
              f"files); pen-down {sum(x['length_m'] for x in m):.1f} m, "
              f"{sum(x['lifts'] for x in m)} lifts, {sum(x['pen_changes'] for x in m)} pen "
              f"changes; planning {sum(x['plan_s'] for x in m):.1f} s, CPU "
              f"{sum(x['plan_cpu_s'] for x in m):.1f} s "
              f"(reading alone {sum(x['read_s'] for x in m):.1f} s)")
        judged_out = area("ink_disputed_px")
        if judged_out:
            print(f"    ink on disputed pixels (not judged): {judged_out:.2f} mm2")
        zero = sum(x["zero_width"] for x in m)
        if zero:
            print(f"    {zero} pen-down stretches drawn with a pen of unknown (0) width leave no "
                  f"ink ({sum(x['zero_width'] > 0 for x in m)} files; widths from "
                  f"{'/'.join(sorted({x['widths_from'] for x in m}))})")
        clipped = sum(x["clipped"] for x in m)
        if clipped:
            print(f"    {clipped} ink spans fell off the grid (not counted)")
        worst_in = [r for r in rows if pct(r["modes"][mode]["inked_px"], r["copper_px"]) < TARGET_INKED]
        worst_out = [r for r in rows if pct(r["modes"][mode]["out_b_px"], r["copper_px"]) > TARGET_OUTSIDE]
        largest = max(rows, key=lambda r: r["bytes"])
        slowest = max(rows, key=lambda r: r["modes"][mode]["plan_s"])
        lp = largest["modes"][mode]
        mark = lambda ok: "PASS" if ok else "MISS"  # noqa: E731
        note = "" if mode != "ink" or tuple(opts["pens"]) == (0.3,) else \
            f" (targets are for a 0.3 mm pen; this ran {opts['pens']})"
        print(f"  {mark(inked >= TARGET_INKED)} [{mode}] inked >= {TARGET_INKED:g} % of the copper: "
              f"{inked:.2f} % ({len(worst_in)} of {len(rows)} files below){note}")
        print(f"  {mark(out_b <= TARGET_OUTSIDE)} [{mode}] ink outside beyond the narrow-feature "
              f"overdraw <= {TARGET_OUTSIDE:g} %: {out_b:.2f} % ({len(worst_out)} files above)")
        places = [(Path(r["path"]).name, box) for r in rows
                  for box in r["modes"][mode].get("bridges_at_mm", [])[:2]]
        if places:
            print("    where (ink outside the copper touching 2+ islands; file mm, x0,y0..x1,y1; "
                  "2 a file at most): " + "; ".join(
                      f"{n} {b[0]:.2f},{b[1]:.2f}..{b[2]:.2f},{b[3]:.2f}" for n, b in places[:10])
                  + (" ..." if len(places) > 10 else ""))
        print(f"  {mark(bridges == 0)} [{mode}] zero bridges: {bridges} "
              f"({sum(x['bridges'] > 0 for x in m)} files)")
        timed = (alone or {}).get(mode)
        judged = statistics.median(timed) if timed else lp["plan_s"]
        how = (f"median of {len(timed)} alone: " + ", ".join(f"{t:.2f}" for t in timed)
               + f" s; in the run {lp['plan_s']:.2f} s") if timed else "in the run"
        print(f"  {mark(judged <= TARGET_PLAN_S)} [{mode}] planning <= {TARGET_PLAN_S:g} s "
              f"for the largest copper layer: {judged:.2f} s ({how}; {largest['path']}, "
              f"{largest['bytes'] / 1000:.0f} kB; CPU {lp['plan_cpu_s']:.2f} s, reading alone "
              f"{lp['read_s']:.2f} s); slowest in the run "
              f"{slowest['modes'][mode]['plan_s']:.2f} s ({Path(slowest['path']).name})")
    if failures:
        print("\nfailures:")
        for f in failures:
            print(f"    {f['path']}: {f['error']}")


# ---- selftest ----------------------------------------------------------------------------------

_HEAD = "%FSLAX46Y46*%\n%MOMM*%\n%LPD*%\n"


def _gerber(body: str, apertures: dict[int, str]) -> str:
    return _HEAD + "".join(f"%ADD{k}{v}*%\n" for k, v in apertures.items()) + body + "M02*\n"


def _xy(x_mm: float, y_mm: float) -> str:
    return f"X{round(x_mm * NM_PER_MM)}Y{round(y_mm * NM_PER_MM)}"


def _exact_mask(grid: R.Grid, kind: str, size: float, a, b=None) -> np.ndarray:
    """The shape sampled at every pixel centre, straight from its definition (mm)."""
    cols = (grid.left_nm + (np.arange(grid.width) + 0.5) * grid.pitch_nm) / NM_PER_MM
    rows = (grid.top_nm - (np.arange(grid.height) + 0.5) * grid.pitch_nm) / NM_PER_MM
    X, Y = np.meshgrid(cols, rows)
    if kind == "R":
        return (np.abs(X - a[0]) <= size / 2) & (np.abs(Y - a[1]) <= size / 2)
    if kind == "C":
        return (X - a[0]) ** 2 + (Y - a[1]) ** 2 <= (size / 2) ** 2
    dx, dy = b[0] - a[0], b[1] - a[1]
    t = np.clip(((X - a[0]) * dx + (Y - a[1]) * dy) / (dx * dx + dy * dy), 0, 1)
    return (X - a[0] - t * dx) ** 2 + (Y - a[1] - t * dy) ** 2 <= (size / 2) ** 2


def _centroid(mask: np.ndarray) -> np.ndarray:
    rows, cols = np.nonzero(mask)
    return np.array([cols.mean(), -rows.mean()])        # x right, y up


def _setup(tmp: Path, name: str, text: str, dpmm: int, band: int, pad_mm: float = 1.0):
    """Grid, reference, P, D for a Gerber text written to tmp/name."""
    from galileo_cnc.plan.ink import dark_geometry
    from galileo_cnc.readers import read_file

    path = tmp / name
    path.write_text(text)
    parsed, box, _ = R.pygerber_parse(path)
    pad = pad_mm * NM_PER_MM
    grid = R.Grid.around((box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad), dpmm,
                         (box[0], box[1]))
    pyg = R.pygerber_mask(parsed, dpmm)
    at = grid.place(box[0], box[1] + pyg.shape[0] * grid.pitch_nm)
    rings = R.rings_of(dark_geometry(read_file(path)).polygons())
    canvas = R.SpanCanvas(grid.height, grid.width)
    copper, disputed, ours, placed = reference(grid, rings, pyg, at, band, canvas)
    return path, grid, copper, disputed, ours, placed, canvas


def selftest(opts: dict) -> None:
    config = bench_config()
    band = opts["band"]
    resolutions = sorted({20, 40, int(opts["px_per_mm"])})
    # off-grid centres; a 0.02 mm dot at (0.2, 0.3) sets pygerber's bounding box (so
    # the shapes sit at an arbitrary pixel phase) and is left out of the window
    shapes = [("square flash 1.7 mm", "R", 1.7, (3.0123, 2.0311), None),
              ("round flash 1 mm", "C", 1.0, (3.0371, 2.0052), None),
              ("round flash 0.3 mm", "C", 0.3, (3.0219, 2.0407), None),
              ("trace 0.5 mm", "T", 0.5, (3.0137, 2.0291), (6.0411, 3.3173)),
              ("trace 0.5 mm along X", "T", 0.5, (3.0137, 2.0291), (6.0411, 2.0291))]
    print("selftest: pixel counts in a window round each shape (the anchor dot excluded);")
    print("  exact = area x px/mm^2; E = the shape sampled at pixel centres from its definition;")
    print("  P = pygerber's raster, D = our dark_geometry filled at pixel centres; X = disputed")
    print(f"  (P and D differ more than {band} px from P's boundary; expect 0), C = the reference")
    print("  (D less X); 'band' = the shape's perimeter in pixels (the size of a one-pixel")
    print("  boundary error); shift = P's centroid minus E's in px (x right, y up).")
    print(f"{'shape':22} {'px/mm':>5} {'exact':>9} {'E':>7} {'P':>7} {'P-exact':>8} {'band':>5} "
          f"{'P^E':>5} {'shift x,y':>11} {'D^E':>4} {'C^E':>4} {'X':>3} | synthetic ink = shape: "
          f"{'inked%':>7} {'out%':>5} | machine: {'inked%':>7} {'out%':>6} {'expect':>7}")
    with tempfile.TemporaryDirectory() as scratch:
        tmp = Path(scratch)
        for dpmm in resolutions:
            for name, kind, size, a, b in shapes:
                code = {"R": f"R,{size}X{size}", "C": f"C,{size}", "T": f"C,{size}"}[kind]
                body = "D10*\n" + _xy(0.2, 0.3) + "D03*\nD11*\n"
                body += _xy(*a) + ("D03*\n" if b is None else "D02*\n" + _xy(*b) + "D01*\n")
                text = _gerber(body, {10: "C,0.02", 11: code})
                path, grid, copper, disputed, ours, placed, canvas = _setup(
                    tmp, f"{kind}{size}_{dpmm}.gbr", text, dpmm, band)
                exact = _exact_mask(grid, kind, size, a, b)
                window = R.dilate(exact, 4)
                if kind == "R":
                    area, perimeter = size * size, 4 * size
                elif kind == "C":
                    area, perimeter = math.pi * size * size / 4, math.pi * size
                else:
                    length = math.dist(a, b)
                    area = size * length + math.pi * size * size / 4
                    perimeter = 2 * length + math.pi * size
                count = lambda m: int(np.count_nonzero(m & window))  # noqa: E731
                shift = _centroid(placed & window) - _centroid(exact)
                # synthetic ink equal to the shape: the capsule painter for discs and
                # traces (so it is checked too), the exact mask for the square
                if kind == "R":
                    ink = exact
                else:
                    canvas.clear()
                    ends = [(a, b or a)]
                    u0, v0 = grid.u(ends[0][0][0] * NM_PER_MM), grid.v(ends[0][0][1] * NM_PER_MM)
                    u1, v1 = grid.u(ends[0][1][0] * NM_PER_MM), grid.v(ends[0][1][1] * NM_PER_MM)
                    for spans in R.capsule_spans([u0], [v0], [u1], [v1], size / 2 * dpmm):
                        canvas.add(*spans)
                    ink = canvas.mask()
                ink = ink & window
                cu = copper & window
                synth_in = pct(count(ink & cu), count(cu))
                synth_out = pct(count(ink & ~cu), count(cu))
                painter = int(np.count_nonzero(ink ^ exact))
                # through the machine: centre mode draws each aperture with a pen of its
                # own width: a flash is a dot of the aperture's size, a trace itself
                planned = plan(path, config, "centre", ())
                widths, _ = pen_widths(planned)
                strokes = R.steps_segments(planned.job, config, widths, opts["tol"])
                canvas.clear()
                paint_strokes(canvas, grid, strokes, planned.offset_nm, config.nm_per_step)
                drawn = canvas.mask() & window
                machine_in = pct(count(drawn & cu), count(cu))
                machine_out = pct(count(drawn & ~cu), count(cu))
                expect = "78.54" if kind == "R" else "100"     # a 1.7 mm dot in a 1.7 mm square
                print(f"{name:22} {dpmm:5d} {area * dpmm * dpmm:9.1f} {count(exact):7d} "
                      f"{count(placed):7d} {pct(count(placed) - area * dpmm * dpmm, area * dpmm * dpmm):+7.2f}% "
                      f"{perimeter * dpmm:5.0f} {count(placed ^ exact):5d} "
                      f"{shift[0]:+5.2f},{shift[1]:+5.2f} {count(ours ^ exact):4d} "
                      f"{count(copper ^ exact):4d} {count(disputed):3d} | {'':22} {synth_in:7.2f} "
                      f"{synth_out:5.2f} "
                      f"| {'':8} {machine_in:7.2f} {machine_out:6.2f} {expect:>7}"
                      + ("" if kind == "R" else f"  (painter vs E: {painter} px)"))
        # bridges and the allowance, with synthetic ink
        dpmm = int(opts["px_per_mm"])
        text = _gerber("D11*\n" + _xy(3.0, 2.0) + "D03*\n" + _xy(4.4, 2.0) + "D03*\n"
                       "D12*\n" + _xy(3.0, 4.0) + "D02*\n" + _xy(6.0, 4.3) + "D01*\n",
                       {11: "R,1.0X1.0", 12: "C,0.2"})
        path, grid, copper, disputed, ours, placed, canvas = _setup(tmp, "pair.gbr", text,
                                                                    dpmm, band)
        runs, labels, count_islands = R.islands(copper)

        def stroke(points, width_mm, extra_px=0.0):
            canvas.clear()
            paint_paths(canvas, grid, [(np.array(points, dtype=np.float64) * NM_PER_MM,
                                        round(width_mm * NM_PER_MM))], extra_px)
            return canvas.mask()

        across = stroke([(3.0, 2.0), (4.4, 2.0)], 0.3)
        within = stroke([(2.8, 2.0), (3.2, 2.1)], 0.3)
        both = across | within
        print(f"\nbridges ({dpmm} px/mm): two 1 mm squares 0.4 mm apart and a 0.2 mm trace: "
              f"{count_islands} islands (expect 3); a 0.3 mm stroke joining the squares: "
              f"{R.bridges(runs, labels, across | copper)} (expect (1, 1)) at "
              f"{R.bridge_places(runs, labels, across & ~copper)} (rows, cols); one inside a "
              f"square: {R.bridges(runs, labels, within | copper)} (expect (0, 0)); both: "
              f"{R.bridges(runs, labels, both | copper)}")
        # a trace thinner than a pixel samples as dots: one island once joined
        hair = [(3.0, 5.0), (6.0, 5.3)]
        text = _gerber("D13*\n" + _xy(*hair[0]) + "D02*\n" + _xy(*hair[1]) + "D01*\n",
                       {13: "C,0.01"})
        _, hair_grid, hair_copper, *_ = _setup(tmp, "hair.gbr", text, dpmm, band)
        hair_runs, hair_labels, hair_raster = R.islands(hair_copper)
        from galileo_cnc.plan.ink import dark_geometry
        from galileo_cnc.readers import read_file
        joined = R.join_by_outline(hair_runs, hair_labels, hair_grid,
                                   dark_geometry(read_file(tmp / "hair.gbr")).polygons())
        hair_canvas = R.SpanCanvas(hair_grid.height, hair_grid.width)
        paint_paths(hair_canvas, hair_grid, [(np.array(hair) * NM_PER_MM, 300_000)])
        hair_ink = hair_canvas.mask()
        print(f"a 0.01 mm trace samples as {hair_raster} raster islands, joined by our "
              f"geometry: {len(np.unique(joined))} (expect 1); a 0.3 mm pen along it: bridges "
              f"{R.bridges(hair_runs, joined, hair_ink | hair_copper)} (expect (0, 0)), "
              f"without the join {R.bridges(hair_runs, hair_labels, hair_ink | hair_copper)}")
        trace = [(3.0, 4.0), (6.0, 4.3)]
        ink = stroke(trace, 0.3)
        allowance = stroke(trace, 0.3, extra_px=1.0)
        m = measure_ink(copper, disputed, runs, labels, ink, allowance)
        cu_trace = copper & R.dilate(stroke(trace, 0.2), 1)
        print(f"allowance: a 0.3 mm pen along the 0.2 mm trace: inked "
              f"{pct(np.count_nonzero(ink & cu_trace), np.count_nonzero(cu_trace)):.2f} % of the "
              f"trace, outside {m['out_a_px'] + m['out_b_px']} px of which (a) {m['out_a_px']} in "
              f"the allowance, (b) {m['out_b_px']} beyond it (expect 0); exact overdraw "
              f"{0.1 * math.dist(*trace) + math.pi * (0.15 ** 2 - 0.1 ** 2):.3f} mm2 = "
              f"{(0.1 * math.dist(*trace) + math.pi * (0.15 ** 2 - 0.1 ** 2)) * dpmm * dpmm:.0f} px")


# ---- main ---------------------------------------------------------------------------------------

def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a handful of small copper layers")
    ap.add_argument("--limit", type=int, default=None, help="first N files only")
    ap.add_argument("--files", default=None, help="glob on corpus paths, e.g. 'kicad/*'")
    ap.add_argument("--pens", default="0.3", help="ink mode's pens in mm, e.g. 0.3,0.8")
    ap.add_argument("--modes", default="ink,centre", help="comma-separated: ink, centre")
    ap.add_argument("--px-per-mm", type=int, default=40, help="raster resolution (whole px/mm)")
    ap.add_argument("--max-mpx", type=float, default=60.0,
                    help="largest grid in megapixels; bigger boards get fewer px/mm")
    ap.add_argument("--band", type=int, default=2,
                    help="px round pygerber's boundary where our exact geometry decides")
    ap.add_argument("--max-disagree", type=float, default=5.0,
                    help="%% of the copper beyond which pygerber is taken to misread a file")
    ap.add_argument("--tol", type=float, default=0.5, help="chord tolerance in steps")
    ap.add_argument("--jobs", type=int, default=1, help="files measured at once")
    ap.add_argument("--alone", type=int, default=3,
                    help="plannings of the largest layer timed alone after the run (0: none)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per file")
    ap.add_argument("--max-gb", type=float, default=8.0, help="address space per child (0: no cap)")
    ap.add_argument("--png", default=None, help="save an overlay per file and mode in this folder")
    ap.add_argument("--json", default=None, help="save every file's record (JSON) here")
    ap.add_argument("--selftest", action="store_true", help="check the measurement and stop")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--time-plan", help=argparse.SUPPRESS)
    ap.add_argument("--opts", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child_main(args.child, json.loads(args.opts))
        return
    if args.time_plan:
        time_plan_main(args.time_plan, json.loads(args.opts))
        return
    opts = {"pens": [float(p) for p in args.pens.split(",")],
            "modes": [m.strip() for m in args.modes.split(",") if m.strip()],
            "px_per_mm": args.px_per_mm, "max_mpx": args.max_mpx, "band": args.band,
            "max_disagree": args.max_disagree, "tol": args.tol,
            "png": str(Path(args.png).resolve()) if args.png else None}
    if plan_options_class() is None:
        print("ink mode is not available in this checkout (galileo_cnc.plan.pipeline has no "
              "PlanOptions): centre mode only, through plan_file(path, config, 'auto')")
        opts["modes"] = [m for m in opts["modes"] if m != "ink"] or ["centre"]
    if args.selftest:
        selftest(opts)
        return
    files = copper_files(args)
    sizes = sum((CORPUS / f).stat().st_size for f in files)
    print(f"{len(files)} copper layers, {sizes / MB:.1f} MB, modes {', '.join(opts['modes'])}, "
          f"{args.px_per_mm} px/mm (at most {args.max_mpx:g} Mpx), {args.jobs} at a time",
          file=sys.stderr)
    started = time.perf_counter()
    records: list[dict | None] = [None] * len(files)

    def one(k: int) -> None:
        records[k] = run_child(files[k], opts, args.timeout, args.max_gb)
        r = records[k]
        state = r.get("error") or (
            f"{r['dpmm']} px/mm, ref {r['ref']}; pygerber {r.get('pyg_parse_s', 0):.1f} + "
            f"{r.get('pyg_render_s', 0):.1f} s, ours {r.get('dark_s', 0):.1f} s, reference "
            f"{r.get('reference_s', 0):.1f} s, " + ", ".join(
                f"{m}: plan {v.get('plan_s', 0):.1f} walk {v.get('walk_s', 0):.1f} raster "
                f"{v.get('raster_s', 0):.1f} s" for m, v in r["modes"].items()
                if "plan_s" in v) + f"; peak {r.get('peak_mb', 0):.0f} MB")
        print(f"  [{sum(x is not None for x in records)}/{len(files)}] {files[k]}: "
              f"{r.get('wall_s', 0):.1f} s, {state}", file=sys.stderr, flush=True)

    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        list(pool.map(one, range(len(files))))
    done = [r for r in records if r is not None]
    measured = [r for r in done if "error" not in r]
    alone = {}
    if measured and args.alone > 0:
        largest = max(measured, key=lambda r: r["bytes"])["path"]
        print(f"timing the largest layer alone, {args.alone} times: {largest}", file=sys.stderr)
        alone = time_alone(largest, opts, args.alone)
    if args.json:
        Path(args.json).write_text(json.dumps({"opts": opts, "records": done,
                                               "largest_alone_s": alone}, indent=1))
    report(done, opts["modes"], opts, time.perf_counter() - started, alone)


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    main()
