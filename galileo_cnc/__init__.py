"""galileo-cnc: plot PCB artwork, G-code and DXF drawings on home-built CNC pen plotters."""

__version__ = "0.1.0"
from galileo_cnc.transport import port as _port  # noqa: E402,F401  registers sim://, simavr://
