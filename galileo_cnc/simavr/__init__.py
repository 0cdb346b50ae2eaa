"""`simavr://`: the real firmware running in simavr, as a pyserial port.
"""
