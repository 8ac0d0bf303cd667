"""docs/architecture.md against the code: cited paths, dotted and bare names, the rank table
and links resolve, every limbctl part is named; a stale document shows the checks fail."""

from __future__ import annotations

import functools
import importlib
import re
from functools import cache
from pathlib import Path
from types import ModuleType

from tests.test_layers import RANK

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
#: Top folders whose paths the document may cite.
PATH_ROOTS = ("limbctl", "firmware_sim", "calib", "docs", "tests", "benchmarks")
#: Top packages whose dotted names the document may cite.
PACKAGES = ("limbctl", "firmware_sim", "calib")
#: The registries section 5 must cite, as dotted names.
REGISTRIES = (
    "limbctl.teleop.sources.SOURCES",
    "limbctl.region.edge_choice.EDGE_STRATEGIES",
    "limbctl.region.edge_choice.AUTO_ORDER",
    "limbctl.envelope.MODEL_KINDS",
    "limbctl.servo.control_table.MODEL_BY_NAME",
    "firmware_sim.control_table.MODELS",
    "limbctl.servo.families.FAMILIES",
    "limbctl.cli.SUBCOMMANDS",
)

_FENCE = re.compile(r"^```.*?^```", re.S | re.M)
_CODE = re.compile(r"`([^`]+)`")
_PATH = re.compile(rf"^(?:{'|'.join(PATH_ROOTS)})/[\w./*-]*$")
_DOTTED = re.compile(rf"^(?:{'|'.join(PACKAGES)})(?:\.\w+)+(?:\(\))?$")
_CLASS = re.compile(r"^[A-Z][a-z]\w*(?:\.\w+)*(?:\(\))?$")
_CONSTANT = re.compile(r"^[A-Z][A-Z0-9]*_[A-Z0-9_]*$|^[A-Z]{3,}$")
_FUNCTION = re.compile(r"^_?[a-z]\w*\(\)$")
_MODULE_ATTRIBUTE = re.compile(r"^[a-z]\w*(?:\.\w+)+$")
_LINK = re.compile(r"\]\(([^)\s]+)\)")
_RANK_ROW = re.compile(r"^\|\s*(\d+)\s*\|\s*`(\w+)`\s*\|", re.M)


def code_spans(text: str) -> list[str]:
    """Every inline code span outside fenced blocks, in order (a line break read as a space)."""
    return [re.sub(r"\s*\n\s*", " ", span) for span in _CODE.findall(_FENCE.sub("", text))]


def cited_paths(text: str) -> list[str]:
    return [span for span in code_spans(text) if _PATH.match(span)]


def missing_paths(text: str, root: Path = ROOT) -> list[str]:
    """Cited paths that do not exist (a glob matching nothing; a limbctl folder not a package)."""
    missing = []
    for span in cited_paths(text):
        if "*" in span:
            found = any(root.glob(span))
        elif span.endswith("/"):
            found = (root / span).is_dir()
            if span.startswith("limbctl/"):
                found = found and (root / span / "__init__.py").is_file()
        else:
            found = (root / span).exists()
        if not found:
            missing.append(span)
    return missing


def module_of_path(span: str) -> str | None:
    """The importable module a cited path stands for, or None."""
    path = ROOT / span.rstrip("/")
    if path.is_dir() and (path / "__init__.py").is_file():
        return ".".join(path.relative_to(ROOT).parts)
    if path.suffix == ".py" and path.is_file() and path.parent != ROOT / "benchmarks":
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
    return None


@cache
def _import(name: str) -> ModuleType | None:
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


def resolve(dotted: str) -> object:
    """The object a dotted name stands for (the longest importable prefix, then attributes);
    LookupError when no prefix imports or an attribute is missing."""
    parts = dotted.removesuffix("()").split(".")
    for cut in range(len(parts), 0, -1):
        module = _import(".".join(parts[:cut]))
        if module is None:
            continue
        try:
            return functools.reduce(getattr, parts[cut:], module)
        except AttributeError as exc:
            missing = f"{'.'.join(parts[:cut])} has no {exc.name!r} path"
            raise LookupError(f"{dotted}: {missing}") from None
    raise LookupError(f"{dotted}: no importable module")


def named_modules(text: str) -> list[ModuleType]:
    """The modules the document names, by path or by dotted name."""
    names = {module_of_path(span) for span in cited_paths(text)}
    for span in filter(_DOTTED.match, code_spans(text)):
        parts = span.removesuffix("()").split(".")
        names.update(".".join(parts[:cut]) for cut in range(1, len(parts) + 1))
    return [m for name in sorted(n for n in names if n) if (m := _import(name)) is not None]


def unresolved_dotted(text: str) -> list[str]:
    bad = []
    for span in filter(_DOTTED.match, code_spans(text)):
        try:
            resolve(span)
        except LookupError as exc:
            bad.append(str(exc))
    return bad


def unresolved_bare(text: str) -> list[str]:
    """Classes, ``Class.attribute``, ``function()``, CONSTANTS no named module has, and
    ``module.attribute`` the named module lacks."""
    modules = named_modules(text)
    by_last_name: dict[str, list[ModuleType]] = {}
    for module in modules:
        by_last_name.setdefault(module.__name__.rpartition(".")[2], []).append(module)
    bad = []
    for span in dict.fromkeys(code_spans(text)):
        parts = span.removesuffix("()").split(".")
        if _CLASS.match(span) or _CONSTANT.match(span) or _FUNCTION.match(span):
            if not any(_has_path(module, parts) for module in modules):
                bad.append(span)
        elif _MODULE_ATTRIBUTE.match(span) and not _DOTTED.match(span):
            candidates = by_last_name.get(parts[0], [])
            if candidates and not any(_has_path(m, parts[1:]) for m in candidates):
                bad.append(span)
    return bad


def _has_path(target: object, parts: list[str]) -> bool:
    try:
        functools.reduce(getattr, parts, target)
    except AttributeError:
        return False
    return True


def unmentioned_parts(text: str, root: Path = ROOT) -> list[str]:
    """Subpackages of limbctl and modules directly in it that the document never names."""
    cited = set(cited_paths(text))
    wanted = [
        f"{path.parent.relative_to(root).as_posix()}/"
        for path in sorted((root / "limbctl").rglob("__init__.py"))
        if path.parent != root / "limbctl"
    ]
    wanted += [f"limbctl/{path.name}" for path in sorted((root / "limbctl").glob("*.py"))]
    return [part for part in wanted if part not in cited]


def rank_table(text: str) -> dict[str, int]:
    return {layer: int(rank) for rank, layer in _RANK_ROW.findall(text)}


def broken_links(text: str, doc: Path = DOC) -> list[str]:
    """Relative links whose file (or ``#anchor`` heading) does not exist."""
    bad = []
    for target in _LINK.findall(_FENCE.sub("", text)):
        file_part, _, anchor = target.partition("#")
        path = (doc.parent / file_part) if file_part else doc
        if re.match(r"^[a-z]+://", target):
            bad.append(f"{target}: links outside the repository")
        elif not path.is_file() or (
            anchor and anchor not in _anchors(path.read_text(encoding="utf-8"))
        ):
            bad.append(target)
    return bad


def _anchors(markdown: str) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    return {
        re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        for heading in re.findall(r"^#+\s+(.+)$", _FENCE.sub("", markdown), re.M)
    }


# ---- the document against the code ------------------------------------------------------------
def test_the_document_matches_the_code():
    text = DOC.read_text(encoding="utf-8")
    assert cited_paths(text), "the document cites no paths: the checks see nothing"
    assert missing_paths(text) == [], "cited paths that do not exist"
    assert unmentioned_parts(text) == [], "limbctl parts the document never names"
    assert unresolved_dotted(text) == [], "dotted names that do not resolve"
    assert unresolved_bare(text) == [], "bare names no named module has"
    assert rank_table(text) == RANK, "the rank table is not tests/test_layers.py's RANK"
    assert broken_links(text) == [], "links that reach no file or heading"
    spans = set(code_spans(text))
    for registry in REGISTRIES:
        assert registry in spans, f"{registry} is not cited in {DOC.name}"
        assert isinstance(resolve(registry), (dict, tuple)), registry
    for outside in ("DESIGN" + ".md", "../" + "shared", "](/", "file://"):
        assert outside not in text, f"a reference outside the repository: {outside}"


# ---- the checks can fail ----------------------------------------------------------------------
STALE = """# Stale

| rank | layer | where |
|---|---|---|
| 0 | `errors` | `limbctl/errors.py` |
| 9 | `teleop` | `limbctl/teleop/` |

`limbctl/teleop/gate.py`, `limbctl/teleop/no_such_module.py`, `limbctl/data/`,
`limbctl.teleop.sources.NO_SUCH_REGISTRY`, `Gate.step()`, `Gate.no_such_method`, `NoSuchClass`,
`no_such_function()`, `NO_SUCH_CONSTANT`, `gate.NO_SUCH`, `gate.Gate`
([gone](no_such_doc.md), [no heading](region.md#no-such-heading)).
"""


def test_checks_report_a_stale_document():
    assert missing_paths(STALE) == ["limbctl/teleop/no_such_module.py", "limbctl/data/"]
    assert "limbctl/cli.py" in unmentioned_parts(STALE)
    assert "limbctl/teleop/sources/" in unmentioned_parts(STALE)
    assert len(unresolved_dotted(STALE)) == 1
    assert unresolved_bare(STALE) == [
        "Gate.no_such_method",
        "NoSuchClass",
        "no_such_function()",
        "NO_SUCH_CONSTANT",
        "gate.NO_SUCH",
    ]
    assert rank_table(STALE) != RANK
    assert broken_links(STALE) == ["no_such_doc.md", "region.md#no-such-heading"]
    for name in ("limbctl.teleop.sources.SOURCES", "limbctl.envelope.base.Envelope._registry"):
        assert resolve(name), f"resolve misses the real {name}"
