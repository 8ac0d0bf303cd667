"""The layers import only downward, with no loops, counting imports inside functions: the
ranks are :data:`RANK` (docs/architecture.md's table); ``firmware_sim`` imports nothing of the
project."""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("limbctl", "calib", "firmware_sim")

#: The layers from rank 0 up, those of one rank together; a module may import modules of equal or
#: lower rank (siblings excepted where SIBLINGS_APART says so).
RANKED = "errors calib, geometry, servo, region, envelope, teach teleop view, eval, app"
#: Rank of each layer.
RANK = {layer: rank for rank, layers in enumerate(RANKED.split(", ")) for layer in layers.split()}
#: Layers of one rank that must not import each other.
SIBLINGS_APART = {"teach", "teleop", "view"}
#: Modules directly in limbctl/ that are the app.
APP = set("cli jobs file_jobs upkeep demo live session plot operators __init__ __main__".split())


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    return {
        module_name(path): path for package in PACKAGES for path in (ROOT / package).rglob("*.py")
    }


def imported(path: Path, name: str, modules: dict[str, Path]) -> set[str]:
    """Every module ``path`` imports, at top level or inside functions, as dotted names
    (``from package import module`` as ``package.module``: ``__init__`` re-exports from below)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            subs = {f"{base}.{alias.name}" for alias in node.names}
            found.update(subs & modules.keys())
            if not subs <= modules.keys():
                found.add(base)
    return found


def layer(name: str) -> str | None:
    """The layer of a project module, None for anything outside the project."""
    parts = name.split(".")
    if parts[0] in ("calib", "firmware_sim"):
        return parts[0]
    if parts[0] != "limbctl":
        return None
    if len(parts) == 1:
        return "app"
    if parts[1] in RANK:
        return parts[1]
    if parts[1] in APP:
        return "app"
    raise AssertionError(f"{name}: not in any layer; add it to a subpackage or to APP")


def project_edges() -> dict[str, set[str]]:
    modules = all_modules()
    edges: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets = set()
        for target in imported(path, name, modules):
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name:
                targets.add(target)
        edges[name] = targets
    return edges


EDGES = project_edges()


@pytest.mark.parametrize("name", sorted(EDGES))
def test_imports_point_down(name):
    source = layer(name)
    for target in EDGES[name]:
        goal = layer(target)
        if source == "firmware_sim" or goal == "firmware_sim":
            assert source == goal or source == "app", f"{name} imports {target}"
            continue
        if source == "calib":
            assert goal == "calib", f"calib must import nothing of limbctl: {name} -> {target}"
            continue
        assert RANK[goal] <= RANK[source], f"{name} ({source}) imports {target} ({goal}) above it"
        if goal != source and goal in SIBLINGS_APART:
            assert source not in SIBLINGS_APART, f"{name} imports its sibling layer {target}"
        if goal == "eval":
            assert source in ("eval", "app"), f"eval is used only by the app: {name} -> {target}"


def test_no_import_loops():
    """No import loop (a package's ``__init__`` re-exporting its own submodules is none)."""
    graph = {n: {t for t in EDGES[n] if t in EDGES and not n.startswith(t + ".")} for n in EDGES}
    try:
        graphlib.TopologicalSorter(graph).prepare()
    except graphlib.CycleError as exc:
        pytest.fail(f"import loop: {exc.args[1]}")


def test_modules_are_short_few_at_the_top_and_cite_nothing_outside_the_repository():
    texts = {name: path.read_text(encoding="utf-8") for name, path in all_modules().items()}
    long = {name: n for name, text in texts.items() if (n := len(text.splitlines())) > 500}
    assert not long, f"modules over 500 lines: {long}"
    flat = sorted(p.name for p in (ROOT / "limbctl").glob("*.py"))
    assert len(flat) <= 12, f"more than a dozen modules directly in limbctl: {flat}"
    for name, text in texts.items():
        assert "DESIGN.md" not in text and "../shared" not in text, f"{name} cites outside"
