"""Reaching the machine: opening ports (pyserial), finding boards, and the link
(greeting, reader thread, status).
"""
