"""The README and docs/ cite paths that exist and ``tests/....py::test_name`` tests that are
defined there."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")])
#: A repository path: one of the top-level folders, then path characters; ``::name`` optional.
CITED_PATH = re.compile(
    r"(?<![\w/.])((?:tests|limbctl|benchmarks|docs|firmware_sim|calib|examples)/[\w./-]*\w)"
    r"(?:::(\w+))?"
)


def citations(document: Path) -> list[tuple[int, str, str | None]]:
    """(line number, path, test name or None) for every repository path ``document`` cites."""
    found = []
    for number, line in enumerate(document.read_text(encoding="utf-8").splitlines(), 1):
        for match in CITED_PATH.finditer(line):
            found.append((number, match.group(1), match.group(2)))
    return found


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_cited_paths_and_tests_exist(document):
    missing = []
    for number, path, name in citations(document):
        target = ROOT / path
        if not target.exists():
            missing.append(f"line {number}: {path} does not exist")
        elif name and target.suffix == ".py":
            source = target.read_text(encoding="utf-8")
            if not re.search(rf"^\s*(?:async )?def {name}\(|^class {name}\b", source, re.M):
                missing.append(f"line {number}: {path} defines no {name}")
    assert not missing, "\n".join(missing)


def test_the_pattern_finds_paths_and_test_names():
    line = "see `tests/teach/test_dataset.py::test_preflight_checks` and docs/safety.md."
    found = [(m.group(1), m.group(2)) for m in CITED_PATH.finditer(line)]
    assert found == [
        ("tests/teach/test_dataset.py", "test_preflight_checks"),
        ("docs/safety.md", None),
    ]
