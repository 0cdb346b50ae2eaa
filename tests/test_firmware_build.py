"""`make -C firmware` builds the sketch, and it fits an Arduino Uno.

Flash: 32 KiB minus the 512-byte optiboot boot loader. RAM: the static data
(.data + .bss) must leave STACK_MARGIN_BYTES (512) of the 2 KiB free for the
stack. Estimated deepest stack: ~200 bytes in the main loop (an arc's setup walk)
plus ~80 bytes for the step interrupt nested on the receive interrupt.
"""

from firmware_support import (ELF, STACK_MARGIN_BYTES, UNO_FLASH_BYTES, UNO_RAM_BYTES,
                              build_firmware)


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
