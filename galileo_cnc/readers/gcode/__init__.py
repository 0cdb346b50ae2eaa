"""G-code: read a drawing into a Program, recognise G-code files, write Programs back.

`read_gcode` turns a file into a Program (integer nm, each op with its line and
column), `looks_like_gcode` sniffs content, and `write_gcode` exports a Program
as G-code that reads back to the same ops. The dialect is in docs/gcode.md.
"""

from galileo_cnc.readers.gcode.reader import read_gcode
from galileo_cnc.readers.gcode.sniff import looks_like_gcode
from galileo_cnc.readers.gcode.writer import GcodeExportError, gcode_lines, write_gcode

__all__ = ["read_gcode", "looks_like_gcode", "write_gcode", "gcode_lines", "GcodeExportError"]
