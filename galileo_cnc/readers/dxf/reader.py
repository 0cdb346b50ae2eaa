"""Read a DXF drawing (ASCII or binary) into a Program in integer nanometres.

ezdxf parses the file (load.py); a scan of our own (scan.py) checks its structure
and records each entity's line; walk.py expands blocks and turns entities into
paths; emit.py converts each coordinate once to nanometres and writes the rows.
docs/dxf.md describes the mapping and its decisions.
"""

from __future__ import annotations

import os
from typing import Iterable

from galileo_cnc.errors import SourcePos
from galileo_cnc.program.ops import Program, ProgramBuilder
from galileo_cnc.readers import limits
from galileo_cnc.readers.dxf.errors import DxfError
from galileo_cnc.readers.dxf.scan import BINARY_SENTINEL, scan_ascii, scan_binary
from galileo_cnc.readers.dxf.units import INSUNITS, UNIT_NAMES, Scale
from galileo_cnc.readers.source import FileAccessError, check_text, read_bytes

DEFAULT_TOLERANCE_NM = 5000
# Units of the inch family: Program.units says "in" for these, "mm" for the others.
_IMPERIAL = frozenset(["in", "ft", "mi", "uin", "mil", "yd", "us-ft", "us-in", "us-yd", "us-mi"])


def read_dxf(path: str | os.PathLike, *, units: str | None = None,
             layers: Iterable[str] | str | None = None, tolerance_nm: int = DEFAULT_TOLERANCE_NM,
             points: bool = False, max_ops: int | None = None) -> Program:
    """Read the DXF file at `path` (see docs/dxf.md).

    units: "mm" or "in" (or another name in units.UNIT_NAMES) overrides $INSUNITS.
    layers: draw only these layers (names compared case-insensitively); a name the
        file does not have is an error that lists the layers it has.
    tolerance_nm: how far the lines and arcs that stand for an ELLIPSE, a SPLINE or
        a non-uniformly scaled circle may stray from it.
    points: draw POINT entities as dots (a zero-length pen-down).
    max_ops: the op limit (readers/limits.py; None: $GALILEO_MAX_OPS or MAX_OPS). Block
        expansion has its own limit (MAX_BLOCK_ENTITIES, $GALILEO_MAX_BLOCK_ENTITIES).
    """
    name = path if isinstance(path, str) else os.fsdecode(path)
    if not (isinstance(tolerance_nm, (int, float)) and tolerance_nm > 0):
        raise DxfError(SourcePos(name, 0, 0), f"the tolerance must be a positive number of "
                       f"nanometres, not {tolerance_nm!r}")
    override = None
    if units is not None:
        override = UNIT_NAMES.get(units.strip().lower()) if isinstance(units, str) else None
        if override is None:
            raise DxfError(SourcePos(name, 0, 0), f"unknown unit {units!r}: use one of "
                           + ", ".join(sorted(set(UNIT_NAMES) - {"µm"})))
    try:
        data = read_bytes(name)
    except FileAccessError as problem:  # missing, not a regular file, too big
        raise DxfError(SourcePos(name, 0, 0), f"cannot read the file: {problem.why}") from None
    binary = data.startswith(BINARY_SENTINEL)
    if not binary:
        check_text(name, data, DxfError)
    scan = scan_binary(name, data) if binary else scan_ascii(name, data)

    from galileo_cnc.readers.dxf.load import load  # ezdxf is imported only to read a file
    from galileo_cnc.readers.dxf.emit import Emitter
    from galileo_cnc.readers.dxf.walk import Walker, attribute

    doc, load_warnings, recovered = load(name)
    out = ProgramBuilder(name)
    for line, message, text in scan.warnings:
        out.warn(line, 1 if line else 0, message, text)
    for line, message in load_warnings:
        out.warn(line, 1 if line else 0, message)

    # What the file says, from our scan: ezdxf gives a file without a HEADER (an OpenSCAD
    # export, a trimmed or binary R12 file) its own default header, whose $INSUNITS is 6
    # (metres), and that would read a 40 mm part 40 m wide.
    insunits = scan.insunits
    code = override if override is not None else insunits
    if code is None or code == 0 or code not in INSUNITS:
        if override is None:
            what = "no $INSUNITS" if code is None else \
                ("$INSUNITS 0 (unitless)" if code == 0 else f"$INSUNITS {code} (not a length)")
            out.warn(0, 0, f"the drawing has {what}: read as millimetres "
                     "(--units in reads it as inches)")
        code = 4
    unit, factor = INSUNITS[code]
    tolerance_units = tolerance_nm / float(factor)

    # without a TABLES section the layer table is ezdxf's default (0, Defpoints)
    all_layers = _layer_names(doc, attribute, "TABLES" in scan.sections)
    selection = _selection(name, layers, all_layers)
    emitter = Emitter(out, Scale(factor), name)
    emitter.max_ops = limits.max_ops(max_ops)
    walker = Walker(doc, scan, emitter, tolerance_units, selection, points, name)
    walker.run()

    for dxftype, count in sorted(walker.skipped.items()):
        line = walker.first_skipped.get(dxftype, 0)
        how = "drawn only with points=True" if dxftype == "POINT" else "not drawn"
        out.warn(line, 1 if line else 0, f"{count} {dxftype} entit{'y' if count == 1 else 'ies'} "
                 f"{how}")
    if emitter.widths_noted is not None:
        line = emitter.widths_noted
        out.warn(line, 1 if line else 0, "polyline widths are not drawn: the pen follows the "
                 "centre line")
    for message, line in walker.notes.items():
        out.warn(line, 1 if line else 0, message)

    layer_counts = {layer: 0 for layer in all_layers}
    for layer, count in walker.layer_counts.items():
        layer_counts[layer] = layer_counts.get(layer, 0) + count
    metadata = {
        "units": unit,
        "insunits": insunits,
        "nm_per_unit": str(factor),
        "layers": layer_counts,
        # as the drawing spells them
        "selected_layers": [layer for layer in all_layers if layer.casefold() in selection]
        if selection is not None else None,
        "entities": dict(walker.drawn),
        "skipped": dict(walker.skipped),
        "invalid": dict(walker.invalid),
        "handles": emitter.handles,
        "dxf_version": doc.dxfversion,
        "binary": binary,
        "recovered": recovered,
        "tolerance_nm": tolerance_nm,
        "paths": emitter.paths,
        "joined": emitter.joined,
    }
    return out.build("dxf", "in" if unit in _IMPERIAL else "mm", metadata=metadata,
                     line_count=scan.line_count)


def _layer_names(doc, attribute, table: bool = True) -> list[str]:
    """The layers of the file's layer table (if it has one), then any others that
    entities name."""
    names = []
    seen = set()

    def add(layer_name: str) -> None:
        if layer_name.casefold() not in seen:
            seen.add(layer_name.casefold())
            names.append(layer_name)

    for layer in doc.layers if table else ():
        add(layer.dxf.name)
    for layout in (doc.modelspace(), *doc.blocks):
        for entity in layout:
            add(attribute(entity, "layer", "0"))
    return names


def _selection(source: str, layers, all_layers: list[str]) -> set[str] | None:
    if layers is None:
        return None
    wanted = [layers] if isinstance(layers, str) else list(layers)
    known = {layer.casefold() for layer in all_layers}
    unknown = [layer for layer in wanted if layer.casefold() not in known]
    if unknown:
        listing = ", ".join(sorted(all_layers, key=str.casefold)) or "(none)"
        which = ", ".join(repr(layer) for layer in unknown)
        raise DxfError(SourcePos(source, 0, 0),
                       f"no layer {which} in this drawing; its layers are: {listing}")
    return {layer.casefold() for layer in wanted}
