"""The package's folders follow the data flow (docs/architecture.md): no module
imports from a later stage than its own, nor sideways from another folder of its
stage; the shell's front end (cli/) never imports the console's, both reach a
machine through backends/; and no two modules import each other, directly or
round a circle. Checked on the source, lazy imports inside functions included."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "galileo_cnc"

#: stage of each top-level module or folder; a module may import its own folder and
#: anything of a lower stage. The reference machine and the wire protocol share a
#: stage, so neither may import the other.
STAGES = {
    "errors": 0,
    "config": 1, "job": 1, "command_text": 1, "program": 1,
    "readers": 2, "machine": 2, "protocol": 2,
    "plan": 3, "transport": 3, "simavr": 3,
    "sim": 4, "stream": 4, "preview": 4, "firmware_headers": 4,
    "grbl": 5,                              # GRBL's job engine builds on stream/'s journal
    "backends": 6,                          # one Machine interface over stream/ and grbl/
    "serve": 7,                             # the web front end (cli's `serve` starts it)
    "console": 8, "cli": 8,                 # the front ends: neither imports the other
    "__main__": 9,                          # the program: starts either front end
}


def _unit(module: str) -> str:
    """'galileo_cnc.plan.planner' -> 'plan'."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = [p for p in rel.parts if p != "__init__"]
    return ".".join(parts)


def _imports(source: str, module: str, is_package: bool) -> list[tuple[int, str]]:
    """(line, absolute module) of every galileo_cnc import in `source`."""
    package = module if is_package else module.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names if a.name.startswith("galileo_cnc")]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "galileo_cnc":                 # from galileo_cnc import protocol
                found += [(node.lineno, f"galileo_cnc.{a.name}") for a in node.names
                          if a.name in STAGES]
            elif target == "galileo_cnc.plan":          # from galileo_cnc.plan import curves
                found += [(node.lineno, f"galileo_cnc.plan.{a.name}") for a in node.names]
            elif target.startswith("galileo_cnc."):
                found.append((node.lineno, target))
    return found


def _later_imports(source: str, module: str, is_package: bool, unit, stages: dict,
                   kind: str = "") -> list[str]:
    """Each import of `module`'s source that reaches a later (or sideways) unit of
    `stages`; `unit` names a module's unit ('' outside them), `kind` the stages'."""
    own = unit(module)
    problems = []
    for line, target in _imports(source, module, is_package):
        other = unit(target)
        if own and other not in ("", own) and not stages[other] < stages[own]:
            name = f"{kind}.{own}" if kind else own
            stage = f"{kind} stage" if kind else "stage"
            problems.append(f"{module}:{line}: {name} ({stage} {stages[own]}) imports "
                            f"{target} ({stage} {stages[other]})")
    return problems


def backward_imports(source: str, module: str, is_package: bool = False) -> list[str]:
    """Each import of `module`'s source that reaches a later (or sideways) stage."""
    return _later_imports(source, module, is_package, _unit, STAGES)


#: plan/'s own stages (galileo_cnc/plan/__init__.py): a plan module imports its own
#: folder and what lies below it. Path order sits below the ink, which starts it on its
#: walks' ends; the ink and the planner share a stage (the pipeline hands the ink's
#: Program to the planner), so neither imports the other; what two stages share
#: (curves, widths, ...) lies below them all.
PLAN_STAGES = {
    "offsets": 0, "curves": 0, "widths": 0, "native": 0, "collector": 0, "measure": 0,
    "transform": 0, "feeds": 0,
    "order": 1, "sides": 1,
    "ink": 2, "planner": 2,
    "mill": 3,                              # milling builds on the ink's exact copper
    "open_traces": 3, "drill_marks": 3, "board_lines": 3,
    "pipeline": 4, "board_plan": 5,
    "gcode_writer": 5,
}


def _plan_unit(module: str) -> str:
    """'galileo_cnc.plan.order.tour' -> 'order'; '' outside plan/ (or plan itself)."""
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[1] == "plan" else ""


def backward_plan_imports(source: str, module: str, is_package: bool = False) -> list[str]:
    """Each import of a plan module's source that reaches a later (or sideways) plan stage."""
    return _later_imports(source, module, is_package, _plan_unit, PLAN_STAGES, "plan")


SOURCES = sorted(p for p in PACKAGE.rglob("*.py") if p.parent.name != "__pycache__")


def front_end_imports(source: str, module: str, is_package: bool = False) -> list[str]:
    """Each import of console/ in a cli/ module: the shell's front end never loads the
    console's (prompt_toolkit); both go through backends/."""
    if _unit(module) != "cli":
        return []
    return [f"{module}:{line}: cli imports {target}"
            for line, target in _imports(source, module, is_package)
            if _unit(target) == "console"]


def import_graph(sources: dict[str, tuple[str, bool]]) -> dict[str, set[str]]:
    """module -> the package's modules it imports (lazy imports included): `from pkg
    import name` is an import of pkg.name when that is a module, else of pkg."""
    graph: dict[str, set[str]] = {}
    for module, (source, is_package) in sources.items():
        package = module if is_package else module.rsplit(".", 1)[0]
        targets = set()
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for alias in node.names:
                    name = f"{target}.{alias.name}"
                    targets.add(name if name in sources else target)
        graph[module] = {t for t in targets if t in sources and t != module}
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of `graph` (its strongly connected parts of two or more)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:           # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph.get(node, ())):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            part = []
            while True:
                other = stack.pop()
                on_stack.discard(other)
                part.append(other)
                if other == node:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def _package_sources() -> dict[str, tuple[str, bool]]:
    return {_module_name(p): (p.read_text(), p.name == "__init__.py") for p in SOURCES}


def test_no_cli_module_imports_the_console():
    problems = [problem for p in SOURCES
                for problem in front_end_imports(p.read_text(), _module_name(p),
                                                 p.name == "__init__.py")]
    assert problems == []


def test_no_import_circle_in_the_package():
    assert import_cycles(import_graph(_package_sources())) == []


def test_the_front_end_and_circle_checks_catch_what_they_forbid():
    assert front_end_imports("def f():\n    from galileo_cnc.console import run_console\n",
                             "galileo_cnc.cli.main") == [
        "galileo_cnc.cli.main:2: cli imports galileo_cnc.console"]
    graph = import_graph({
        "galileo_cnc.console.app": ("from galileo_cnc.console.commands import x\n", False),
        "galileo_cnc.console.commands": ("def f():\n    from galileo_cnc.console.app "
                                         "import Console\n", False)})
    assert import_cycles(graph) == [["galileo_cnc.console.app", "galileo_cnc.console.commands"]]


def test_every_folder_and_module_has_a_stage():
    units = {_unit(_module_name(p)) for p in SOURCES} - {""}
    assert units <= set(STAGES), f"give these a stage: {sorted(units - set(STAGES))}"


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_imports_a_later_stage(path):
    # galileo_cnc/__init__.py (no stage) only registers the URL schemes
    assert backward_imports(path.read_text(), _module_name(path),
                            path.name == "__init__.py") == []


PLAN_SOURCES = [p for p in SOURCES if p.relative_to(PACKAGE).parts[0] == "plan"]


def test_every_plan_module_and_folder_has_a_plan_stage():
    units = {_plan_unit(_module_name(p)) for p in PLAN_SOURCES} - {""}
    assert units <= set(PLAN_STAGES), f"give these a plan stage: {sorted(units - set(PLAN_STAGES))}"


@pytest.mark.parametrize("path", PLAN_SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_plan_module_imports_a_later_plan_stage(path):
    assert backward_plan_imports(path.read_text(), _module_name(path),
                                 path.name == "__init__.py") == []


def test_the_plan_rule_catches_later_and_sideways_stages():
    # path order never asks the planner, nor the ink
    assert backward_plan_imports("from galileo_cnc.plan.planner import PlanError\n",
                                 "galileo_cnc.plan.order.paths") == [
        "galileo_cnc.plan.order.paths:1: plan.order (plan stage 1) imports "
        "galileo_cnc.plan.planner (plan stage 2)"]
    # the planner borrows nothing from the ink (its three helpers moved down)
    assert len(backward_plan_imports("from galileo_cnc.plan.ink.inking import mm_text\n",
                                     "galileo_cnc.plan.planner")) == 1
    assert len(backward_plan_imports("def f():\n    from galileo_cnc.plan import ink\n",
                                     "galileo_cnc.plan.order.tour")) == 1
    # shared helpers import no stage, not even each other
    assert len(backward_plan_imports("from galileo_cnc.plan import native\n",
                                     "galileo_cnc.plan.curves")) == 1
    # a stage's own folder, and relative imports, resolve as in the package rule
    assert backward_plan_imports("from .chains import chain\n",
                                 "galileo_cnc.plan.order.paths") == []
    assert backward_plan_imports("from galileo_cnc.plan.order import paths\n",
                                 "galileo_cnc.plan.planner") == []


def test_the_rule_catches_backward_and_sideways_imports():
    assert backward_imports("from galileo_cnc.plan.planner import plan_program\n",
                            "galileo_cnc.readers.probe") == [
        "galileo_cnc.readers.probe:1: readers (stage 2) imports galileo_cnc.plan.planner "
        "(stage 3)"]
    # the reference machine never imports the protocol (same stage, another folder)
    assert len(backward_imports("def f():\n    from galileo_cnc import protocol\n",
                                "galileo_cnc.machine.planner")) == 1
    assert backward_imports("from ..job import Rapid\n", "galileo_cnc.protocol.spec") == []


def test_pyproject_ships_every_package_and_the_help_file():
    # a package missing from the list is missing from every `pip install .`
    import tomllib

    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())
                 ["tool"]["setuptools"]["packages"])
    on_disk = {".".join(p.parent.relative_to(PACKAGE.parent).parts)
               for p in PACKAGE.rglob("__init__.py")}
    assert on_disk | {"galileo_cnc.helpfiles"} == listed
    assert (PACKAGE.parent / "helpfiles" / "helpfile.f").is_file()


def test_the_architecture_doc_names_every_folder_and_its_stage():
    # docs/architecture.md is the map a newcomer reads: every package folder appears in
    # its tree (a line starting "name/"), and every stage of STAGES in its table with
    # that number
    doc = (PACKAGE.parent / "docs" / "architecture.md").read_text()
    tree = doc.split("## The tree", 1)[1].split("## The rule", 1)[0]
    entries = {line.split()[0] for line in tree.splitlines() if line.strip()}
    folders = {p.parent.name for p in PACKAGE.rglob("__init__.py")} - {PACKAGE.name}
    missing = sorted(f for f in folders if f"{f}/" not in entries)
    assert missing == [], f"docs/architecture.md's tree leaves out {missing}"
    rows = {}
    for line in doc.split("## The rule", 1)[1].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 2 and cells[0].isdigit():
            for name in cells[1].split("(")[0].replace("`", "").split(","):
                rows[name.strip()] = int(cells[0])
    assert rows == STAGES
