"""C headers for the firmware, generated from the one Python definition of each thing.

`protocol_header()` renders galileo_cnc/protocol.py (wire format, commands, error
codes, states, CRC table) and `config_header()` renders a MachineConfig plus the
arc band tables of docs/motion.md §5.3. Both files are committed under
firmware/galileo/ so the Arduino IDE can build the sketch without Python; tests
assert the committed text equals what these functions produce.

    python -m galileo_cnc.protocol --header firmware/galileo/protocol.h
    python -m galileo_cnc.firmware_headers --config-header firmware/galileo/config.h [--config my.toml]
"""

from __future__ import annotations

from pathlib import Path

from . import protocol as P
from .config import MIN_FEED_STEPS_PER_S, NO_PIN, TICKS_PER_S, MachineConfig, load_config
from .machine.arcs import BAND_RHO_Q15, BAND_SIN_Q16, MAX_ARC_COORD
from .machine.ramps import FRAC_BITS, RHO_BITS


def _c_char(byte: bytes) -> str:
    value = byte[0]
    return f"'{chr(value)}'" if 32 < value < 127 and chr(value) not in "'\\" else f"0x{value:02X}"


def _table(values, per_line: int = 12, indent: str = "    ") -> str:
    items = [str(v) for v in values]
    rows = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return ",\n".join(indent + row for row in rows)


def protocol_header() -> str:
    out = [
        "/* Generated from galileo_cnc/protocol.py by",
        " *   python -m galileo_cnc.protocol --header firmware/galileo/protocol.h",
        " * Do not edit: change the Python definition and regenerate (docs/protocol.md). */",
        "#ifndef GALILEO_PROTOCOL_H",
        "#define GALILEO_PROTOCOL_H",
        "",
        "#include <stdint.h>",
        "#include <avr/pgmspace.h>",
        "",
        f"#define PROTO_VERSION {P.PROTOCOL_VERSION}",
        f'#define PROTO_FIRMWARE_VERSION "{P.FIRMWARE_VERSION}"',
        f'#define PROTO_BANNER_NAME "{P.BANNER_NAME}"',
        f"#define PROTO_MAX_LINE_BYTES {P.MAX_LINE_BYTES} /* including the newline */",
        f"#define PROTO_RX_BUFFER_BYTES {P.RX_BUFFER_BYTES}",
        f"#define PROTO_QUEUE_BLOCKS {P.QUEUE_BLOCKS}",
        f"#define PROTO_SEQ_MAX {P.SEQ_MAX}UL",
        f"#define PROTO_CRC8_POLY 0x{P.CRC8_POLY:02X}",
        "",
        "/* Real-time bytes, picked off in the receive interrupt. */",
    ]
    for name, byte in P.REALTIME_BYTES.items():
        out.append(f"#define PROTO_RT_{name} {_c_char(byte)}")
    out += ["", "enum proto_arg_kind {"]
    out += [f"    ARG_{kind.name}," for kind in P.ARG_KINDS]
    out += ["};", ""]
    for kind in P.ARG_KINDS:
        out.append(f"#define ARG_{kind.name}_LO ({kind.lo}L)")
        out.append(f"#define ARG_{kind.name}_HI ({kind.hi}L)")
    max_args = max(len(spec.args) for spec in P.COMMANDS)
    out += ["", f"#define PROTO_MAX_ARGS {max_args}", "", "enum proto_command {"]
    out += [f"    CMD_{spec.name}," for spec in P.COMMANDS]
    out += ["    CMD_COUNT", "};", "", "enum proto_error {"]
    out += [f"    ERR_{e.name} = {e.code}," for e in P.ERRORS]
    out += [f"    ERR_COUNT = {max(e.code for e in P.ERRORS) + 1}", "};", "",
            "enum proto_state {"]
    out += [f"    STATE_{s.upper()}," for s in P.STATES]
    out += ["    STATE_COUNT", "};", "",
            "struct proto_command_spec {",
            "    char mnemonic[4];",
            "    uint8_t min_args, max_args;",
            f"    uint8_t kinds[{max_args}];",
            "};", "",
            "/* Tables: defined in the one file that defines PROTO_TABLES before including. */",
            "extern const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM;",
            "extern const char *const proto_error_texts[ERR_COUNT] PROGMEM;",
            "extern const uint8_t proto_error_is_alarm[ERR_COUNT] PROGMEM;",
            "extern const char *const proto_state_names[STATE_COUNT] PROGMEM;",
            "extern const uint8_t proto_crc8_table[256] PROGMEM;",
            "", "#ifdef PROTO_TABLES", "",
            "const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM = {"]
    for spec in P.COMMANDS:
        kinds = [f"ARG_{kind.name}" for _f, kind in spec.args] + ["0"] * (max_args - len(spec.args))
        out.append(f'    {{"{spec.mnemonic}", {spec.min_args}, {len(spec.args)}, '
                   f'{{{", ".join(kinds)}}}}}, /* {spec.cls.__name__} */')
    out.append("};")
    out.append("")
    for e in P.ERRORS:
        out.append(f'static const char proto_error_text_{e.code}[] PROGMEM = "{e.text}";')
    by_code = {e.code: e for e in P.ERRORS}
    n_codes = max(by_code) + 1
    texts = [f"proto_error_text_{c}" if c in by_code else "0" for c in range(n_codes)]
    alarms = [str(int(by_code[c].alarm)) if c in by_code else "0" for c in range(n_codes)]
    out += ["const char *const proto_error_texts[ERR_COUNT] PROGMEM = {",
            _table(texts, 4), "};",
            "const uint8_t proto_error_is_alarm[ERR_COUNT] PROGMEM = {",
            _table(alarms, 16), "};", ""]
    for s in P.STATES:
        out.append(f'static const char proto_state_{s}[] PROGMEM = "{s}";')
    out += ["const char *const proto_state_names[STATE_COUNT] PROGMEM = {",
            _table([f"proto_state_{s}" for s in P.STATES], 5), "};", "",
            "const uint8_t proto_crc8_table[256] PROGMEM = {",
            _table([f"0x{v:02X}" for v in P.CRC8_TABLE], 12), "};", "",
            "#endif /* PROTO_TABLES */", "", "#endif /* GALILEO_PROTOCOL_H */", ""]
    return "\n".join(out)


def config_header(cfg: MachineConfig | None = None, source: str = "the defaults") -> str:
    cfg = cfg or MachineConfig()
    tmin, tmax = cfg.travel_min_steps, cfg.travel_max_steps
    values = [
        ("TICKS_PER_S", TICKS_PER_S, "Timer1 at 16 MHz / 8: one tick is 0.5 us"),
        ("FRAC_BITS", FRAC_BITS, "subtick = 1/256 tick"),
        ("RHO_BITS", RHO_BITS, "path length per event in Q15"),
        ("FEED_STEPS_PER_S", cfg.feed_steps_per_s, "default feed"),
        ("RAPID_STEPS_PER_S", cfg.rapid_steps_per_s, "pen-up travel"),
        ("Z_FEED_STEPS_PER_S", cfg.z_feed_steps_per_s, "pen up / down"),
        ("HOME_FEED_STEPS_PER_S", cfg.home_feed_steps_per_s, "homing seek and pull-off"),
        ("MIN_FEED_STEPS_PER_S", MIN_FEED_STEPS_PER_S, ""),
        ("MAX_FEED_STEPS_PER_S", cfg.max_feed_steps_per_s, "= TICKS_PER_S / MIN_STEP_PERIOD"),
        ("MIN_STEP_PERIOD_TICKS", cfg.min_step_period_ticks, ""),
        ("ACCEL_STEPS_PER_S2", cfg.accel_steps_per_s2, "axis acceleration bound A"),
        ("RAMP_START_FACTOR", cfg.ramp_start_factor, "a move starts at this x the period"),
        ("PEN_DOWN_Z_STEPS", cfg.pen_down_z_steps, ""),
        ("PEN_UP_Z_STEPS", cfg.pen_up_z_steps, ""),
        ("FLASH_DWELL_MS", cfg.flash_dwell_ms, ""),
        ("X_TRAVEL_MIN_STEPS", tmin[0], "soft limits, machine steps"),
        ("X_TRAVEL_MAX_STEPS", tmax[0], ""),
        ("Y_TRAVEL_MIN_STEPS", tmin[1], ""),
        ("Y_TRAVEL_MAX_STEPS", tmax[1], ""),
        ("Z_TRAVEL_MIN_STEPS", tmin[2], ""),
        ("Z_TRAVEL_MAX_STEPS", tmax[2], ""),
        ("X_STEP_PIN", cfg.x_step_pin, "Arduino pin numbers"),
        ("X_DIR_PIN", cfg.x_dir_pin, ""),
        ("Y_STEP_PIN", cfg.y_step_pin, ""),
        ("Y_DIR_PIN", cfg.y_dir_pin, ""),
        ("Z_STEP_PIN", cfg.z_step_pin, ""),
        ("Z_DIR_PIN", cfg.z_dir_pin, ""),
        ("X_HOME_PIN", cfg.x_home_pin, f"{NO_PIN}: no end-stop; INPUT_PULLUP, active LOW"),
        ("Y_HOME_PIN", cfg.y_home_pin, ""),
        ("Z_HOME_PIN", cfg.z_home_pin, ""),
        ("X_HOME_DIR", cfg.x_home_dir, "seek direction"),
        ("Y_HOME_DIR", cfg.y_home_dir, ""),
        ("Z_HOME_DIR", cfg.z_home_dir, ""),
        ("HOME_DEBOUNCE_READS", cfg.home_debounce_reads, "consecutive active reads"),
        ("HOME_PULLOFF_STEPS", cfg.home_pulloff_steps, ""),
        ("MAX_ARC_COORD", MAX_ARC_COORD, "|coordinate| relative to an arc centre"),
    ]
    out = [
        "/* Machine configuration, generated from galileo_cnc/config.py "
        f"({source}) by",
        " *   python -m galileo_cnc.firmware_headers --config-header firmware/galileo/config.h",
        " * Edit the machine's TOML file and regenerate (--config FILE), or edit the",
        " * values here for a one-off build; docs/motion.md defines what they mean. */",
        "#ifndef GALILEO_CONFIG_H", "#define GALILEO_CONFIG_H", "",
    ]
    for name, value, comment in values:
        suffix = "L" if abs(value) > 32767 else ""
        line = f"#define CFG_{name} ({value}{suffix})"
        out.append(f"{line:<44} /* {comment} */" if comment else line)
    if cfg.home_pulloff_steps <= cfg.home_debounce_reads - 1:
        out.append('#error "HOME_PULLOFF_STEPS must exceed HOME_DEBOUNCE_READS - 1"')
    out += ["", f"#define CFG_N_BANDS {len(BAND_SIN_Q16)}",
            "/* Arc timing bands (docs/motion.md §5.3): sin of the band edges, Q16, and",
            " * the mean path length per event inside each band, Q15. */",
            "#define CFG_BAND_SIN_Q16 { \\",
            _table(BAND_SIN_Q16, 11).replace("\n", " \\\n") + " }",
            "#define CFG_BAND_RHO_Q15 { \\",
            _table(BAND_RHO_Q15, 11).replace("\n", " \\\n") + " }",
            "", "#endif /* GALILEO_CONFIG_H */", ""]
    return "\n".join(out)


def write_if_changed(path: str | Path, text: str) -> bool:
    path = Path(path)
    if path.exists() and path.read_text() == text:
        return False
    path.write_text(text)
    return True


def main(argv: list[str] | None = None) -> int:
    import argparse
    parser = argparse.ArgumentParser(prog="python -m galileo_cnc.firmware_headers",
                                     description="Generate the firmware's C headers.")
    parser.add_argument("--protocol-header", metavar="PATH")
    parser.add_argument("--config-header", metavar="PATH")
    parser.add_argument("--config", metavar="TOML", help="machine profile (default: the seed)")
    args = parser.parse_args(argv)
    if args.protocol_header:
        write_if_changed(args.protocol_header, protocol_header())
    if args.config_header:
        cfg = load_config(args.config)
        write_if_changed(args.config_header,
                         config_header(cfg, args.config or "the defaults"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
