"""Where a Program draws: its extents in nm, from the op table (arcs by their true extremes)."""

from __future__ import annotations

import numpy as np

from galileo_cnc.program.geometry import arc_extremes
from galileo_cnc.program.ops import KIND, POSITIONED_KINDS, TOOL, VALUE, X, Y, I, J, OpKind, Program

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


def dark_mask(table: np.ndarray) -> np.ndarray:
    """True for rows under dark polarity: the last %LP before them (dark at the start)."""
    kind = table[:, KIND]
    last = np.maximum.accumulate(np.where(kind == OpKind.POLARITY, np.arange(len(table)), -1))
    return np.where(last >= 0, table[np.maximum(last, 0), VALUE] != 0, True)


def region_mask(table: np.ndarray) -> np.ndarray:
    """True for rows inside a G36/G37 region (the contour), markers excluded."""
    kind = table[:, KIND]
    depth = np.cumsum((kind == OpKind.REGION_BEGIN).astype(np.int64)
                      - (kind == OpKind.REGION_END).astype(np.int64))
    return (depth > 0) & (kind != OpKind.REGION_BEGIN)


def extents(program: Program, with_apertures: bool = False,
            visited: bool = False) -> tuple[int, int, int, int] | None:
    """Bounding box in nm of drawn centre lines (incl. arc extremes) and flash points.

    With `with_apertures`, each drawn point is widened by its aperture's extent.
    With `visited`, the points the machine travels to (moves) count too, so the box
    holds everything the job does. None when nothing is drawn.
    """
    table = program.table
    kind = table[:, KIND]
    drawn = np.isin(kind, [int(k) for k in _DRAWN])
    if not drawn.any() and not (kind == OpKind.FLASH).any():
        return None
    flashes = (kind == OpKind.FLASH) | ((kind == OpKind.MOVE) if visited else False)
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
    grow = _grower(program, with_apertures)
    box = _union(grow(np.concatenate(boxes))) if boxes else None
    arcs = np.flatnonzero(np.isin(kind, [int(OpKind.ARC_CW), int(OpKind.ARC_CCW)]))
    if box is not None and len(arcs):
        # an arc inside its whole circle, and that inside the box so far, adds nothing:
        # only the others need their extremes (ink has tens of thousands of arcs)
        centre = starts[arcs] + table[arcs][:, [I, J]]
        radius = np.ceil(np.hypot(table[arcs, I], table[arcs, J]).astype(np.float64)) + 1
        circles = grow(np.column_stack([centre - radius[:, None], centre + radius[:, None],
                                        table[arcs, TOOL]]).astype(np.int64))
        inside = ((circles[:, 0] >= box[0]) & (circles[:, 1] >= box[1])
                  & (circles[:, 2] <= box[2]) & (circles[:, 3] <= box[3]))
        arcs = arcs[~inside]
    if len(arcs):
        arc_boxes = [arc_extremes(int(starts[r, 0]), int(starts[r, 1]), int(table[r, X]),
                                  int(table[r, Y]), int(table[r, I]), int(table[r, J]),
                                  int(table[r, KIND]) == OpKind.ARC_CW) + (int(table[r, TOOL]),)
                     for r in arcs]
        arc_box = _union(grow(np.array(arc_boxes, dtype=np.int64)))
        box = arc_box if box is None else (min(box[0], arc_box[0]), min(box[1], arc_box[1]),
                                           max(box[2], arc_box[2]), max(box[3], arc_box[3]))
    return box


def _grower(program: Program, with_apertures: bool):
    """Boxes (x0, y0, x1, y1, tool) widened by their aperture's extent, or as they are."""
    def grow(boxes: np.ndarray) -> np.ndarray:
        if with_apertures:
            boxes = boxes.copy()
            for code, aperture in program.apertures.items():
                boxes[boxes[:, 4] == code, :4] += np.asarray(aperture.extent_nm, dtype=np.int64)
        return boxes
    return grow


def union_box(*boxes):
    """The box (xmin, ymin, xmax, ymax) around every box given; None ones are left
    out, and None for none at all."""
    boxes = [b for b in boxes if b is not None]
    if not boxes:
        return None
    return (min(b[0] for b in boxes), min(b[1] for b in boxes),
            max(b[2] for b in boxes), max(b[3] for b in boxes))


def _union(boxes: np.ndarray) -> tuple[int, int, int, int]:
    return (int(boxes[:, 0].min()), int(boxes[:, 1].min()),
            int(boxes[:, 2].max()), int(boxes[:, 3].max()))
