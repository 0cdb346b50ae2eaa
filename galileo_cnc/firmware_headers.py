"""C headers for the firmware, generated from the one Python definition of each thing.

`protocol_header()` renders galileo_cnc/protocol/spec.py (wire format, commands
with their queue blocks, error codes, states, the line check) and `config_header()`
renders the board's fixed facts (config/hardware.py), a MachineConfig with its
digest, and the arc band tables of docs/motion.md §5.3. Both files are committed
under firmware/galileo/ so the Arduino IDE can build the sketch without Python;
tests assert the committed text equals what these functions produce.

One command writes both (a build tool: it may import every stage it describes):

    python -m galileo_cnc.firmware_headers [--config my-profile.toml]
"""

from __future__ import annotations

from pathlib import Path

from galileo_cnc.config.hardware import DEFAULT_BAUD, F_CPU_HZ, TICKS_PER_S, TIMER1_PRESCALER
from galileo_cnc.config.machine import MIN_FEED_STEPS_PER_S, MachineConfig, load_config
from galileo_cnc.machine.arcs import BAND_RHO_Q15, BAND_SIN_Q16, MAX_ARC_COORD
from galileo_cnc.machine.ramps import FRAC_BITS, RHO_BITS
from galileo_cnc.protocol import spec as P


def _c_char(byte: bytes) -> str:
    value = byte[0]
    return f"'{chr(value)}'" if 32 < value < 127 and chr(value) not in "'\\" else f"0x{value:02X}"


def _table(values, per_line: int = 12, indent: str = "    ") -> str:
    items = [str(v) for v in values]
    rows = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return ",\n".join(indent + row for row in rows)


def protocol_header() -> str:
    out = [
        "/* Generated from galileo_cnc/protocol/spec.py by",
        " *   python -m galileo_cnc.firmware_headers",
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
        "/* The check on every line, both ways: text, separator (even/odd text length),",
        " * CRC-16 over both as four upper-case hex digits. */",
        f"#define PROTO_CRC16_POLY 0x{P.CRC16_POLY:04X}",
        f"#define PROTO_CRC16_INIT 0x{P.CRC16_INIT:04X}",
        f"#define PROTO_CHECK_SEP_EVEN {_c_char(P.CHECK_SEPARATORS[0])}",
        f"#define PROTO_CHECK_SEP_ODD {_c_char(P.CHECK_SEPARATORS[1])}",
        f"#define PROTO_CHECK_BYTES {P.CHECK_BYTES}",
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
            "    uint8_t blocks; /* queue room reserved before planning (HOME: per axis) */",
            f"    uint8_t kinds[{max_args}];",
            "};", "",
            "/* Tables: defined in the one file that defines PROTO_TABLES before including. */",
            "extern const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM;",
            "extern const char *const proto_error_texts[ERR_COUNT] PROGMEM;",
            "extern const uint8_t proto_error_is_alarm[ERR_COUNT] PROGMEM;",
            "extern const char *const proto_state_names[STATE_COUNT] PROGMEM;",
            "", "#ifdef PROTO_TABLES", "",
            "const struct proto_command_spec proto_commands[CMD_COUNT] PROGMEM = {"]
    for spec in P.COMMANDS:
        kinds = [f"ARG_{kind.name}" for _f, kind in spec.args] + ["0"] * (max_args - len(spec.args))
        out.append(f'    {{"{spec.mnemonic}", {spec.min_args}, {len(spec.args)}, {spec.blocks}, '
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
            "#endif /* PROTO_TABLES */", "", "#endif /* GALILEO_PROTOCOL_H */", ""]
    return "\n".join(out)


def config_header(cfg: MachineConfig | None = None, source: str = "the defaults") -> str:
    cfg = cfg or MachineConfig()
    fixed = [
        ("F_CPU_HZ", F_CPU_HZ, "the board's clock"),
        ("TIMER1_PRESCALER", TIMER1_PRESCALER, ""),
        ("TICKS_PER_S", TICKS_PER_S, "Timer1 at F_CPU / 8: one tick is 0.5 us"),
        ("SERIAL_BAUD", DEFAULT_BAUD, ""),
        ("FRAC_BITS", FRAC_BITS, "subtick = 1/256 tick"),
        ("RHO_BITS", RHO_BITS, "path length per event in Q15"),
        ("MIN_FEED_STEPS_PER_S", MIN_FEED_STEPS_PER_S, ""),
        ("MAX_ARC_COORD", MAX_ARC_COORD, "|coordinate| relative to an arc centre"),
    ]
    out = [
        "/* Machine configuration, generated from galileo_cnc/config/ "
        f"({source}) by",
        " *   python -m galileo_cnc.firmware_headers [--config PROFILE.toml]",
        " * Edit the machine's profile and regenerate, then reflash: the banner's digest",
        " * tells the host which profile this build is for. docs/motion.md defines the",
        " * values. */",
        "#ifndef GALILEO_CONFIG_H", "#define GALILEO_CONFIG_H", "",
    ]
    for name, value, comment in fixed + list(cfg.firmware_values()):
        suffix = "UL" if name == "SERIAL_BAUD" or name == "F_CPU_HZ" else (
            "L" if abs(value) > 32767 else "")
        line = f"#define CFG_{name} ({value}{suffix})"
        out.append(f"{line:<44} /* {comment} */" if comment else line)
    out += ["", "#if defined(F_CPU) && F_CPU != CFG_F_CPU_HZ",
            '#error "F_CPU differs from CFG_F_CPU_HZ: step timing and baud would be wrong"',
            "#endif"]
    if cfg.home_pulloff_steps <= cfg.home_debounce_reads - 1:
        out.append('#error "HOME_PULLOFF_STEPS must exceed HOME_DEBOUNCE_READS - 1"')
    out += ["", "/* The banner's `config` field and the `C` query's answer (docs/protocol.md). */",
            f'#define CFG_DIGEST "{cfg.firmware_digest()}"',
            f'#define CFG_VALUES_TEXT "{cfg.firmware_text()}"',
            "", f"#define CFG_N_BANDS {len(BAND_SIN_Q16)}",
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


FIRMWARE_DIR = Path("firmware/galileo")


def main(argv: list[str] | None = None) -> int:
    import argparse
    parser = argparse.ArgumentParser(
        prog="python -m galileo_cnc.firmware_headers",
        description="Write the firmware's generated headers, protocol.h and config.h.")
    parser.add_argument("--config", metavar="TOML",
                        help="machine profile to build for (default: the seed's machine)")
    parser.add_argument("--out", metavar="DIR", default=str(FIRMWARE_DIR),
                        help=f"where the sketch is (default: {FIRMWARE_DIR})")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if not out.is_dir():
        parser.error(f"{out}: no such folder (run from the checkout, or give --out)")
    cfg = load_config(args.config)
    for name, text in (("protocol.h", protocol_header()),
                       ("config.h", config_header(cfg, args.config or "the defaults"))):
        changed = write_if_changed(out / name, text)
        print(f"{out / name}: {'written' if changed else 'unchanged'}")
    print(f"config digest {cfg.firmware_digest()}: reflash the board (make -C firmware upload)"
          " so its banner names it")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
