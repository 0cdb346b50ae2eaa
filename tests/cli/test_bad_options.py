"""Bad options are refused before anything is read, planned or moved: NaN and
infinite margins, and output files that could not be written after a long job."""

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = str(ROOT / "samples" / "led-blinker.gbr")


def galileo(*args: str, home: Path) -> subprocess.CompletedProcess:
    env = {"PATH": "/usr/bin:/bin", "GALILEO_CNC_HOME": str(home), "GALILEO_CNC_NO_PROBE": "1",
           "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "galileo_cnc", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "-1", "1e9", "one"])
@pytest.mark.parametrize("command", ["info", "preview", "plot"])
def test_margins_that_are_not_a_length_are_refused(tmp_path, command, value):
    extra = ["-o", str(tmp_path / "p.png")] if command == "preview" else []
    extra += ["--port", "sim://?speed=0", "--yes"] if command == "plot" else []
    done = galileo(command, SAMPLE, f"--margin={value}", *extra, home=tmp_path)
    assert done.returncode == 2
    assert f"argument --margin: expected a length in mm from 0 to 1000, got '{value}'" \
        in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("option, path, expected", [
    ("--preview", "missing/dir/p.png", "the folder {tmp}/missing/dir does not exist"),
    ("--trace", ".", "is a folder, expected a file name"),
])
def test_plot_outputs_are_checked_before_the_job_starts(tmp_path, option, path, expected):
    target = str(tmp_path / path) if path != "." else str(tmp_path)
    done = galileo("plot", SAMPLE, "--port", "sim://?speed=0", "--yes", option, target,
                   home=tmp_path)
    assert done.returncode == 1
    assert expected.format(tmp=tmp_path) in done.stderr
    assert "lines" not in done.stdout          # no progress bar: nothing was sent
    assert not (tmp_path / "journal.json").exists()    # no job was begun


@pytest.mark.parametrize("command", ["preview", "convert"])
def test_outputs_that_cannot_be_written_are_named(tmp_path, command):
    done = galileo(command, SAMPLE, "-o", str(tmp_path / "no" / "out"), home=tmp_path)
    assert done.returncode == 1
    assert done.stderr.strip() == \
        f"galileo-cnc: --output {tmp_path}/no/out: the folder {tmp_path}/no does not exist"


@pytest.mark.parametrize("name, why", [("out.txt", "'.txt' is not an image format it writes"),
                                       ("noext", "the name has no extension")])
def test_preview_names_no_writer_knows_are_refused_before_any_work(tmp_path, name, why):
    # issue 31, item 15: `preview -o out.txt` ended in a traceback after the planning;
    # the file to read is not even opened (it does not exist here) before the name is
    # refused
    target = tmp_path / name
    done = galileo("preview", str(tmp_path / "missing.gbr"), "-o", str(target), home=tmp_path)
    assert done.returncode == 1
    assert done.stderr == (f"galileo-cnc: --output {target}: {why}; name it .png (a picture; "
                           f"also .jpg, .jpeg, .bmp, .tif, .tiff, .webp, .gif) or .svg (a "
                           f"vector preview a browser can zoom)\n")
    assert not target.exists()


def test_plot_preview_without_an_extension_is_refused_before_the_job(tmp_path):
    # `plot --preview noext` crashed after the whole job had been plotted
    done = galileo("plot", SAMPLE, "--port", "sim://?speed=0", "--yes", "--mode", "centre",
                   "--preview", str(tmp_path / "noext"), home=tmp_path)
    assert done.returncode == 1
    assert done.stderr.startswith(f"galileo-cnc: --preview {tmp_path}/noext: the name has "
                                  "no extension; name it .png")
    assert done.stdout == ""                   # nothing connected, planned or sent
    assert not (tmp_path / "journal.json").exists()


def test_plot_with_no_board_found_is_an_error_unless_sim_is_named(tmp_path):
    # issue 31, item 13: no board found, plot went on for minutes on the real-time
    # simulated machine; now only a named sim:// plots there
    done = galileo("plot", SAMPLE, "--yes", "--mode", "centre", home=tmp_path)
    assert done.returncode == 1
    assert done.stderr == ("galileo-cnc: plot: no board found (no serial port answered as "
                           "galileo-cnc firmware or GRBL): connect it, or name its port with "
                           "--port (galileo-cnc ports --probe lists them); --port sim:// plots "
                           "on the built-in simulated machine (sim://?speed=0 at once)\n")
    assert done.stdout == ""
    svg = tmp_path / "plotted.svg"           # and the vector preview of what was plotted
    done = galileo("plot", SAMPLE, "--yes", "--mode", "centre", "--port", "sim://?speed=0",
                   "--preview", str(svg), home=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "connected to sim://?speed=0" in done.stdout and "no board found" not in done.stdout
    assert f"preview: {svg}: vector preview " in done.stdout
    assert ET.parse(svg).getroot().tag == "{http://www.w3.org/2000/svg}svg"
