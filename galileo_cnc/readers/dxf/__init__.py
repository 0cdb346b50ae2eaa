"""DXF drawings: read one into a Program (integer nm, rows with their source lines),
recognise DXF files by content. The mapping is in docs/dxf.md.

ezdxf (the parser) is imported when a file is read, not when this package is.
"""

from galileo_cnc.readers.dxf.errors import DxfError
from galileo_cnc.readers.dxf.reader import DEFAULT_TOLERANCE_NM, read_dxf
from galileo_cnc.readers.dxf.sniff import looks_like_dxf

__all__ = ["read_dxf", "looks_like_dxf", "DxfError", "DEFAULT_TOLERANCE_NM"]
