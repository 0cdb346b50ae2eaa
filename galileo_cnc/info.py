"""What `galileo-cnc info` reports about a file: counts, apertures, extents, offsets.

All geometry is computed in nm from the Program table; millimetres appear only in
the returned summary (the edge where floats are allowed).
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import arc_extremes
from .program import KIND, NM_PER_MM, POSITIONED_KINDS, TOOL, X, Y, I, J, OpKind, Program

DEFAULT_MARGIN_NM = 1 * NM_PER_MM
_DRAWN = (OpKind.LINE, OpKind.ARC_CW, OpKind.ARC_CCW)


def start_points(table: np.ndarray) -> np.ndarray:
    """(N, 2) start point of every row: the position of the last positioned row before it."""
    starts = np.zeros((len(table), 2), dtype=np.int64)
    if not len(table):
        return starts
    positioned = np.isin(table[:, KIND], POSITIONED_KINDS)
    last = np.maximum.accumulate(np.where(positioned, np.arange(len(table)), -1))
    previous = np.concatenate(([-1], last[:-1]))
    known = previous >= 0
    starts[known] = table[previous[known]][:, [X, Y]]
    return starts


def region_mask(table: np.ndarray) -> np.ndarray:
    """True for rows inside a G36/G37 region (the contour), markers excluded."""
    kind = table[:, KIND]
    depth = np.cumsum((kind == OpKind.REGION_BEGIN).astype(np.int64)
                      - (kind == OpKind.REGION_END).astype(np.int64))
    return (depth > 0) & (kind != OpKind.REGION_BEGIN)


def extents(program: Program, with_apertures: bool = False) -> tuple[int, int, int, int] | None:
    """Bounding box in nm of drawn centre lines (incl. arc extremes) and flash points.

    With `with_apertures`, each drawn point is widened by its aperture's extent.
    None when nothing is drawn.
    """
    table = program.table
    kind = table[:, KIND]
    drawn = np.isin(kind, [int(k) for k in _DRAWN])
    flashes = kind == OpKind.FLASH
    starts = start_points(table)
    boxes = []  # rows of (xmin, ymin, xmax, ymax, tool)
    for rows, from_start in ((drawn, True), (flashes, False)):
        if not rows.any():
            continue
        x, y, tool = table[rows, X], table[rows, Y], table[rows, TOOL]
        if from_start:
            sx, sy = starts[rows, 0], starts[rows, 1]
            boxes.append(np.stack([np.minimum(x, sx), np.minimum(y, sy),
                                   np.maximum(x, sx), np.maximum(y, sy), tool], axis=1))
        else:
            boxes.append(np.stack([x, y, x, y, tool], axis=1))
    arcs = np.flatnonzero(np.isin(kind, [int(OpKind.ARC_CW), int(OpKind.ARC_CCW)]))
    if len(arcs):
        arc_boxes = [arc_extremes(int(starts[r, 0]), int(starts[r, 1]), int(table[r, X]),
                                  int(table[r, Y]), int(table[r, I]), int(table[r, J]),
                                  int(table[r, KIND]) == OpKind.ARC_CW) + (int(table[r, TOOL]),)
                     for r in arcs]
        boxes.append(np.array(arc_boxes, dtype=np.int64))
    if not boxes:
        return None
    all_boxes = np.concatenate(boxes)
    if with_apertures:
        grow = np.zeros((len(all_boxes), 4), dtype=np.int64)
        for code, aperture in program.apertures.items():
            grow[all_boxes[:, 4] == code] = aperture.extent_nm
        all_boxes[:, :4] += grow
    return (int(all_boxes[:, 0].min()), int(all_boxes[:, 1].min()),
            int(all_boxes[:, 2].max()), int(all_boxes[:, 3].max()))


def proposed_offset(program: Program, margin_nm: int = DEFAULT_MARGIN_NM) -> tuple[int, int]:
    """The offset getg proposes (seed rule): minimum coordinate minus a margin.

    Subtracting it from every coordinate puts the artwork's lower-left corner at
    (margin, margin) from the machine origin.
    """
    box = extents(program)
    if box is None:
        return (0, 0)
    return (box[0] - margin_nm, box[1] - margin_nm)


def offset_from_text(text: str) -> tuple[int, int]:
    """An offset the user typed, 'X,Y' or 'X Y' in mm, in nm; ValueError otherwise."""
    parts = text.replace(",", " ").split()
    if len(parts) != 2:
        raise ValueError(f"expected two numbers, X,Y in mm, got {text!r}")
    try:
        x_mm, y_mm = float(parts[0]), float(parts[1])
    except ValueError:
        raise ValueError(f"expected two numbers, X,Y in mm, got {text!r}") from None
    if not (math.isfinite(x_mm) and math.isfinite(y_mm)):
        raise ValueError("the offsets must be finite numbers")
    return round(x_mm * NM_PER_MM), round(y_mm * NM_PER_MM)


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


def summarize(program: Program, margin_nm: int = DEFAULT_MARGIN_NM) -> dict:
    """Everything `galileo-cnc info --json` prints, as plain data (lengths in mm)."""
    table = program.table
    kind = table[:, KIND]
    in_region = region_mask(table)
    box = extents(program)
    offset = proposed_offset(program, margin_nm)
    per_aperture = per_aperture_counts(program)
    return {
        "file": program.source,
        "format": program.format,
        "units": program.units,
        "format_spec": program.metadata.get("format"),
        "line_count": program.line_count,
        "operations": len(program),
        "apertures": [
            {"code": code, "shape": ap.shape, "description": ap.describe(),
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
    }


def format_summary(summary: dict) -> str:
    """The human-readable `info` report."""
    lines = [
        f"file        {summary['file']}",
        f"format      {summary['format']}  units {summary['units']}"
        + (f"  digits {summary['format_spec']}" if summary["format_spec"] else ""),
        f"lines       {summary['line_count']}   operations {summary['operations']}",
    ]
    counts = summary["counts"]
    lines.append(f"counts      {counts['draws']} draws, {counts['arcs']} arcs, "
                 f"{counts['flashes']} flashes, {counts['regions']} regions")
    if summary["apertures"]:
        lines.append("apertures")
        for ap in summary["apertures"]:
            lines.append(f"  D{ap['code']:<4} {ap['description']:<32} {ap['draws']:>6} draws "
                         f"{ap['arcs']:>6} arcs {ap['flashes']:>6} flashes")
    box, full = summary["bbox_mm"], summary["bbox_with_apertures_mm"]
    if box:
        lines.append(f"extent      X {box['min_x']:.4f} .. {box['max_x']:.4f} mm, "
                     f"Y {box['min_y']:.4f} .. {box['max_y']:.4f} mm (centre lines)")
        lines.append(f"            X {full['min_x']:.4f} .. {full['max_x']:.4f} mm, "
                     f"Y {full['min_y']:.4f} .. {full['max_y']:.4f} mm (with apertures)")
        offset = summary["proposed_offset_mm"]
        lines.append(f"minimum     X {box['min_x']:.4f} mm, Y {box['min_y']:.4f} mm")
        lines.append(f"offset      X {offset['x']:.4f} mm, Y {offset['y']:.4f} mm "
                     f"(minimum minus a {summary['margin_mm']} mm margin)")
    else:
        lines.append("extent      nothing is drawn")
    if summary["warnings"]:
        total = sum(summary["warning_counts"].values()) or len(summary["warnings"])
        lines.append(f"warnings    {total}")
        for warning in summary["warnings"]:
            lines.append(f"  {warning}")
    return "\n".join(lines)
