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
