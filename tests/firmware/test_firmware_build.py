"""`make -C firmware` builds the sketch, and it fits an Arduino Uno.

Flash: 32 KiB minus the 512-byte optiboot boot loader. RAM: the static data
(.data + .bss) must leave STACK_MARGIN_BYTES (512) of the 2 KiB free for the
stack, and the stack's measured high-water mark must fit in what is left with
STACK_HEADROOM_BYTES to spare.

The high-water mark is measured, not estimated: the firmware paints its free
SRAM with 0xC5 at reset (firmware/galileo/stackpaint.cpp) and the simavr
harness (`--stack-paint`) reports, after a demanding job, the lowest byte that
no longer holds the pattern and the lowest stack pointer it saw
(docs/harness.md, "Stack").
"""


import math

from galileo_cnc import protocol as P
from galileo_cnc.job import (ArcTo, Dwell, Flash, Home, Jog, LineTo, PenDown, PenUp, Rapid,
                             SetFeed, SetOrigin)
from galileo_cnc.simavr import board as simavr
from galileo_cnc.simavr.board import SimulatedBoard

from firmware_support import (ELF, STACK_MARGIN_BYTES, UNO_FLASH_BYTES, UNO_RAM_BYTES,
                              FirmwareLink, build_firmware, build_harness,
                              check_bad_input_replies, framed, status_when)

# SRAM that must stay free below the deepest measured stack pointer. The job
# below cannot hit every path at its worst instant (e.g. the receive interrupt
# nested under the step interrupt at the planner's deepest point), so the
# measured peak needs room to spare. Measured (docs/harness.md, "Stack"): 234
# bytes by SP, 222 written, of the 521 left by .data+.bss.
STACK_HEADROOM_BYTES = 128


def test_firmware_builds_with_arduino_mk():
    built = build_firmware()
    assert ELF.is_file()
    assert "Program:" in built["output"] and "Data:" in built["output"], \
        "the build must print flash and RAM use"


def test_firmware_fits_an_uno_with_room_for_the_stack():
    built = build_firmware()
    assert built["flash_bytes"] is not None and built["ram_bytes"] is not None
    assert built["flash_bytes"] <= UNO_FLASH_BYTES, built["flash_bytes"]
    assert built["ram_bytes"] <= UNO_RAM_BYTES - STACK_MARGIN_BYTES, built["ram_bytes"]


# ---- the measured stack -------------------------------------------------------------

def _demanding_job(link):
    """Every path with a deep stack: bad lines, homing, lines, arcs of every size,
    flashes, real-time bytes (status bursts, hold, resume, abort) while moving."""
    check_bad_input_replies(link, idle_timeout_s=60)        # at power-up: needs N0 at 0,0
    assert link.send(ArcTo(10, 0, 5, 40_000, cw=True)).code == 7   # radius too large
    assert link.send_raw(framed(b"N%d CW 1 2 3" % link.seq)).code == 4   # too few
    # (refused lines are not counted: the same number comes next)
    assert link.send(P.QueryVersion()).kind == "ok"

    job = [Home(), SetFeed(20000), Jog(3000, 3000, 0), SetOrigin(), SetFeed(2500)]
    for x, y in [(900, 310), (310, 900), (-310, 900), (-900, 310), (-900, -310),
                 (-310, -900), (310, -900), (900, -310)]:
        job += [LineTo(x, y), LineTo(0, 0)]
    job += [PenUp(), PenDown(), LineTo(100, 50, 200), LineTo(-40, 80, 0), LineTo(0, 0, 0),
            ArcTo(0, 0, 300, 0, cw=False), ArcTo(0, 0, 0, -250, cw=True),
            SetFeed(1600), ArcTo(205, 3, 100, 0, cw=True), ArcTo(0, 0, -102, 0, cw=False),
            SetFeed(100), ArcTo(0, 0, -1, 0, cw=False), ArcTo(1, 1, 0, 1, cw=True),
            ArcTo(0, 0, 1, -1, cw=False), SetFeed(800), ArcTo(-5, 5, -5, 0, cw=True),
            ArcTo(0, 0, 0, -5, cw=False), ArcTo(3, 4, 3, 4, cw=True),
            ArcTo(0, 0, -3, -4, cw=False), SetFeed(3000), ArcTo(0, 0, 4, 7, cw=False),
            # large radii: a 20 000-step circle's short arcs, both ways, and back
            ArcTo(200, 0, 100, -20_000, cw=True), ArcTo(0, 0, -100, -20_000, cw=False),
            Rapid(200, 100), Flash(), Rapid(400, 100), Flash(50), Dwell(30), PenDown(),
            LineTo(0, 0)]
    replies = link.stream(job)
    assert all(r.kind == "ok" for r in replies), [r for r in replies if r.kind != "ok"]
    status = link.wait_idle(120)
    assert (status.state, status.x_steps, status.y_steps) == ("idle", 0, 0), status

    # A burst of status queries while a fast line runs.
    assert all(r.kind == "ok" for r in link.stream([SetFeed(8000), LineTo(2000, 700)]))
    for _ in range(40):
        assert link.status().state in ("run", "idle")
    link.wait_idle(60)

    # Hold and resume in the middle of a line, with queries while held.
    assert all(r.kind == "ok" for r in link.stream([SetFeed(1600), LineTo(0, 0)]))
    status_when(link, lambda s: s.state == "run" and s.x_steps < 1700, 60.0, 0.005)
    link.port.write(P.RT_HOLD)
    held = status_when(link, lambda s: s.state == "hold", 60.0, 0.005)
    assert held.x_steps > 0
    link.port.write(P.RT_RESUME)
    status = link.wait_idle(60)
    assert (status.x_steps, status.y_steps) == (0, 0), status

    # Junction speeds (LX, CWX, CCX): blocks entered at speed, a hold braking across them.
    from galileo_cnc.config.machine import MachineConfig
    from galileo_cnc.machine.planner import with_exit_indices
    sides = [LineTo(round(900 * math.cos(a)), round(900 * math.sin(a)))
             for a in (k * math.pi / 4 + 0.3 for k in range(9))]
    wave = [SetFeed(1600)] + sides + [ArcTo(sides[-1].x_steps - 400, sides[-1].y_steps, -200, 0,
                                            cw=True), LineTo(0, 0)]
    wire = with_exit_indices([Jog(3000, 3000, 0), SetOrigin()] + wave, MachineConfig(
        junction_deviation_mm=0.05, vertex_speed_change_mm_s=3.0))[2:]
    assert sum(1 for c in wire if c.__class__ in (LineTo, ArcTo) and c.exit_index) >= 6
    assert all(r.kind == "ok" for r in link.stream(wire))
    link.port.write(P.RT_HOLD)
    status_when(link, lambda s: s.state == "hold", 60.0, 0.005)
    link.port.write(P.RT_RESUME)
    status = link.wait_idle(60)
    assert (status.x_steps, status.y_steps) == (0, 0), status

    # Abort a line with blocks queued behind it, then unlock.
    assert all(r.kind == "ok" for r in link.stream([LineTo(1500, 500), LineTo(0, 0)]))
    status_when(link, lambda s: s.state == "run" and s.x_steps > 300, 60.0, 0.005)
    link.port.write(P.RT_ABORT)
    alarm = link.read_reply()
    assert (alarm.kind, alarm.code) == ("alarm", 14)
    assert link.send(Jog(1, 0, 0)).code == 9
    assert link.send(P.Unlock()).kind == "ok"
    assert link.send(Jog(0, 0, 0)).kind == "ok"
    link.wait_idle(60)


def test_measured_stack_fits_with_headroom():
    built = build_firmware()
    build_harness()
    with SimulatedBoard(ELF, trace=False, endstops=("X:7:-60", "Y:6:-45"),
                        stack_paint=simavr.STACK_PAINT_BYTE) as board:
        link = FirmwareLink(board.port)
        try:
            _demanding_job(link)
        finally:
            link.close()
        board.stop()
    stack = board.stack
    assert board.summary["overruns"] == "0"
    assert stack, f"no stack report: {board.log[-2000:]}"
    print(f"\nstack: peak {stack['peak']} B written ({stack['sp_peak']} B by SP), "
          f"static {stack['static']} B, never touched {stack['free']} B "
          f"of {UNO_RAM_BYTES} B")
    # The harness found the static data's end where avr-size says it is.
    assert stack["static"] == built["ram_bytes"]
    assert stack["ram_start"] + stack["static"] == stack["end"]
    assert stack["ramend"] + 1 - stack["ram_start"] == UNO_RAM_BYTES
    # The painting measured something: the stack wrote below its idle depth, the
    # pattern is intact all the way from the static data to the deepest SP, and
    # the painted mark agrees with the stack pointer's (a pushed byte may equal
    # the pattern, a frame's lowest bytes may stay unwritten).
    assert 64 < stack["peak"] <= stack["sp_peak"], stack
    assert stack["clobbered"] == 0, stack
    assert stack["free"] == stack["lowest"] - stack["end"]
    assert stack["sp_peak"] - stack["peak"] < 32, stack
    # And it fits: static data + the deepest stack + headroom <= 2 KiB.
    assert stack["static"] + stack["sp_peak"] + STACK_HEADROOM_BYTES <= UNO_RAM_BYTES, stack
