"""`galileo-cnc info FILE`: what a file holds and the offsets getg proposes; for an
Excellon drill file, its tools, holes and slots.

All geometry is computed in nm from the Program table; millimetres appear only in
the returned summary (the edge where floats are allowed).
"""

from __future__ import annotations

import json
from typing import Callable

import numpy as np

from galileo_cnc.command_text import fixed_text
from galileo_cnc.config.machine import MachineConfig
from galileo_cnc.plan.measure import job_lengths
from galileo_cnc.plan.open_traces import ink_warnings, open_traces
from galileo_cnc.plan.pipeline import Artwork, PlanOptions, plan_file
from galileo_cnc.program.drills import DrillFile
from galileo_cnc.program.extents import extents, region_mask
from galileo_cnc.readers.gerber.transformed import aperture_label
from galileo_cnc.program.ops import KIND, NM_PER_MM, TOOL, OpKind, Program


def per_aperture_counts(program: Program) -> dict[int, dict[str, int]]:
    """Draws, arcs and flashes per aperture, region contours excluded."""
    table = program.table[~region_mask(program.table)]
    result: dict[int, dict[str, int]] = {}
    for name, kinds in (("draws", [OpKind.LINE]), ("arcs", [OpKind.ARC_CW, OpKind.ARC_CCW]),
                        ("flashes", [OpKind.FLASH])):
        rows = table[np.isin(table[:, KIND], [int(k) for k in kinds])]
        codes, counts = np.unique(rows[:, TOOL], return_counts=True)
        for code, count in zip(codes.tolist(), counts.tolist()):
            result.setdefault(code, {"draws": 0, "arcs": 0, "flashes": 0})[name] = count
    return result


def _mm(nm: int) -> float:
    return round(nm / NM_PER_MM, 6)


def _box_mm(box):
    if box is None:
        return None
    return {"min_x": _mm(box[0]), "min_y": _mm(box[1]), "max_x": _mm(box[2]), "max_y": _mm(box[3])}


def summarize(artwork: Artwork) -> dict:
    """Everything `galileo-cnc info --json` prints, as plain data (lengths in mm)."""
    program, margin_nm = artwork.program, artwork.margin_nm
    table = program.table
    kind = table[:, KIND]
    in_region = region_mask(table)
    box = artwork.drawn_box_nm
    offset = artwork.proposal_nm
    per_aperture = per_aperture_counts(program)
    return {
        "file": program.source,
        "format": program.format,
        "units": program.metadata.get("units") or program.units,   # a DXF may be in m, cm, ft
        "format_spec": program.metadata.get("format"),
        "line_count": program.line_count,
        "operations": len(program),
        "apertures": [
            {"code": code, "label": aperture_label(program, code), "shape": ap.shape,
             "description": ap.describe(),
             "size_mm": [_mm(v) for v in ap.params_nm], "hole_mm": [_mm(v) for v in ap.hole_nm],
             "macro": ap.macro, **per_aperture.get(code, {"draws": 0, "arcs": 0, "flashes": 0})}
            for code, ap in sorted(program.apertures.items())],
        "counts": {
            "draws": int(((kind == OpKind.LINE) & ~in_region).sum()),
            "arcs": int((np.isin(kind, [int(OpKind.ARC_CW), int(OpKind.ARC_CCW)]) & ~in_region).sum()),
            "flashes": int((kind == OpKind.FLASH).sum()),
            "regions": int((kind == OpKind.REGION_BEGIN).sum()),
        },
        "bbox_mm": _box_mm(box),
        "bbox_with_apertures_mm": _box_mm(extents(program, with_apertures=True)),
        "min_mm": None if box is None else {"x": _mm(box[0]), "y": _mm(box[1])},
        "margin_mm": _mm(margin_nm),
        "proposed_offset_mm": {"x": _mm(offset[0]), "y": _mm(offset[1])},
        "warnings": [str(w) for w in program.warnings],
        "warning_counts": program.metadata.get("warning_counts", {}),
        # DXF: every layer with the entities it holds, and the ones read (None: all)
        "layers": program.metadata.get("layers"),
        "selected_layers": program.metadata.get("selected_layers"),
    }


def plan_summary(artwork: Artwork, config: MachineConfig, options: PlanOptions,
                 on_stage: Callable[[str], None] | None = None,
                 verbose: bool = False) -> tuple[str, dict]:
    """("ink", ink_summary) in ink mode, else ("plan", the job's lengths): the figures
    of the whole plan, which info works out only on request (--plan: seconds on a
    large board). `verbose`: every warning (else left-out trace pieces as one summary)."""
    if artwork.misfit(config) is not None:
        # the plan of a board too big for this machine is still worth knowing (the
        # summary says it does not fit): measured on a machine whose travel holds it
        config = _holding(config, artwork)
    planned = plan_file(artwork, config, "auto", options=options, on_stage=on_stage)
    lengths = job_lengths(planned.job)
    mm_per_step = config.nm_per_step / NM_PER_MM
    if planned.ink is None:
        return "plan", {"pen_down_mm": round(lengths.drawn_steps * mm_per_step, 1),
                        "pen_up_mm": round(lengths.travel_steps * mm_per_step, 1),
                        "pen_lifts": lengths.lifts,
                        "pen_changes": len(planned.job.pen_changes)}
    figures = ink_summary(planned, lengths, mm_per_step, verbose)
    # the offset getg proposes in ink mode: from where the fills go, not the centre lines
    offset, margin = planned.offset_nm, artwork.margin_nm
    figures["min_mm"] = {"x": _mm(offset[0] + margin), "y": _mm(offset[1] + margin)}
    figures["proposed_offset_mm"] = {"x": _mm(offset[0]), "y": _mm(offset[1])}
    return "ink", figures


def ink_summary(planned, lengths, mm_per_step: float, verbose: bool = False) -> dict:
    """What the pens make of the copper: areas, pen-down length, lifts, narrow
    features, the trace pieces left out."""
    ink = planned.ink
    traces = open_traces(ink)
    return {
        "pens_mm": [_mm(w) for w in ink.pens_nm],
        "copper_mm2": round(ink.copper_nm2 / NM_PER_MM ** 2, 3),
        "filled_mm2": round(ink.filled_nm2 / NM_PER_MM ** 2, 3),
        "inked_mm2": round(ink.inked_nm2 / NM_PER_MM ** 2, 3),
        "pen_down_mm": round(lengths.drawn_steps * mm_per_step, 1),
        "pen_up_mm": round(lengths.travel_steps * mm_per_step, 1),
        "pen_lifts": lengths.lifts,
        "pen_changes": len(planned.job.pen_changes),
        "narrow_features": sum(not feature.neck for feature in ink.narrow),
        "necks_drawn": len(ink.necks),
        "necks_left": len(ink.necks_left),
        "bridges_avoided": len(ink.bridges),
        "close_island_pairs": ink.close.count,
        "planning_s": round(ink.seconds, 2),
        "open_traces": None if traces is None else {
            "pieces": traces.pieces, "total_mm": _mm(traces.total_nm),
            "longest_mm": _mm(traces.longest_nm), "longest_at": str(traces.longest_at),
            "widest_pen_mm": _mm(traces.widest_pen_nm)},
        "warnings": ink_warnings(ink, verbose),
    }


def _holding(config: MachineConfig, artwork: Artwork) -> MachineConfig:
    """`config` with travel for the artwork, its margin and the ink past its centre
    lines (twice its size on each axis: the ink reaches a pen radius past the copper)."""
    x0, y0, x1, y1 = artwork.visited_box_nm
    return config.replace(x_travel_mm=max(config.x_travel_mm, 2 * (x1 - x0) / NM_PER_MM),
                          y_travel_mm=max(config.y_travel_mm, 2 * (y1 - y0) / NM_PER_MM))


#: file warnings info prints without --verbose (a layer may have thousands)
SHOWN_WARNINGS = 10


def format_summary(summary: dict, verbose: bool = False) -> str:
    """The human-readable `info` report; `verbose`: every file warning."""
    lines = [
        f"file        {summary['file']}",
        f"format      {summary['format']}  units {summary['units']}"
        + (f"  digits {summary['format_spec']}" if summary["format_spec"] else ""),
        f"lines       {summary['line_count']}   operations {summary['operations']}",
    ]
    counts = summary["counts"]
    lines.append(f"counts      {counts['draws']} draws, {counts['arcs']} arcs, "
                 f"{counts['flashes']} flashes, {counts['regions']} regions")
    if summary.get("layers"):
        chosen = summary["selected_layers"]
        lines.append(f"layers      {len(summary['layers'])}"
                     + (f", reading {', '.join(chosen)}" if chosen else "")
                     + " (--layers A,B picks them)")
        for name, count in summary["layers"].items():
            lines.append(f"  {name:<30} {count:>6} entities")
    if summary["apertures"]:
        lines.append("apertures")
        for ap in summary["apertures"]:
            lines.append(f"  {ap['label']:<5} {ap['description']:<32} {ap['draws']:>6} draws "
                         f"{ap['arcs']:>6} arcs {ap['flashes']:>6} flashes")
    box, full = summary["bbox_mm"], summary["bbox_with_apertures_mm"]
    if box:
        lines.append(f"extent      X {box['min_x']:.4f} .. {box['max_x']:.4f} mm, "
                     f"Y {box['min_y']:.4f} .. {box['max_y']:.4f} mm (centre lines)")
        lines.append(f"            X {full['min_x']:.4f} .. {full['max_x']:.4f} mm, "
                     f"Y {full['min_y']:.4f} .. {full['max_y']:.4f} mm (with apertures)")
        inked = summary.get("ink") or {}
        offset = inked.get("proposed_offset_mm") or summary["proposed_offset_mm"]
        low = inked.get("min_mm") or {"x": box["min_x"], "y": box["min_y"]}
        lines.append(f"minimum     X {fixed_text(low['x'], 4)} mm, Y "
                     f"{fixed_text(low['y'], 4)} mm"
                     + (" (where the pen goes, fills included)" if inked else ""))
        lines.append(f"offset      X {fixed_text(offset['x'], 4)} mm, Y "
                     f"{fixed_text(offset['y'], 4)} mm "
                     f"(minimum minus a {summary['margin_mm']} mm margin)")
        if not inked and summary.get("inked_by_default"):
            lines.append("            in ink mode the fills reach past the centre lines: "
                         "info --plan gives the offset getg and plot propose")
    else:
        lines.append("extent      nothing is drawn")
    if summary.get("misfit"):
        lines.append(f"travel      does not fit: {summary['misfit'].split(': ', 1)[-1]}")
    ink = summary.get("ink")
    if ink:
        copper = ink["copper_mm2"] or 1.0
        pens = ", ".join(f"{w:g}" for w in ink["pens_mm"])
        lines.append(f"ink         pens {pens} mm: copper {ink['copper_mm2']:.2f} mm2, "
                     f"filled {100 * ink['filled_mm2'] / copper:.1f} %, inked with centre "
                     f"lines {100 * ink['inked_mm2'] / copper:.1f} %")
        lines.append(f"            pen down {ink['pen_down_mm'] / 1000:.2f} m, pen up "
                     f"{ink['pen_up_mm'] / 1000:.2f} m, {ink['pen_lifts']} pen lifts, "
                     f"{ink['narrow_features']} narrow features drawn as centre lines"
                     + (f", {ink['necks_drawn']} necks drawn" if ink["necks_drawn"] else "")
                     + (f", {ink['necks_left']} left bare" if ink["necks_left"] else "")
                     + (f", {ink['bridges_avoided']} bridges avoided" if ink["bridges_avoided"]
                        else "")
                     + (f", {ink['close_island_pairs']} pair"
                        f"{'s' * (ink['close_island_pairs'] != 1)} of islands too close "
                        "kept apart" if ink["close_island_pairs"] else ""))
        for warning in ink["warnings"]:
            lines.append(f"  {warning}")
    plan = summary.get("plan")
    if plan:
        lines.append(f"plan        pen down {plan['pen_down_mm'] / 1000:.2f} m, pen up "
                     f"{plan['pen_up_mm'] / 1000:.2f} m, {plan['pen_lifts']} pen lifts, "
                     f"{plan['pen_changes']} pen changes")
    if not ink and not plan:
        lines.append("plan        --plan works out the job: pen-down and travel lengths"
                     + ("; on Gerber the ink and the trace pieces it leaves out"
                        if summary["format"] == "gerber" else "")
                     + " (seconds on a large board)")
    if summary["warnings"]:
        total = sum(summary["warning_counts"].values()) or len(summary["warnings"])
        lines.append(f"warnings    {total}")
        shown = summary["warnings"] if verbose else summary["warnings"][:SHOWN_WARNINGS]
        for warning in shown:
            lines.append(f"  {warning}")
        if len(shown) < len(summary["warnings"]):
            lines.append(f"  ... and {len(summary['warnings']) - len(shown):,} more "
                         "(--verbose lists them all)")
    return "\n".join(lines)


# ---- drill files (Excellon): holes and slots, not a drawing ---------------------------

def drill_summary(drill: DrillFile) -> dict:
    """Everything `galileo-cnc info --json DRILLFILE` prints (lengths in mm): the tools
    with their hole and slot counts, the extent, and every hole and slot."""
    per_tool: dict[str, dict[str, int]] = {name: {"holes": 0, "slots": 0} for name in drill.tools}
    for hole in drill.holes:
        per_tool.setdefault(hole.tool, {"holes": 0, "slots": 0})["holes"] += 1
    for slot in drill.slots:
        per_tool.setdefault(slot.tool, {"holes": 0, "slots": 0})["slots"] += 1
    box = drill.box_nm()
    return {
        "file": drill.source,
        "format": "excellon",
        "units": drill.units,
        "format_spec": drill.metadata.get("format"),
        "generator": drill.metadata.get("generator") or None,
        "assumed": drill.metadata.get("assumed", []),
        "plated": drill.plated,
        "plated_from": drill.metadata.get("plated_from"),
        "line_count": drill.line_count,
        "tools": [{"tool": name, "diameter_mm": _mm(drill.tools.get(name, 0)), **counts}
                  for name, counts in per_tool.items()],
        "counts": {"holes": len(drill.holes), "slots": len(drill.slots)},
        "bbox_mm": _box_mm(box),
        "holes": [{"x_mm": _mm(h.x_nm), "y_mm": _mm(h.y_nm), "diameter_mm": _mm(h.diameter_nm),
                   "tool": h.tool, "plated": h.plated, "line": h.line} for h in drill.holes],
        "slots": [{"x0_mm": _mm(s.x0_nm), "y0_mm": _mm(s.y0_nm), "x1_mm": _mm(s.x1_nm),
                   "y1_mm": _mm(s.y1_nm), "diameter_mm": _mm(s.diameter_nm), "tool": s.tool,
                   "plated": s.plated, "line": s.line,
                   **({"arc": s.arc, "cx_mm": _mm(s.cx_nm), "cy_mm": _mm(s.cy_nm)} if s.arc else {})}
                  for s in drill.slots],
        "warnings": drill.metadata.get("warnings", []),
    }


def format_drill_summary(summary: dict, verbose: bool = False) -> str:
    """The human-readable `info` report of a drill file."""
    plated = {True: "plated", False: "unplated", None: "plating not stated"}[summary["plated"]]
    lines = [
        f"file        {summary['file']}",
        f"format      Excellon drill  units {summary['units']}  {summary['format_spec']}"
        + (f"  ({summary['generator']})" if summary["generator"] else ""),
        f"lines       {summary['line_count']}   {plated}"
        + (f" (from {summary['plated_from']})" if summary["plated_from"] else ""),
        f"counts      {summary['counts']['holes']} holes, {summary['counts']['slots']} slots",
    ]
    for note in summary["assumed"]:
        lines.append(f"assumed     {note}")
    if summary["tools"]:
        lines.append("tools")
        for tool in summary["tools"]:
            lines.append(f"  {tool['tool']:<5} {tool['diameter_mm']:>8.4f} mm  "
                         f"{tool['holes']:>6} holes {tool['slots']:>5} slots")
    box = summary["bbox_mm"]
    if box:
        lines.append(f"extent      X {box['min_x']:.4f} .. {box['max_x']:.4f} mm, "
                     f"Y {box['min_y']:.4f} .. {box['max_y']:.4f} mm (holes included)")
    else:
        lines.append("extent      no holes")
    if summary["warnings"]:
        shown = summary["warnings"] if verbose else summary["warnings"][:SHOWN_WARNINGS]
        lines.append(f"warnings    {len(summary['warnings'])}")
        lines.extend(f"  {w}" for w in shown)
    return "\n".join(lines)


def drill_report(path: str, as_json: bool, verbose: bool = False) -> str | None:
    """`info` of an Excellon file (the text to print), or None if `path` is not one."""
    from galileo_cnc.readers import is_drill_file, read_drill

    if not is_drill_file(path):
        return None
    summary = drill_summary(read_drill(path))
    return json.dumps(summary, indent=2) if as_json else format_drill_summary(summary, verbose)
