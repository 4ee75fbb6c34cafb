"""The package's structure as docs/architecture.md states it: layers, no import cycle, where
OpenCV, matplotlib and the simulation may be imported, module count and file sizes.

Imports are read from the source with ``ast`` (inside functions too), so a lazy import that
runs upward or closes a circle fails here as surely as a module-level one.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "multieye"

#: Layer of each subpackage or top-level module (docs/architecture.md).
LAYERS = {
    "core": 0, "optimize": 1, "imaging": 1, "io": 1, "solvers": 2, "estimate": 3,
    "pipeline": 4, "outputs": 5, "sim": 5, "experiments": 6, "demo": 6, "many": 6, "cli": 7,
    "__main__": 8,
}
#: What the simulation layer may use, although it sits above them (it renders and writes
#: datasets, nothing more).
SIM_MAY_IMPORT = {"core", "imaging", "io", "sim"}
CV2_ALLOWED = ("core/lens.py", "imaging/", "sim/", "io/intrinsics_files.py", "io/rosbag.py")
MATPLOTLIB_ALLOWED = ("outputs/figures.py", "outputs/figures_rig.py", "experiments/figures.py")
SIM_USERS = ("sim", "experiments", "demo", "cli")


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


def _imports(path: Path) -> tuple[set[str], set[str]]:
    """multieye modules and third-party top-level packages that a file imports."""
    ours, theirs = set(), set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            (ours if name.split(".")[0] == "multieye" else theirs).add(name)
    return ours, {n.split(".")[0] for n in theirs}


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The module an imported dotted name refers to (a name inside a module -> the module)."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    graph = {}
    for mod, path in modules.items():
        targets = {_resolve(n, modules) for n in _imports(path)[0]}
        graph[mod] = {t for t in targets if t and t != mod}
    return graph


def _package(mod: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "(top)"


def test_no_import_cycle_between_modules():
    graph = _graph()
    # a package's __init__ re-exporting its own modules is not a cycle with them; every
    # other edge counts
    edges = {m: {t for t in ts if not (m == t.rpartition(".")[0] and m.count(".") >= 1)}
             for m, ts in graph.items()}
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in sorted(edges.get(m, ())):
            if state.get(t) == 1:
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)
    assert cycles == [], "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_imports_point_down_the_layers():
    wrong = []
    for mod, targets in _graph().items():
        src = _package(mod)
        for t in targets:
            dst = _package(t)
            if src == dst:
                continue
            if dst == "(top)":
                wrong.append(f"{mod} imports the top-level package {t}")
            elif src == "sim" and dst not in SIM_MAY_IMPORT:
                wrong.append(f"{mod} (sim) imports {t}")
            elif src != "(top)" and LAYERS[dst] >= LAYERS[src]:
                wrong.append(f"{mod} (layer {LAYERS[src]}) imports {t} (layer {LAYERS[dst]})")
    assert wrong == []


def test_every_subpackage_has_a_layer():
    packages = {_package(m) for m in _modules()} - {"(top)"}
    assert packages <= set(LAYERS), f"no layer for {sorted(packages - set(LAYERS))}"


def test_only_the_simulation_its_experiments_the_demo_and_the_cli_import_the_simulation():
    users = {mod for mod, targets in _graph().items()
             if any(_package(t) == "sim" for t in targets)}
    assert {u for u in users if _package(u) not in SIM_USERS} == set()


@pytest.mark.parametrize("package, allowed", [("cv2", CV2_ALLOWED),
                                              ("matplotlib", MATPLOTLIB_ALLOWED)])
def test_opencv_and_matplotlib_stay_in_their_modules(package, allowed):
    users = [p.relative_to(SRC).as_posix() for p in SRC.rglob("*.py")
             if package in _imports(p)[1]]
    assert [u for u in users if not u.startswith(allowed)] == []
    assert users, f"no module imports {package}: the allow-list is stale"


def test_few_top_level_modules_and_no_long_files():
    top = {p.name for p in SRC.glob("*.py")} - {"__init__.py", "__main__.py", "cli.py"}
    assert len(top) <= 6, sorted(top)
    long = {p.relative_to(SRC).as_posix(): n for p in SRC.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 600}
    assert long == {}


def test_tests_mirror_the_package():
    tests = Path(__file__).parent
    for package in LAYERS:
        if (SRC / package).is_dir():
            assert (tests / package).is_dir(), f"tests/{package}/ is missing"
