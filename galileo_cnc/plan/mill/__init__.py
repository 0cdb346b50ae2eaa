"""Milling a board on a GRBL machine (docs/mill.md): isolation passes round the exact
copper (isolate.py), the proof that none enters it (proof.py)."""
