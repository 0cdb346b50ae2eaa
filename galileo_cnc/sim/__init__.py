"""`sim://`: the reference machine behind the wire protocol, as a pyserial port.
"""
