"""galileo-cnc: plot PCB artwork and G-code drawings on home-built CNC pen plotters."""

__version__ = "0.1.0"
