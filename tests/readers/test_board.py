"""Boards: which files make one and each file's role (readers/board/; issue 32, item 2).

The expected roles below were written by reading the files (their X2 attributes, the
tools' header comments, the names, the drill files' comments), not by running the code:
every file of every corpus board that carries drill files, Gerber folder
<corpus>/<tool>/<board>/ plus drill folder <corpus>/drill/<tool>/<board>/.
"""

from __future__ import annotations

import json
import os
import shutil
import zipfile
from pathlib import Path

import pytest

from galileo_cnc.program.drills import DrillFile, Hole, Slot
from galileo_cnc.readers.board.board import BoardError, open_board
from galileo_cnc.readers.board.describe import describe_board
from galileo_cnc.readers.board.roles import ROLES
from tests.corpus import CORPUS

TC, BC, IC = "top-copper", "bottom-copper", "inner-copper"
TS, BS, TM, BM, TP, BP = ("top-silk", "bottom-silk", "top-mask", "bottom-mask", "top-paste",
                          "bottom-paste")
OUT, DP, DU, DR, OTHER = "outline", "drill-plated", "drill-unplated", "drill", "other"


def _kicad(prefix: str, sep: str, ext: str = "", silk: str = "SilkS", paste: bool = True) -> dict:
    roles = {"F{s}Cu": TC, "B{s}Cu": BC, "F{s}" + silk: TS, "B{s}" + silk: BS,
             "F{s}Mask": TM, "B{s}Mask": BM, "Edge{s}Cuts": OUT}
    if paste:
        roles.update({"F{s}Paste": TP, "B{s}Paste": BP})
    return {f"{prefix}-{layer.format(s=sep)}{ext}": role for layer, role in roles.items()}


EXPECTED: dict[str, dict[str, str]] = {
    "allegro/minnowmax-reva1": {
        "MinnowMax_assy.art": OTHER, "MinnowMax_fab.art": OTHER,
        "MinnowMax_lyr1_GAF.art": TC, "MinnowMax_lyr2.art": IC, "MinnowMax_lyr3.art": IC,
        "MinnowMax_lyr5.art": IC, "MinnowMax_lyr6.art": IC, "MinnowMax_lyr8.art": IC,
        "MinnowMax_lyr9.art": IC,            # a 10-layer board (its drill file: 1-10)
        "MinnowMax_smc_GAF.art": TM, "MinnowMax_spc.art": TP,
        "MinnowMax_RevA1_NCDRILL.drl": DR,   # PLATED and NON_PLATED tools
        "MinnowMax_RevA1_NCROUTE.rou": DR},
    "allegro/tracespace-371": {
        "assy1.art": OTHER, "fab1.art": OTHER, "l1_primary.art": TC, "l3_vcc.art": IC,
        "l4_secondary.art": BC, "mask_sec.art": BM, "paste_prm.art": TP, "silk_prm.art": TS,
        "silk_sec.art": BS, "08_057494d.rou": DR, "ncdrill-1-4.drl": DR},
    "altium/limesdr-qpcie": {
        "LimeSDR-QPCIe_1v2.G2": IC, "LimeSDR-QPCIe_1v2.GBO": BS, "LimeSDR-QPCIe_1v2.GM1": OUT,
        "LimeSDR-QPCIe_1v2.GTL": TC, "LimeSDR-QPCIe_1v2.GTP": TP, "LimeSDR-QPCIe_1v2.GTS": TM,
        "LimeSDR-QPCIe_1v2-RoundHoles.TXT": DR, "LimeSDR-QPCIe_1v2-SlotHoles.TXT": DR},
    "altium/usbvil": {
        "pic18f14k50.gbl": BC, "pic18f14k50.gbo": BS, "pic18f14k50.gbs": BM,
        "pic18f14k50.gko": OUT, "pic18f14k50.gtl": TC, "pic18f14k50.gto": TS,
        "pic18f14k50.gts": TM, "pic18f14k50.txt": DR},
    "diptrace/mainboard": {
        "mainboard_BoardOutline.gbr": OUT, "mainboard_Bottom.gbr": BC,
        "mainboard_BottomMask.gbr": BM, "mainboard_Top.gbr": TC, "mainboard_TopMask.gbr": TM,
        "mainboard_TopSilk.gbr": TS, "mainboard.drl": DR},
    "diptrace/panel": {
        "panel_BoardOutline.gbr": OUT, "panel_Bottom.gbr": BC, "panel_BottomMask.gbr": BM,
        "panel_BottomSilk.gbr": BS, "panel.drl": DR},
    "eagle/8bit-mixtape": {
        "mixtape.gbl": BC, "mixtape.gbo": BS, "mixtape.gbp": BP, "mixtape.gbs": BM,
        "mixtape.gml": OUT, "mixtape.gtl": TC, "mixtape.gto": TS, "mixtape.gtp": TP,
        "mixtape.gts": TM, "mixtape.txt": DR},
    "eagle/arduino-uno": {
        "arduino-uno.cmp": TC, "arduino-uno.gko": OUT, "arduino-uno.plc": TS,
        "arduino-uno.sol": BC, "arduino-uno.stc": TM, "arduino-uno.sts": BM,
        "arduino-uno.drd": DR},
    "eagle/core": {
        "core.GBL": BC, "core.GBO": BS, "core.GBP": BP, "core.GBS": BM, "core.GTL": TC,
        "core.GTO": TS, "core.GTP": TP, "core.GTS": TM, "core.MIL": OUT, "core.TXT": DR},
    "eagle/freeduino": {
        "freeduino.cmp": TC, "freeduino.plc": TS, "freeduino.sol": BC, "freeduino.stc": TM,
        "freeduino.sts": BM, "freeduino.drd": DR},
    "eagle/gyw-electro-x2": {
        "copper_bottom.gbr": BC, "copper_top.gbr": TC, "profile.gbr": OUT,
        "silkscreen_bottom.gbr": BS, "silkscreen_top.gbr": TS, "soldermask_bottom.gbr": BM,
        "soldermask_top.gbr": TM, "solderpaste_bottom.gbr": BP, "solderpaste_top.gbr": TP,
        "drills.xln": DR},
    "eagle/manifold-slave": {
        f"manifold-slave-v1.{ext}": role for ext, role in (
            ("GBL", BC), ("GBO", BS), ("GBP", BP), ("GBS", BM), ("GML", OUT), ("GTL", TC),
            ("GTO", TS), ("GTP", TP), ("GTS", TM), ("TXT", DR))},
    "eagle/pcb-tools-example": {
        "board_outline.GKO": OUT, "bottom_copper.GBL": BC, "bottom_mask.GBS": BM,
        "bottom_silk.GBO": BS, "copper.GTL": TC, "silkscreen.GTO": TS, "soldermask.GTS": TM,
        "top_copper.GTL": TC, "top_mask.GTS": TM, "top_silk.GTO": TS, "ncdrill.DRD": DR},
    "easyeda/tracespace-367": {
        "Gerber_BoardOutline.GKO": OUT, "Gerber_BottomSolderMaskLayer.GBS": BM,
        "Gerber_TopLayer.GTL": TC, "Gerber_TopSilkLayer.GTO": TS,
        "Gerber_TopSolderMaskLayer.GTS": TM, "Gerber_Drill_NPTH.DRL": DU,
        "Gerber_Drill_PTH.DRL": DP},
    "geda-pcb/hellboard": {
        "hellboard.back.gbr": BC, "hellboard.fab.gbr": OTHER,
        "hellboard.group1.gbr": IC,           # "ground", a copper group of its own
        "hellboard.plated-drill.cnc": DP},
    "geda-pcb/numpres": {
        "numpres.pcb.output_componentmask.grb": TM,
        "numpres.pcb.output_group1.grb": BC,  # "contains layers solder (0) ..."
        "numpres.pcb.output_group2.grb": TC,  # "contains layers component (3) ..."
        "numpres.pcb.output_plated-drill.grb": DP, "numpres.pcb.output_unplated-drill.grb": DU},
    "geda-pcb/stepper-lights-controller": {
        "controller.bottom.gbr": BC, "controller.bottommask.gbr": BM,
        "controller.fab.gbr": OTHER, "controller.group3.gbr": IC, "controller.top.gbr": TC,
        "controller.topmask.gbr": TM, "controller.topsilk.gbr": TS,
        "controller.plated-drill.cnc": DP, "controller.unplated-drill.cnc": DU},
    "kicad/8seg-driver": {**_kicad("driver", "_"), "driver-NPTH": DU, "driver-PTH": DP},
    "kicad/atmega328-motor-board": {
        **{name + ext: role for (name, role), ext in zip(
            _kicad("ATMEGA328_Motor_Board", ".").items(),
            (".gtl", ".gbl", ".gto", ".gbo", ".gts", ".gbs", ".gm1", ".gtp", ".gbp"))},
        "ATMEGA328_Motor_Board.drl": DR},
    "kicad/chibi-2024": {**_kicad("chibi_2024", ".", ".gbr"), "chibi_2024.drl": DR},
    "kicad/flashpads-nox2noap": {**_kicad("Flashpads", "_", ".gbr", silk="Silkscreen"),
                                 "Flashpads-NPTH.drl": DU, "Flashpads-PTH.drl": DP},
    "kicad/flashpads-x2ap": {**_kicad("Flashpads", "_", ".gbr", silk="Silkscreen"),
                             "Flashpads-NPTH.drl": DU, "Flashpads-PTH.drl": DP},
    "kicad/mchck": {**_kicad("mchck", "_", ".pho", paste=False), "mchck.drl": DR},
    "mentor-xpedition/ekf-ccgr0": {
        "jj1.grb": BP,                        # "G04 Layer : SolderPasteBottom.gdo"
        "stp0.grb": BM,                       # "G04 Layer : SoldermaskBottom.gdo"
        "jj1.drl": DP},                       # "; Contents: Thru / Mill / Plated"
    "mentor-xpedition/minnowmax-80101": {
        **{f"80101_0125_F200_L{n:02d}.gdo": IC for n in (2, 3, 5, 8, 9, 11)},
        "80101_0125_F200_L12_Bottom.gdo": BC,
        "80101_0125_F200_SilkscreenBottom.gdo": BS, "80101_0125_F200_SilkscreenTop.gdo": TS,
        "80101_0125_F200_SolderPasteBottom.gdo": BP,
        "80101_0125_F200_SoldermaskBottom.gdo": BM, "80101_0125_F200_SoldermaskTop.gdo": TM,
        "80101_0125_F200_ContourPlated.ncd": DP, "80101_0125_F200_ThruHoleNonPlated.ncd": DU,
        "80101_0125_F200_ThruHolePlated.ncd": DP},
    "mentor-xpedition/nollezappare-veribest": {"AssemblyTop.gdo": OTHER,
                                               "ThruHolePlated.ncd": DP},
    "orcad/led-display-g4-arena": {
        "Assembly.art": OTHER, "GND2.art": IC,
        "LAYER_1.art": IC,                    # ETCH/LAYER 1: an inner layer of six
        "PWR.art": IC, "Solder_Mask_Bottom.art": BM, "TOP.art": TC,
        "silk_screen_bottom.art": BS, "arena_12-12_v6_L1-L6.drl": DR},
    "orcad/rs232-cm-orcad-layout": {
        "rs232_cm.asb": OTHER, "rs232_cm.bot": BC,
        "rs232_cm.drd": OTHER,                # a Gerber drill drawing
        "rs232_cm.smt": TM, "rs232_cm.ssb": BS, "rs232_cm.top": TC, "thruhole.tap": DR},
    "p-cad/zxinet": {
        "ZXINET.GBL": BC, "ZXINET.GBS": BM, "ZXINET.GKO": OUT, "ZXINET.GTO": TS,
        "ZXINET.GTS": TM, "ZXINET.DRL": DR},
    "pads/osu-mars-rover-2011": {
        "Bottom.pho": BC, "Layer3.pho": IC, "SMB.pho": BM, "SSB.pho": BS, "SST.pho": TS,
        "Drill.drl": DR},
    "pcb-rnd/epl-isolatedpwr": {
        "power-art.asb": OTHER, "power-art.fab": OTHER, "power-art.gbl": BC,
        "power-art.gbp": BP, "power-art.gbs": BM, "power-art.gtl": TC, "power-art.gto": TS,
        "power-art.gts": TM, "power-art.xln": DR},
    "target3001/solarcast-irnasiotbank": {
        "IRNASIoTbank1.2.PasteBot": BP, "IRNASIoTbank1.2.PasteTop": TP,
        "IRNASIoTbank1.2.PosiTop": TS, "IRNASIoTbank1.2.StopBot": BM,
        "IRNASIoTbank1.2.Top": TC, "IRNASIoTbank1.2.Drill": DR},
    # EKF's German names; side 1 carries the SMD pads (its flashes coincide with stp1's
    # and sieb1's) and d1's legend reads unmirrored (the title block, the references):
    # the top; side 0 is the solder side, as in ekf-ccgr0's stp0 (SoldermaskBottom)
    "unknown/ekf2": {
        "d1.grb": TS, "l0.grb": BC, "l1.grb": TC, "l3.grb": IC, "l4.grb": IC, "pow.grb": IC,
        "pow3.grb": IC, "sieb0.grb": BP, "sieb1.grb": TP, "stp0.grb": BM, "stp1.grb": TM,
        "drill0.exc": DR, "drill1.exc": DR, "drill20.exc": DR, "drill30.exc": DR},
    "upverter/sportiduino": {
        "design_export.gbl": BC, "design_export.gbp": BP, "design_export.gbs": BM,
        "design_export.gtl": TC, "design_export.gto": TS, "design_export.gts": TM,
        "design_export.xln": OTHER,           # Gerber flashes of the holes, not Excellon
        "design_export.drl": DR},
    "zuken-emulated/8seg-driver": {
        "Conductive-1.fph": TC, "MetalMask-A.fph": TP, "MetalMask-B.fph": BP,
        "Resist-B.fph": BM, "Symbol-A.fph": TS,
        "8seg_Driver__routed_Drill_thru_nplt.fdr": DU,
        "8seg_Driver__routed_Drill_thru_plt.fdr": DP},
}


def _board_files(board: str) -> list[Path]:
    """The corpus files of a board: its Gerber folder (upstream notes left out) and drills."""
    files = []
    for folder in (CORPUS / board, CORPUS / "drill" / board):
        if folder.is_dir():
            files += [p for p in sorted(folder.iterdir())
                      if p.is_file() and not p.name.startswith("UPSTREAM")]
    return files


def test_the_table_covers_every_corpus_board_with_drill_files():
    boards = {f"{tool.name}/{board.name}" for tool in (CORPUS / "drill").iterdir()
              for board in tool.iterdir() if board.is_dir()}
    assert boards == set(EXPECTED)
    for board, roles in EXPECTED.items():
        assert set(roles.values()) <= set(ROLES), board
        assert {p.name for p in _board_files(board)} <= set(roles), board


def _roles(board) -> dict[str, str]:
    return {layer.file.rsplit("/", 1)[-1]: layer.role for layer in board.layers}


def _assert_roles(board, expected: dict[str, str], present: set[str]) -> int:
    """No file a wrong role; every file a role, but where the corpus in use keeps only part
    of a board (the curated one), a numbered copper layer without the bottom copper beside
    it may rightly stay unplaced."""
    got = _roles(board)
    unplaced = {u.file.rsplit("/", 1)[-1]: u.why for u in board.unplaced}
    if present == set(expected):
        assert not unplaced, unplaced
    assert all("no file is the bottom copper" in why for why in unplaced.values()), unplaced
    assert {u.file for u in board.ignored} == {"README.txt"}
    wrong = {name: (got.get(name), expected[name]) for name in present
             if name not in unplaced and got.get(name) != expected[name]}
    assert not wrong, f"{board.source}: (got, expected) {wrong}"
    assert set(got) | set(unplaced) == present
    assert all(layer.why for layer in board.layers)
    return len(got)


def test_every_file_of_every_corpus_board_gets_its_role_in_a_folder_and_a_zip(tmp_path):
    checked = 0
    for name, expected in EXPECTED.items():
        files = _board_files(name)
        if not files:
            continue   # a corpus without this board
        folder = tmp_path / name.replace("/", "_")
        (folder / "drill").mkdir(parents=True)
        for path in files:   # drill files in a subfolder, as many exports do
            target = folder / ("drill" if path.parent.parent.parent.name == "drill" else "")
            os.symlink(path, target / path.name)
        (folder / "README.txt").write_text("exported for the fab\n")
        present = {p.name for p in files}
        board = open_board(folder)
        checked += _assert_roles(board, expected, present)
        archive = tmp_path / f"{name.replace('/', '_')}.zip"
        with zipfile.ZipFile(archive, "w", zipfile.ZIP_STORED) as zipped:
            for path in files:
                zipped.write(path, f"{name.split('/')[1]}/{path.name}")
        zipped_board = open_board(archive)
        try:
            assert _roles(zipped_board) == _roles(board)
            assert len(zipped_board.unplaced) == len(board.unplaced)
        finally:
            zipped_board.close()
    assert checked >= 40   # the curated corpus keeps at least this many of these files


KICAD_HEAD = "%FSLAX46Y46*%\n%MOMM*%\n"
X2_HEAD = "%TF.FileFunction,{}*%\n" + KICAD_HEAD


def _write(folder: Path, files: dict[str, str]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (folder / name).write_text(text)
    return folder


def test_a_job_file_places_files_whose_names_say_nothing(tmp_path):
    job = {"Header": {"GenerationSoftware": {"Vendor": "KiCad", "Application": "Pcbnew"}},
           "FilesAttributes": [
               {"Path": "a.gbr", "FileFunction": "Copper,L1,Top", "FilePolarity": "Positive"},
               {"Path": "b.gbr", "FileFunction": "Copper,L2,Bot", "FilePolarity": "Positive"},
               {"Path": "c.gbr", "FileFunction": "Legend,Bot", "FilePolarity": "Positive"},
               {"Path": "d.gbr", "FileFunction": "Profile,NP", "FilePolarity": "Positive"}]}
    folder = _write(tmp_path / "b", {name: KICAD_HEAD + "M02*\n"
                                     for name in ("a.gbr", "b.gbr", "c.gbr", "d.gbr")})
    (folder / "board.gbrjob").write_text(json.dumps(job))
    for where in (folder, folder / "board.gbrjob"):
        board = open_board(where)
        assert {layer.file: layer.role for layer in board.layers} == {
            "a.gbr": TC, "b.gbr": BC, "c.gbr": BS, "d.gbr": OUT}
        assert all(layer.why.startswith("job file") for layer in board.layers)
        assert board.job == "board.gbrjob" and not board.unplaced


def test_x2_wins_over_the_name_and_says_so(tmp_path):
    folder = _write(tmp_path / "b", {"board-F_Cu.gbr": X2_HEAD.format("Copper,L2,Bot") + "M02*\n",
                                     "board.GTO": X2_HEAD.format("Legend,Bot") + "M02*\n",
                                     "board-PTH.gbr": X2_HEAD.format("Plated,1,2,PTH") + "M02*\n"})
    board = open_board(folder)
    got = {layer.file: layer for layer in board.layers}
    assert got["board-F_Cu.gbr"].role == BC and got["board.GTO"].role == BS
    # a drill layer in Gerber form is a drawing to the Excellon reader's eyes
    assert got["board-PTH.gbr"].role == OTHER and "not an Excellon" in got["board-PTH.gbr"].why
    assert "X2 FileFunction Copper,L2,Bot" in got["board-F_Cu.gbr"].why
    assert "name, which says top-copper" in got["board-F_Cu.gbr"].why


def test_a_file_no_rule_places_is_named_and_an_override_places_it(tmp_path):
    drill = "M48\nMETRIC\nT1C0.8\n%\nT1\nX1.0Y1.0\nM30\n"
    folder = _write(tmp_path / "b", {"mystery.gbr": KICAD_HEAD + "M02*\n",
                                     "board-B_Cu.gbr": KICAD_HEAD + "M02*\n",
                                     "holes.txt": drill, "notes.txt": "fab notes\n"})
    board = open_board(folder)
    assert [u.file for u in board.unplaced] == ["mystery.gbr"]
    assert [u.file for u in board.ignored] == ["notes.txt"]
    assert [layer.file for layer in board.drills()] == ["holes.txt"]
    assert [layer.file for layer in board.copper("bottom")] == ["board-B_Cu.gbr"]
    text, data = describe_board(folder)
    assert "mystery.gbr: not placed" in text and "--layer mystery.gbr=ROLE" in text
    assert data["board"]["unplaced"][0]["file"] == "mystery.gbr"
    placed = open_board(folder, ["mystery.gbr=top-copper", "holes.txt=drill-unplated"])
    assert not placed.unplaced
    assert [(layer.file, layer.why) for layer in placed.copper("top")] == [
        ("mystery.gbr", "--layer mystery.gbr=top-copper")]
    assert placed.files("drill-unplated")[0].file == "holes.txt"
    with pytest.raises(BoardError, match="mystery.gbr=copper-top: no role 'copper-top'"):
        open_board(folder, ["mystery.gbr=copper-top"])
    with pytest.raises(BoardError, match="no file of the board .* is named 'nothere.gbr'"):
        open_board(folder, ["nothere.gbr=top-copper"])


def test_a_zip_member_that_climbs_out_is_refused(tmp_path):
    for bad in ("../evil.gbr", "/etc/evil.gbr", "sub/../../evil.gbr"):
        archive = tmp_path / "bad.zip"
        with zipfile.ZipFile(archive, "w") as zipped:
            zipped.writestr("board-F_Cu.gbr", KICAD_HEAD + "M02*\n")
            zipped.writestr(bad, KICAD_HEAD + "M02*\n")
        with pytest.raises(BoardError, match="outside the board's folder; refused"):
            open_board(archive)
    assert not (tmp_path.parent / "evil.gbr").exists()


def test_a_zip_member_over_the_file_limit_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("GALILEO_MAX_FILE_MB", "1")
    archive = tmp_path / "big.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zipped:
        zipped.writestr("board-F_Cu.gbr", KICAD_HEAD + "G04 x*\n" * 300_000)
    with pytest.raises(BoardError, match="more than the 1 MB limit"):
        open_board(archive)


def test_info_gives_the_size_from_the_outline_and_holes_per_diameter(tmp_path):
    board = "kicad/flashpads-x2ap"   # whole in the curated corpus too
    files = _board_files(board)
    if not any(p.name == "Flashpads-Edge_Cuts.gbr" for p in files):
        pytest.skip(f"the corpus in use lacks {board}'s Gerber files")
    folder = tmp_path / "b"
    folder.mkdir()
    for path in files:
        shutil.copy(path, folder / path.name)
    read = []

    def read_drill(path: str) -> DrillFile:   # a drill file as the Excellon reader gives it
        read.append(Path(path).name)
        return DrillFile(path, holes=[Hole(0, 0, 800_000), Hole(1, 1, 800_000),
                                      Hole(2, 2, 1_000_000)],
                         slots=[Slot(0, 0, 5, 5, 1_000_000)])

    text, data = describe_board(folder, read_drill=read_drill)
    summary = data["board"]
    assert summary["size_from"] == "outline"
    # Edge_Cuts: the rectangle X 20..100, Y -70..-20 mm
    assert summary["size_mm"] == {"x": 80.0, "y": 50.0}
    assert summary["bbox_mm"] == {"min_x": 20.0, "min_y": -70.0, "max_x": 100.0, "max_y": -20.0}
    assert "size: 80 x 50 mm (from the outline)" in text
    assert "holes: 6, slots: 2\n  0.8 mm: 4 holes\n  1 mm: 2 holes, 2 slots" in text
    assert sorted(read) == ["Flashpads-NPTH.drl", "Flashpads-PTH.drl"]
    assert summary["holes"] == [{"diameter_mm": 0.8, "holes": 4, "slots": 0},
                                {"diameter_mm": 1.0, "holes": 2, "slots": 2}]
    assert {"file": "Flashpads-PTH.drl", "role": DP, "why": "X2 FileFunction Plated,1,2,PTH"} \
        in summary["layers"]
    assert summary["holes_bbox_mm"] == {"min_x": -0.5, "min_y": -0.5, "max_x": 0.5, "max_y": 0.5}
    assert describe_board(folder)[1]["board"]["holes"] is None
    for path in folder.iterdir():   # drill files alone: the size is the holes' box
        if path.suffix != ".drl":
            path.unlink()
    alone = describe_board(folder, read_drill=read_drill)[1]["board"]
    assert alone["size_from"] == "holes" and alone["size_mm"] == {"x": 1.0, "y": 1.0}


def test_header_and_name_rules_agree_with_x2_wherever_both_speak():
    """X2 is the tools' own word: on every real corpus layer that carries it, the rules
    that stand in for it on other files (header comments, names) say the same role."""
    from galileo_cnc.readers.board.headers import header_role
    from galileo_cnc.readers.board.names import gerber_name_role
    from galileo_cnc.readers.board.roles import HEAD_BYTES, file_kind, x2_role
    from tests.corpus import corpus_paths

    # tracespace's open-outline fixture: a fabrication drawing (X2) named for its outline
    named_otherwise = {"cuprum/tracespace-365/open_outline_altium.gbr"}
    agree = []
    for relative in corpus_paths("real"):
        with open(CORPUS / relative, "rb") as handle:
            head = handle.read(HEAD_BYTES).decode("utf-8", "replace")
        kind = file_kind(head)
        said = x2_role(head, kind) if kind == "gerber" else None
        other = said and (header_role(head) or gerber_name_role(Path(relative).name))
        if not other or relative in named_otherwise:
            continue
        assert other.role == said.role, (relative, said.why, other.why)
        agree.append(relative)
    assert len(agree) >= 60, len(agree)   # 66 in the curated corpus, 87 in the full one
