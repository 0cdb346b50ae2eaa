"""Issue 31 items 6, 10 and 14 at the console, as the user met them on sim://: a
failed `home` that leaves the head outside the travel, a pen powered on lifted, and
jog refusals in the jog line's work coordinates. sim:// runs the failed seek to its
end as the firmware does (tests/firmware/test_firmware_fitl.py checks the firmware)."""

from __future__ import annotations

import re

from test_console import (BOARD, INSTANT_SIM, WAIT_S, console_in_thread,  # noqa: F401
                          home)

#: the X switch out of reach: `home` seeks the travel plus two pull-offs, then alarm 11
FAR_X_SWITCH = "[machine]\nsim_x_endstop_steps = -100000\n"


def _expect_note(user, pattern: str) -> None:
    """A keypad note, wrapped over the terminal's rows, and redrawn by prompt_toolkit
    only where it differs (it skips blanks already there): matched without blanks."""
    regex = re.compile(pattern.replace(" ", ""))
    found = user.screen.wait_until(lambda text: regex.search(re.sub(r"\s", "", text)), WAIT_S)
    assert found, f"{pattern!r} not on the screen:\n{user.screen.text[-1500:]}"


def _keypad(user, units: str) -> None:
    user.line("setup")
    user.expect(r"choice:")
    user.line("1")
    user.expect(r"jog distance")
    user.line(units)
    user.expect(r"q: back")


def test_a_failed_home_leaves_the_head_outside_and_a_jog_back_works(home, tmp_path):
    profile = tmp_path / "far-switch.toml"
    profile.write_text(FAR_X_SWITCH)
    with console_in_thread(home, f"{INSTANT_SIM}&config={profile}") as user:
        user.line("home")
        user.expect(r"alarm:11 end-stop not found")
        user.expect(r"type unlock")
        assert user.status() == ("alarm", -32324, 0, 0)       # the whole seek ran
        user.line(f"getg {BOARD}")                             # locked: says so, sends nothing
        user.expect(r"use these offsets\?")
        user.line("y")
        user.expect(r"the machine is locked: nothing of the job was sent; type unlock")
        user.expect(r">>")
        user.line("unlock")
        user.expect(r"unlocked.*: state idle")
        _keypad(user, "100")                                   # 1 mm
        user.type("4")                                         # further out: refused
        _expect_note(user, r"refused: X would reach -203\.025 mm, below the travel's start "
                     r"at 0\.000 mm \[-32484 steps\] \(work coordinates; machine -203\.025 mm, "
                     r"0\.000 mm\); X stands outside the travel: jog X\+ back into it")
        user.type("6")                                         # back towards it: taken
        user.type("q")
        user.expect(r"position X -201\.025  Y 0\.000  Z 0\.000 mm")
        user.line("q")
        assert user.status() == ("idle", -32164, 0, 0)
        user.line(f"getg {BOARD}")                             # from out there, into the travel
        user.expect(r"use these offsets\?")
        user.line("y")
        user.expect(r"process has finished")
    assert "reconnect" not in user.screen.text and "port is gone" not in user.screen.text


def test_a_pen_powered_on_lifted_can_be_lowered_and_z_stays_within_its_travel(home):
    with console_in_thread(home) as user:
        _keypad(user, "100")                                   # 1 mm = 160 steps
        user.type("1")                                         # Z down from power-on
        user.type("o")                                         # the paper: origin here
        user.expect(r"origin set here")
        user.type("1")                                         # 2 mm below power-on:
        _expect_note(user, r"refused: Z would reach -1\.000 mm, below the travel's start at "
                    r"-0\.875 mm \[-160 steps\] \(work coordinates; machine -2\.000 mm, "
                    r"-1\.875 mm\); Z has no end-stop: it keeps within 3\.750 mm of every "
                    r"height since power-on")
        user.type("q")
        user.expect(r"position X 0\.000  Y 0\.000  Z 0\.000 mm")
        user.line("q")
        assert user.status() == ("idle", 0, 0, 0)             # work Z 0: machine Z -1 mm


def test_a_jog_refusal_speaks_the_jog_lines_work_coordinates(home):
    with console_in_thread(home) as user:
        _keypad(user, "1000")                                  # 10 mm
        user.type("6")
        user.type("o")                                         # work X 0 = machine 10 mm
        user.expect(r"origin set here")
        user.type("4")
        user.type("4")                                         # work -20 = machine -10
        _expect_note(user, r"refused: X would reach -20\.000 mm, below the travel's start at "
                    r"-10\.000 mm \[-3200 steps\] \(work coordinates; machine -10\.000 mm, "
                    r"0\.000 mm\)")
        user.type("q")
        user.expect(r"position X -10\.000  Y 0\.000  Z 0\.000 mm")
        user.line("q")


def test_a_failed_home_on_grbl_says_how_far_to_jog_back(home):  # noqa: F811 (the fixture)
    # GRBL (simavr, no switches wired): $H seeks Z up 1.5 x $132, ALARM:9, and leaves
    # Z at +15 mm machine, above its travel -10..0 mm. GRBL itself takes only a jog that
    # ends inside the travel (jog_execute checks the target), so the keypad's 1 mm jogs
    # are refused both ways: the refusal says how far one jog must go.
    from test_console_grbl import CONFIG, SETTINGS, console_object, grbl_machine, jog_screen
    settings = {**SETTINGS, 22: "1", 20: "1", 130: "50", 131: "50", 132: "10", 25: "4000",
                24: "200"}
    with grbl_machine(settings) as (board, setup_link):
        setup_link.port.close()                    # the console opens the board itself
        with console_object(home, board.port, CONFIG) as (user, _):
            user.line("home")
            user.expect(r"ALARM:9: Homing fail")
            user.expect(r">>")
            user.line("unlock")
            user.expect(r"unlocked \(\$X\).*Z 15\.000 mm")
            user.line("setup")
            user.expect(r"choice:")
            jog_screen(user, 100)                  # 1 mm
            user.type("1")                         # Z down 1 mm: still above the travel
            _expect_note(user, re.escape(re.sub(r"\s", "", (
                "jog refused: Z would go to 14 mm (work; machine 14 mm), outside GRBL's "
                "travel: work -10..0 mm, machine -10..0 mm ($132=10.000); Z stands outside it, "
                "and GRBL takes only a jog that ends inside: jog Z by -15 mm or more in one "
                "jog, or home ($H) once the switches work"))))
            user.type("q")
            user.expect(r"choice:")
            jog_screen(user, 1500)                 # 15 mm: into the travel, taken
            user.type("1")
            user.expect(r"Idle")
            user.type("q")
            user.expect(r"position X 0\.000  Y 0\.000  Z 0\.000 mm \(work\)")
            user.line("q")
        board.stop()
