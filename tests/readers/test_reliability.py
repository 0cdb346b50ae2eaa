"""Hostile and odd input: positioned errors with the limit, never a traceback, a hang or
a memory blow-up; the odd real files read with a warning (docs/reliability.md)."""

import io
import os
import threading
import time

import numpy as np
import pytest

from galileo_cnc.errors import GalileoError, GcodeError, GerberError, UnknownFormatError
from galileo_cnc.program.ops import X, Y
from galileo_cnc.readers import limits, read_file
from galileo_cnc.readers.dxf import DxfError, read_dxf
from galileo_cnc.readers.gcode import read_gcode
from galileo_cnc.readers.gcode.reader import _lines
from galileo_cnc.readers.gerber import read_gerber
from galileo_cnc.readers.source import BinaryFileError

HEADER = "%FSLAX46Y46*%\n%MOMM*%\n%ADD10C,0.1*%\nD10*\n"


def both_ways(text: str, name: str = "t.gbr") -> GerberError:
    """The error of the vectorised and of the one-by-one reading: the same one."""
    with pytest.raises(GerberError) as fast:
        read_gerber(name, text, min_run=1)
    with pytest.raises(GerberError) as slow:
        read_gerber(name, text, min_run=10**9)
    assert str(fast.value) == str(slow.value)
    return fast.value


def line_of(text: str, needle: str) -> int:
    return text[:text.index(needle)].count("\n") + 1


# ---- absurd numbers ------------------------------------------------------------------

@pytest.mark.parametrize("word", ["G" + "0" * 300 + "36", "M" + "9" * 500, "D" + "1" * 400,
                                  "D" + "7" * 5000, "G" + "9" * 5000])
def test_code_words_of_hundreds_of_digits_are_positioned_errors(word):
    text = HEADER + "X0Y0D02*\n" + word + "*\nM02*\n"
    error = both_ways(text)
    assert error.pos.line == 6


@pytest.mark.parametrize("number", ["9" * 5000, "1" + "0" * 300, "0." + "0" * 4000 + "1"])
def test_numbers_of_thousands_of_digits_are_positioned_errors(number):
    error = both_ways(HEADER + f"%ADD11C,{number}*%\nM02*\n")
    assert error.pos.line == 5 and "characters" in error.message


@pytest.mark.parametrize("expression", ["(" * 5000 + "1" + ")" * 5000, "-" * 5000 + "1",
                                        "(" * 65 + "1" + ")" * 65])
def test_deeply_nested_macro_expressions_are_positioned_errors(expression):
    error = both_ways(HEADER + f"%AMDEEP*1,1,{expression},0,0*%\n%ADD11DEEP*%\nM02*\n")
    assert error.pos.line == 5 and f"more than {limits.MAX_EXPRESSION_DEPTH} deep" in error.message


def test_a_macro_that_squares_a_value_again_and_again_stops_at_once():
    body = "$1=10*" + "".join("$%d=$%dx$%d*" % (k + 1, k, k) for k in range(1, 60))
    started = time.monotonic()
    error = both_ways(HEADER + f"%AMSQ*{body}1,1,$60,0,0*%\n%ADD11SQ*%\nM02*\n")
    assert time.monotonic() - started < 2
    assert error.pos.line == 6 and f"{limits.MAX_MACRO_VALUE_BITS} bits" in error.message


@pytest.mark.parametrize("aperture", ["P,1X6X1" + "0" * 40, "P,1X1" + "0" * 60 + "X0",
                                      "P,1X6X-99999"])
def test_huge_polygon_rotations_and_vertex_counts_are_positioned_errors(aperture):
    error = both_ways(HEADER + f"%ADD11{aperture}*%\nM02*\n")
    assert error.pos.line == 5


def test_huge_macro_rotation_is_a_positioned_error():
    error = both_ways(HEADER + "%AMROT*1,1,1,0,0,1E30*%\n%ADD11ROT*%\nM02*\n")
    assert error.pos.line == 6 and "rotation" in error.message


def test_over_long_coordinates_for_the_format_are_positioned_errors():
    error = both_ways(HEADER + "X0Y0D02*\nX" + "1" * 40 + "Y0D01*\nM02*\n")
    assert error.pos.line == 6 and "more than 12 digits" in error.message


# ---- no silent wrap-around --------------------------------------------------------------

@pytest.mark.parametrize("header", ["%FSLAX60Y60*%\n%MOIN*%\n", "%FSTAX66Y66*%\n%MOIN*%\n",
                                    "%FSLAX46Y46*%\n%MOMM*%\n"])
def test_a_run_of_huge_coordinates_is_refused_in_both_paths_not_wrapped(header):
    statements = [f"X{10**11 + k}Y{k}D01*" for k in range(60)]
    text = header + "%ADD10C,0.1*%\nD10*\nX0Y0D02*\n" + "\n".join(statements) + "\nM02*\n"
    error = both_ways(text)
    assert error.pos.line == 6 and "out of range" in error.message


def test_coordinates_at_the_bound_read_and_beyond_it_do_not():
    ok = HEADER + "X0Y0D02*\n" + "".join(f"X{10**10 - k}Y0D01*\n" for k in range(40)) + "M02*\n"
    program = read_gerber("t.gbr", ok.replace("%FSLAX46Y46", "%FSLAX66Y66").replace(
        "%MOMM", "%MOMM"), min_run=1)
    assert np.abs(program.table[:, X]).max() <= 10**10
    beyond = HEADER.replace("46Y46", "66Y66") + "X0Y0D02*\n" + "".join(
        f"X{10**10 + 1000 * k}Y0D01*\n" for k in range(40)) + "M02*\n"
    assert "out of range" in both_ways(beyond).message


def test_incremental_sums_beyond_the_bound_are_refused_at_the_statement():
    text = "%FSLIX66Y66*%\n%MOMM*%\n%ADD10C,0.1*%\nD10*\n" + \
        "".join(f"X{9 * 10**8}Y0D01*\n" for _ in range(60)) + "M02*\n"
    error = both_ways(text)
    assert error.pos.line == 4 + 12 and "out of range" in error.message


def test_step_and_repeat_beyond_the_bound_is_refused_at_the_sr():
    text = HEADER + "%SRX3000Y1I5000J0*%\nX0Y0D03*\n%SR*%\nM02*\n"
    error = both_ways(text)
    assert error.pos.line == 5 and "%SR" in error.message


# ---- bounded expansion ------------------------------------------------------------------

def test_the_104_byte_step_and_repeat_file_is_refused_at_once():
    text = "%FSLAX24Y24*%%MOIN*%%ADD10C,0.1*%D10*%SRX99999999999Y1I0.1J0.1*%X0Y0D02*X1D01*%SR*%M02*"
    started = time.monotonic()
    error = both_ways(text)
    assert time.monotonic() - started < 1
    assert limits.MAX_OPS_ENV in error.message and f"{limits.MAX_OPS:,}" in error.message


def test_step_and_repeat_within_the_limit_gives_the_same_rows_as_before():
    text = HEADER + "%SRX3Y2I5.0J10.0*%\nG04 x*\nX0Y0D03*\nX1000000Y0D02*X2000000Y0D01*%SR*%M02*\n"
    program = read_gerber("t.gbr", text)
    cells = [(ix, iy) for ix in range(3) for iy in range(2)]
    moves = program.table[program.table[:, 0] == 0][:, [X, Y]].tolist()
    # The block starts with a flash, which goes to its point itself: each copy has only
    # the block's own move, moved (issue 31, item 3: no lead-in move of its own).
    assert moves == [[1_000_000 + ix * 5_000_000, iy * 10_000_000] for ix, iy in cells]
    flashes = program.table[program.table[:, 0] == 4][:, [X, Y]].tolist()
    assert flashes == [[ix * 5_000_000, iy * 10_000_000] for ix, iy in cells]


def test_nested_aperture_blocks_are_refused_before_memory_runs_out(monkeypatch):
    monkeypatch.setenv(limits.MAX_OPS_ENV, "100000")
    parts = ["%ABD100*%\nD10*\nX0Y0D03*\n%AB*%\n"]
    for level in range(1, 12):
        parts += [f"%ABD{100 + level}*%\nD{99 + level}*\n"]
        parts += [f"X{k}Y0D03*\n" for k in range(10)]
        parts += ["%AB*%\n"]
    text = HEADER + "".join(parts) + "D111*\nX0Y0D03*\nM02*\n"
    error = both_ways(text)
    assert "100,000 operations" in error.message and "flashing block aperture" in error.message


def test_max_ops_keyword_and_the_op_limit_of_plain_statements():
    text = HEADER + "X0Y0D02*\n" + "".join(f"X{k}Y0D01*\n" for k in range(1, 20_000)) + "M02*\n"
    assert len(read_gerber("t.gbr", text)) == 20_002  # select, move, pen down, 19,999 lines
    with pytest.raises(GerberError) as caught:
        read_gerber("t.gbr", text, max_ops=5_000)
    # Row 5,000 (from 0) is the line of file line 5,003: the first op beyond the limit.
    assert caught.value.pos.line == 5_003 and "5,000 operations" in caught.value.message


def test_gcode_op_limit_names_the_line_and_how_to_raise_it(monkeypatch):
    text = "G21 G90\nM3\n" + "".join(f"G1 X{k} Y1\n" for k in range(200_000))
    assert len(read_gcode("big.nc", text)) == 200_001
    with pytest.raises(GcodeError) as caught:
        read_gcode("big.nc", text, max_ops=100_000)
    assert caught.value.pos.line == 2 + 100_000
    assert "100,000 operations" in caught.value.message and "GALILEO_MAX_OPS" in caught.value.message
    monkeypatch.setenv(limits.MAX_OPS_ENV, "150000")
    with pytest.raises(GcodeError, match="150,000 operations"):
        read_gcode("big.nc", text)


@pytest.mark.parametrize("text", ["G1 X1\r\nG1 X2\rG1 X3\n\nG1 X4", "\r\r\n\n", "", "a\n" * 5,
                                  ("G1 X1\r" * 300_000) + "\nG1 X2\n"])
def test_gcode_lines_are_split_as_a_stringio_splits_them(text, monkeypatch):
    import galileo_cnc.readers.gcode.reader as reader

    monkeypatch.setattr(reader, "_PIECE_CHARS", 7)
    assert list(_lines(text)) == list(io.StringIO(text, newline=None))


def test_dxf_minsert_expansion_is_refused_before_it_is_walked(tmp_path):
    def pairs(*items):
        return "".join(f"{code}\n{value}\n" for code, value in items)

    body = pairs((0, "SECTION"), (2, "BLOCKS"),
                 (0, "BLOCK"), (8, 0), (2, "B0"), (70, 0), (10, 0), (20, 0), (30, 0),
                 (0, "LINE"), (8, 0), (10, 0), (20, 0), (30, 0), (11, 1), (21, 1), (31, 0),
                 (0, "ENDBLK"), (8, 0),
                 (0, "BLOCK"), (8, 0), (2, "B1"), (70, 0), (10, 0), (20, 0), (30, 0),
                 (0, "INSERT"), (8, 0), (2, "B0"), (10, 0), (20, 0), (30, 0), (70, 30000),
                 (71, 30000), (44, 1), (45, 1),
                 (0, "ENDBLK"), (8, 0), (0, "ENDSEC"),
                 (0, "SECTION"), (2, "ENTITIES"), (0, "INSERT"), (8, 0), (2, "B1"), (10, 0),
                 (20, 0), (30, 0), (0, "ENDSEC"), (0, "EOF"))
    path = tmp_path / "grid.dxf"
    path.write_text(body)
    started = time.monotonic()
    with pytest.raises(DxfError) as caught:
        read_dxf(path)
    assert time.monotonic() - started < 5
    assert caught.value.pos.line >= 1
    assert limits.MAX_BLOCK_ENTITIES_ENV in caught.value.message


# ---- only regular files -----------------------------------------------------------------

@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
def test_dev_zero_is_refused_without_reading_it():
    with pytest.raises(GalileoError, match="character device; only regular files are read"):
        read_file("/dev/zero")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.gbr"
    os.mkfifo(fifo)
    outcome = []

    def read():
        try:
            read_file(fifo)
        except GalileoError as error:
            outcome.append(str(error))

    worker = threading.Thread(target=read, daemon=True)
    worker.start()
    worker.join(5)
    assert outcome and "FIFO" in outcome[0] and "only regular files" in outcome[0]


def test_directories_and_too_big_files_are_refused(tmp_path, monkeypatch):
    with pytest.raises(GalileoError, match="directory"):
        read_file(tmp_path)
    big = tmp_path / "big.nc"
    big.write_bytes(b"G1 X1\n" * 400_000)
    monkeypatch.setenv(limits.MAX_FILE_MB_ENV, "1")
    for reader in (read_file, read_gcode, read_gerber, read_dxf):
        with pytest.raises(GalileoError, match=f"1 MB limit.*{limits.MAX_FILE_MB_ENV}"):
            reader(big)


# ---- odd real files -----------------------------------------------------------------------

def test_a_stray_star_inside_an_aperture_definition_is_read_with_a_warning():
    program = read_gerber("t.gbr", "%FSLAX46Y46*%\n%MOMM*%\n%ADD10R,0.5*X0.25*%\nD10*\nX0Y0D03*\nM02*\n")
    assert program.apertures[10].params_nm == (500_000, 250_000)
    assert any("stray '*'" in str(w) and ":3:" in str(w) for w in program.warnings)


def test_a_missing_include_file_is_a_positioned_error(tmp_path):
    path = tmp_path / "main.gbr"
    path.write_text(HEADER + "%IFlayer-part.gbr*%\nM02*\n")
    with pytest.raises(GerberError) as caught:
        read_file(path)
    assert caught.value.pos.line == 5
    assert "include file 'layer-part.gbr' (%IF) cannot be read" in caught.value.message


def test_an_include_file_is_read_in_place(tmp_path):
    (tmp_path / "part.gbr").write_text("X1000000Y0D02*\nX2000000Y0D01*\n")
    path = tmp_path / "main.gbr"
    path.write_text(HEADER + "X0Y0D03*\n%IFpart.gbr*%\nX3000000Y0D01*\nM02*\n")
    rows = read_file(path).table.tolist()
    drawn = [(r[X], r[-2]) for r in rows if r[0] in (0, 1)]  # moves and lines, with their line
    assert drawn == [(1_000_000, 6), (2_000_000, 6), (3_000_000, 7)]  # included rows at the %IF
    (tmp_path / "self.gbr").write_text(HEADER + "%IFself.gbr*%\nM02*\n")
    with pytest.raises(GerberError, match="nested more than"):
        read_file(tmp_path / "self.gbr")


def test_include_files_are_read_from_the_including_files_folder_only(tmp_path):
    # issue 31, item 18: relative to the including file (a subfolder is inside it; a
    # nested include is relative to its own file), never outside that folder
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "outline.gbr").write_text("X1000000Y0D02*\n%IFedge.gbr*%\n")
    (tmp_path / "parts" / "edge.gbr").write_text("X2000000Y0D01*\n")
    main = tmp_path / "main.gbr"
    main.write_text(HEADER + "%IFparts/outline.gbr*%\nM02*\n")
    lines = read_file(main).table
    assert lines[lines[:, 0] == 1][:, X].tolist() == [2_000_000]
    outside = tmp_path / "secret.gbr"
    outside.write_text("X9000000Y0D01*\n")
    board = tmp_path / "board"
    board.mkdir()
    (board / "link.gbr").symlink_to(outside)
    for target, why in [("../secret.gbr", "is not inside the folder of top.gbr"),
                        ("sub\\..\\..\\secret.gbr", "is not inside the folder of top.gbr"),
                        (str(outside), "is not inside the folder of top.gbr"),
                        ("C:\\boards\\secret.gbr", "is not inside the folder of top.gbr"),
                        ("link.gbr", "leads out of the folder of top.gbr")]:
        top = board / "top.gbr"
        top.write_text(HEADER + f"X0Y0D02*\n%IF{target}*%\nM02*\n")
        with pytest.raises(GerberError) as caught:
            read_file(top)
        assert (caught.value.pos.file, caught.value.pos.line) == (str(top), 6), target
        assert f"include file {target!r} (%IF) {why}" in caught.value.message


def test_a_region_left_open_at_m02_is_a_positioned_error():
    text = HEADER + "G36*\nX0Y0D02*\nX1000000Y0D01*\nX0Y1000000D01*\nM02*\n"
    error = both_ways(text)
    assert error.pos.line == 9 and "G37" in error.message


def test_coordinates_before_fs_are_a_positioned_error_but_a_file_without_fs_reads():
    error = both_ways("%MOMM*%\nX100Y100D02*\n%FSLAX46Y46*%\n%ADD10C,0.1*%\nM02*\n")
    assert error.pos.line == 3 and "coordinates before %FS (from line 2)" in error.message
    program = read_gerber("t.gbr", "%MOMM*%\nX100Y100D02*\nM02*\n")
    assert "no-fs" in program.metadata["warning_counts"]


def test_a_binary_file_points_at_its_first_byte_that_is_not_text(tmp_path):
    path = tmp_path / "board.gbr"
    path.write_bytes(HEADER.encode() + b"X0Y0D02*\nX1\x00\x01Y2D01*\nM02*\n")
    with pytest.raises(BinaryFileError) as caught:
        read_file(path)
    assert (caught.value.pos.line, caught.value.pos.col) == (6, 3)
    assert "byte 0x00" in caught.value.message
    with pytest.raises(GerberError, match=r"board.gbr:6:3: binary data"):
        read_gerber(path)


def test_nul_and_ctrl_z_padding_after_the_end_is_text(tmp_path):
    path = tmp_path / "padded.gbr"
    path.write_bytes(HEADER.encode() + b"X0Y0D03*\nM02*\r\n" + b"\x00" * 300 + b"\x1a")
    assert len(read_file(path)) > 0


def test_unknown_formats_are_positioned_and_still_unknown_format_errors(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("\n\nshopping list: pens, paper\n")
    with pytest.raises(UnknownFormatError) as caught:
        read_file(path)
    assert caught.value.pos.line == 3
    assert "neither a Gerber RS-274X, a G-code nor a DXF file" in str(caught.value)
    empty = tmp_path / "empty.gbr"
    empty.write_bytes(b"")
    with pytest.raises(UnknownFormatError, match="empty"):
        read_file(empty)


def test_aperture_numbers_and_definition_counts_are_bounded(monkeypatch):
    error = both_ways(HEADER + "%ADD" + "1" * 5000 + "C,0.1*%\nM02*\n")
    assert error.pos.line == 5 and "aperture number" in error.message
    monkeypatch.setenv(limits.MAX_APERTURES_ENV, "50")
    text = HEADER + "".join(f"%ADD{11 + k}C,0.1*%\n" for k in range(60)) + "M02*\n"
    error = both_ways(text)
    assert error.pos.line == 4 + 50 and limits.MAX_APERTURES_ENV in error.message
