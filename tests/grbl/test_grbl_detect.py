"""Port probing recognises GRBL: by its banner when opening resets the board,
by its replies to our version request and to `$I` when it stays silent."""

from __future__ import annotations

import os

from galileo_cnc.grbl import firmware
from galileo_cnc.transport.discovery import GRBL, identify_board
from galileo_cnc.transport.port import is_pseudo_terminal

from grbl_support import grbl_elf


def test_grbl_identified_by_banner_then_by_its_replies():
    with firmware.grbl_board(grbl_elf(), trace=False) as board:
        # the first open starts the AVR: GRBL's banner arrives
        assert identify_board(board.port, 115200) == GRBL
        # a re-open does not reset the simulated board: GRBL says nothing until
        # asked; our framed `V` earns an error:N, `$I` its [VER:1.1h...]
        assert identify_board(board.port, 115200) == GRBL
        board.stop()
    assert board.summary["overruns"] == "0"


def test_a_pseudo_terminal_is_asked_at_once_a_usb_port_after_its_boot():
    """A pty (the simulator, socat) has no DTR to reset a board on opening, so probing
    asks `V` at once instead of giving a boot loader half the banner wait."""
    main, side = os.openpty()
    try:
        assert is_pseudo_terminal(os.ttyname(side))
    finally:
        os.close(main)
        os.close(side)
    assert not is_pseudo_terminal("/dev/ttyUSB0") and not is_pseudo_terminal("/dev/null")
