"""One pass over a DXF file's group codes before ezdxf parses it.

ezdxf builds the drawing but keeps no line numbers, and its repair mode
(`ezdxf.recover`) silently reads some broken files (truncated ones, values with a
decimal comma) as something else. This scan does what ezdxf does not:

- refuses what cannot be trusted, with the line: a group code that is not an
  integer, a number that does not parse, a value missing at the end, a section
  that never ends (a truncated file), a section that appears twice;
- tolerates, with a warning, what real writers produce: tags outside any section
  (dxflib 2 ends the HEADER early and writes the rest of it after the ENDSEC),
  a missing EOF;
- records where each entity starts (the line of its `0` group code), with the
  lines of its vertices (LWPOLYLINE `10` codes, POLYLINE `VERTEX` entities), by
  handle and by position in its section or block, so rows can name their source;
- picks up `$INSUNITS` wherever the header variables are.

A binary DXF goes through the same state machine with tags decoded by ezdxf's
binary tag loader; there are no lines then (line 0 in the maps).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field

from galileo_cnc.errors import SourcePos, excerpt
from galileo_cnc.readers.dxf.errors import DxfError

BINARY_SENTINEL = b"AutoCAD Binary DXF\r\n\x1a\x00"

# Group codes whose values are floating point numbers (DXF reference).
_DOUBLE = frozenset([*range(10, 60), *range(110, 150), *range(210, 240), *range(460, 470),
                     *range(1010, 1060)])
_SECTIONS_ONCE = frozenset(["HEADER", "CLASSES", "TABLES", "BLOCKS", "ENTITIES", "OBJECTS",
                            "THUMBNAILIMAGE", "ACDSDATA"])
_SUB_ENTITIES = frozenset(["VERTEX", "SEQEND", "ATTRIB"])
MODELSPACE = "*ENTITIES"  # key of the ENTITIES section in `Scan.layouts`


@dataclass(slots=True)
class EntityLines:
    """Where one entity sits in the file."""

    dxftype: str
    line: int  # line of its `0` group code (0 in a binary file)
    handle: str | None = None
    paperspace: bool = False
    vertex_lines: list[int] = field(default_factory=list)  # LWPOLYLINE 10s, POLYLINE VERTEXes
    vertex_handles: list[str | None] = field(default_factory=list)


@dataclass(slots=True)
class Scan:
    binary: bool = False
    line_count: int = 0
    insunits: int | None = None
    acadver: str | None = None
    sections: list[str] = field(default_factory=list)  # names of the sections, in order
    handles: dict[str, EntityLines] = field(default_factory=dict)
    layouts: dict[str, list[EntityLines]] = field(default_factory=dict)
    vertex_by_handle: dict[str, int] = field(default_factory=dict)
    warnings: list[tuple[int, str, str]] = field(default_factory=list)  # (line, message, text)


class _Machine:
    """The section / block / entity state machine, fed one tag at a time."""

    def __init__(self, source: str, scan: Scan):
        self.source = source
        self.scan = scan
        self.section: str | None = None
        self.section_line = 0
        self.seen: dict[str, int] = {}
        self.expect_section_name = False
        self.last_closed: str | None = None
        self.block: str | None = None  # name of the BLOCK being read, once known
        self.block_entities: list[EntityLines] | None = None
        self.entity: EntityLines | None = None  # the current top-level entity
        self.vertex: bool = False  # inside a VERTEX of self.entity
        self.in_block_header = False
        self.header_var: str | None = None
        self.warned_outside = False
        self.ended = False

    def fail(self, line: int, message: str, text: str = "") -> DxfError:
        return DxfError(SourcePos(self.source, max(line, 1), 1), message, text)

    def warn(self, line: int, message: str, text: str = "") -> None:
        self.scan.warnings.append((line, message, excerpt(text)))

    def tag(self, code: int, value, line: int) -> None:
        if self.expect_section_name:
            self.expect_section_name = False
            if code != 2:
                raise self.fail(line, "expected the section name (group code 2) after SECTION",
                                f"{code}")
            name = str(value).strip().upper()
            if name in _SECTIONS_ONCE and name in self.seen:
                raise self.fail(line, f"the {name} section appears a second time (first at line "
                                f"{self.seen[name]}): a DXF file has each section once; the file "
                                "is damaged or two files were joined", str(value))
            self.seen[name] = line
            self.scan.sections.append(name)
            self.section = name
            return
        if code == 999:
            return  # a comment, allowed anywhere
        if code == 0:
            self._structure(str(value).strip(), line)
            return
        if self.section is None:
            if not self.warned_outside:
                self.warned_outside = True
                after = f" after the {self.last_closed} section" if self.last_closed else ""
                self.warn(line, f"group codes outside any section{after} are ignored "
                          "(a writer closed a section early)", f"{code} {value}")
            if self.last_closed == "HEADER":
                self._header(code, value)
            return
        if self.section == "HEADER":
            self._header(code, value)
        elif self.entity is not None:
            self._entity_tag(code, value, line)
        elif self.in_block_header and code == 2 and self.block is None:
            self.block = str(value).strip().upper()
            self.block_entities = self.scan.layouts.setdefault(self.block, [])

    def _header(self, code: int, value) -> None:
        if code == 9:
            self.header_var = str(value).strip().upper()
        elif self.header_var == "$INSUNITS" and code == 70:
            try:
                self.scan.insunits = int(str(value).strip())
            except ValueError:
                pass
        elif self.header_var == "$ACADVER" and code == 1:
            self.scan.acadver = str(value).strip()

    def _entity_tag(self, code: int, value, line: int) -> None:
        entity = self.entity
        if code == 5:
            handle = str(value).strip().upper()
            if self.vertex:
                entity.vertex_handles[-1] = handle
                self.scan.vertex_by_handle.setdefault(handle, entity.vertex_lines[-1])
            elif entity.handle is None:
                entity.handle = handle
                self.scan.handles.setdefault(handle, entity)
        elif code == 10 and entity.dxftype == "LWPOLYLINE" and not self.vertex:
            entity.vertex_lines.append(line)
        elif code == 67 and not self.vertex and str(value).strip() == "1":
            entity.paperspace = True

    def _structure(self, name: str, line: int) -> None:
        upper = name.upper()
        if upper == "SECTION":
            if self.section is not None:
                raise self.fail(line, f"SECTION inside the {self.section} section (started at "
                                f"line {self.section_line}): its ENDSEC is missing", name)
            self.expect_section_name = True
            self.section_line = line
            self.entity = None
            return
        if upper == "ENDSEC":
            if self.section is None:
                self.warn(line, "ENDSEC without a SECTION is ignored", name)
            self.last_closed = self.section or self.last_closed
            self.section = None
            self.entity = None
            self.block = None
            return
        if upper == "EOF":
            if self.section is not None:
                raise self.fail(line, f"EOF inside the {self.section} section (started at line "
                                f"{self.section_line}): its ENDSEC is missing", name)
            self.ended = True
            return
        if self.section is None:
            if not self.warned_outside:
                self.warned_outside = True
                self.warn(line, "group codes outside any section are ignored", name)
            return
        if self.section == "BLOCKS":
            self._blocks(upper, line)
        elif self.section == "ENTITIES":
            self._new_entity(upper, line, self.scan.layouts.setdefault(MODELSPACE, []))

    def _blocks(self, upper: str, line: int) -> None:
        if upper == "BLOCK":
            self.in_block_header = True
            self.block = None
            self.block_entities = None
            self.entity = None
            return
        if upper == "ENDBLK":
            self.in_block_header = False
            self.entity = None
            self.block_entities = None
            return
        self.in_block_header = False
        if self.block_entities is not None:
            self._new_entity(upper, line, self.block_entities)

    def _new_entity(self, upper: str, line: int, layout: list[EntityLines]) -> None:
        if upper in _SUB_ENTITIES and self.entity is not None:
            self.vertex = upper == "VERTEX"
            if self.vertex:
                self.entity.vertex_lines.append(line)
                self.entity.vertex_handles.append(None)
            return
        self.vertex = False
        self.entity = EntityLines(upper, line)
        layout.append(self.entity)

    def finish(self, last_line: int) -> None:
        if self.expect_section_name or self.section is not None:
            where = self.section or "a"
            raise self.fail(last_line, f"the file ends inside {where} section (started at line "
                            f"{self.section_line}) without its ENDSEC: it is truncated")
        if not self.ended:
            self.warn(last_line, "the file has no EOF marker")


def scan_ascii(source: str, data: bytes) -> Scan:
    """Scan ASCII DXF bytes; raises DxfError naming the line of what is wrong."""
    scan = Scan()
    machine = _Machine(source, scan)
    lines = data.splitlines()
    if lines and lines[0].startswith(b"\xef\xbb\xbf"):
        lines[0] = lines[0][3:]
    count = len(lines)
    scan.line_count = count
    tag = machine.tag
    double = _DOUBLE
    index = 0
    while index < count:
        raw_code = lines[index]
        line = index + 1
        try:
            code = int(raw_code)
        except ValueError:
            stripped = raw_code.strip()
            if not stripped and index >= count - 2 and machine.ended:
                break
            raise machine.fail(line, "expected a group code (an integer)",
                               raw_code.decode("latin-1")) from None
        if index + 1 >= count:
            raise machine.fail(line, f"the file ends after group code {code} without its value: "
                               "it is truncated", raw_code.decode("latin-1"))
        value = lines[index + 1]
        if code in double:
            try:
                float(value)
            except ValueError:
                raise machine.fail(line + 1, f"expected a number for group code {code}",
                                   value.decode("latin-1")) from None
        if code == 0 or code == 2 or code == 5 or code == 9 or code == 1 or code == 70:
            tag(code, value.decode("latin-1"), line)
        else:
            tag(code, value, line)
        index += 2
        if machine.ended:
            break
    machine.finish(max(min(index, count), 1))
    return scan


_OFFSET = re.compile(r"offset (\d+)")


def scan_binary(source: str, data: bytes) -> Scan:
    """Scan a binary DXF with ezdxf's tag decoder; errors name the byte offset."""
    from ezdxf.lldxf.tagger import binary_tags_loader

    scan = Scan(binary=True)
    machine = _Machine(source, scan)
    count = 0
    try:
        for dxftag in binary_tags_loader(data, errors="replace"):
            count += 1
            value = dxftag.value
            machine.tag(dxftag.code, value if isinstance(value, (str, bytes)) else str(value), 0)
            if machine.ended:
                break
    except DxfError as problem:
        raise DxfError(problem.pos, f"{problem.message} (binary DXF, tag {count + 1})") from None
    except (struct.error, IndexError, ValueError, UnicodeError) as problem:
        found = _OFFSET.search(str(problem))
        where = f"at byte {found.group(1)}" if found else f"after tag {count}"
        raise machine.fail(1, f"binary DXF damaged or truncated {where} of {len(data)} bytes "
                           f"({problem})") from None
    try:
        machine.finish(1)
    except DxfError as problem:
        raise DxfError(problem.pos, f"{problem.message} (binary DXF, {count} tags, "
                       f"{len(data)} bytes)") from None
    scan.warnings = [(0, message, text) for _, message, text in scan.warnings]
    return scan
