"""Milling a board on a GRBL machine (docs/mill.md): isolation passes round the exact
copper and the shorts they leave (isolate.py), the proof that no pass enters the copper
(proof.py), the passes as G-code for any sender (gcode.py)."""
