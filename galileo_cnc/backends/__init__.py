"""What speaks to a board: one Machine interface (base.py) for our firmware
(galileo.py: a board, `sim://`, `simavr://`) and stock GRBL 1.1 (grbl.py).

`open_machine` asks the port who answers, once (transport.discovery.open_board),
and opens the right kind; every front end (the console, `plot`) goes through it.
"""

from __future__ import annotations

from galileo_cnc.backends.base import (JobResult, Machine, MachineJob, MachineView, Operator,
                                       Resumption)
from galileo_cnc.config.profile import Profile
from galileo_cnc.transport.discovery import GRBL, open_board


def open_machine(port: str | None, profile: Profile, *, config=None, on_message=None,
                 handle=None, kind: str | None = None, shown_as: str | None = None) -> Machine:
    """The Machine for what answers on `port` (None: find a board, else `sim://`);
    GalileoError (LinkError) when it cannot be opened. `config`: plan with this
    instead of the profile's (the console's feed); the board must still be built for
    the profile's. `kind` (and `handle`, the port left open): what a probe found
    there already; not probed again. `shown_as`: the port's name in messages (a
    simavr:// URL without the step-trace option added for --trace)."""
    if kind is None:
        port, kind, handle = open_board(port, profile.baud)  # a probed port stays open
    config = config if config is not None else profile.config
    if kind == GRBL:
        from galileo_cnc.backends.grbl import GrblMachine
        return GrblMachine.open(port, profile.baud, config, profile.path, profile.config,
                                handle=handle, shown_as=shown_as)
    from galileo_cnc.backends.galileo import GalileoMachine
    return GalileoMachine.open(port, profile.baud, config, profile.path, profile.config,
                               on_message, handle=handle)


__all__ = ["JobResult", "Machine", "MachineJob", "MachineView", "Operator", "Resumption",
           "open_machine"]
