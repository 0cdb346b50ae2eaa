"""`galileo-cnc serve`: the machine on the network, a web page and a JSON API
(galileo_cnc/serve/, docs/serve.md). Secure by default: it listens on loopback
unless --listen says otherwise, and prints a URL holding a fresh token that every
request needs.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys


def add_serve_command(commands, add_connection_options) -> None:
    serve = commands.add_parser("serve", help="a web page and a JSON API for the machine "
                                "(a URL with a token is printed)")
    add_connection_options(serve)
    serve.add_argument("--listen", default="127.0.0.1:8765", metavar="HOST:PORT",
                       help="where the page is served (default 127.0.0.1:8765: this "
                       "computer only; 0.0.0.0:8765 for the network; port 0: any free one)")
    serve.set_defaults(run=run_serve)


def run_serve(args: argparse.Namespace) -> int:
    from galileo_cnc.backends import open_machine
    from galileo_cnc.config.profile import load_profile
    from galileo_cnc.serve.server import WebServer, parse_listen
    from galileo_cnc.serve.service import MachineService
    from galileo_cnc.transport.discovery import open_board
    from galileo_cnc.transport.port import SIM_URL

    host, port = parse_listen(args.listen)          # a typo refused before connecting
    profile = load_profile(args.profile, port=args.port, baud=args.baud)
    device, kind, handle = open_board(profile.port, profile.baud)   # the one probe
    if profile.port is None and device != SIM_URL:
        profile = dataclasses.replace(profile, port=device)
    opened = []

    def open_it():
        if not opened:                  # the probed port, kept open; later: open again
            opened.append(True)
            return open_machine(device, profile, handle=handle, kind=kind)
        return open_machine(profile.port or SIM_URL, profile)

    service = MachineService(open_it)
    try:
        server = WebServer(service, host, port)
        found = " (no board found: the simulated machine)" if profile.port is None else ""
        print(f"{service.machine.describe()}{found}")
        if server.everywhere:
            print(f"listening on every interface ({host}): anyone who has the URL below "
                  f"drives the machine")
        print(f"open the page (the token in it is needed by every request):\n    {server.url}")
        sys.stdout.flush()
        try:
            server.run()
        except KeyboardInterrupt:       # Ctrl-C: how a server is ended, not a failure
            pass
    finally:
        service.close()
    print("galileo-cnc serve: stopped")
    return 0
