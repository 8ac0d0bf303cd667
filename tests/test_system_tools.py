"""tests/system_tools.py: a test run installs the programs its browser and terminal tests drive,
or says in one line what to install and those tests skip (programs hidden by a bare ``PATH``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from tests import system_tools

ROOT = Path(__file__).resolve().parents[1]


def bare_path(tmp_path: Path, keep: tuple[str, ...] = ()) -> str:
    """A PATH of one folder holding links to ``keep`` (programs found on this machine's PATH)."""
    folder = tmp_path / "bin"
    folder.mkdir(exist_ok=True)
    for name in keep:
        (folder / name).symlink_to(shutil.which(name))
    return str(folder)


def test_every_program_is_found_on_this_machine():
    # the suite's own machine has them (installed by the session start when it may)
    assert system_tools.missing() == []
    assert system_tools.packages(["tmux"]) == ["tmux"], "packages name each once"
    assert system_tools.packages(["chromium", "chromedriver"]) == ["chromium", "chromium-driver"]


def test_without_root_or_after_a_failed_install_one_line_says_what_to_install(tmp_path):
    said = []
    line = system_tools.ensure(path=bare_path(tmp_path), root=False, say=said.append)
    assert said == [line]
    assert "\n" not in line
    assert "chromium, chromedriver, tmux not found" in line
    assert "apt-get install chromium chromium-driver tmux" in line
    # as root, a failed install ends in the one line with its reason
    failed = subprocess.CompletedProcess([], 100, "", "E: Unable to locate package chromium")
    said = []
    path = bare_path(tmp_path)
    line = system_tools.ensure(path=path, root=True, install=lambda _: failed, say=said.append)
    assert said[-1] == line and len(said) == 2  # the progress line, then the one line
    assert "installing them failed (E: Unable to locate package chromium)" in line


def test_as_root_it_installs_the_missing_packages_once_with_a_progress_line(tmp_path):
    path = bare_path(tmp_path, keep=("chromium",))
    asked = []

    def install(names):
        # what apt-get does, into the PATH the check reads: the programs appear
        asked.append(list(names))
        for name in names:
            (Path(path) / name).symlink_to(shutil.which(name))
        return subprocess.CompletedProcess([], 0, "", "")

    said = []
    assert system_tools.ensure(path=path, root=True, install=install, say=said.append) is None
    assert asked == [["chromedriver", "tmux"]]
    assert len(said) == 1 and "installing chromium-driver tmux with apt-get" in said[0]
    # a second run finds them: nothing installed, nothing said
    assert system_tools.ensure(path=path, root=True, install=install, say=said.append) is None
    assert len(asked) == 1 and len(said) == 1


BROWSER_TEST = """
from tests.view.browser import chromium
from tests.teleop.tmux import tmux_pane

def test_page():
    with chromium():
        pass

def test_terminal():
    with tmux_pane("true"):
        pass

def test_other():
    assert True
"""


def run_hidden(tree: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    """``python -m pytest -q`` of BROWSER_TEST with tests/conftest.py of ``tree``, as a user who
    may not install: a PATH without the programs (and without apt-get)."""
    (tmp_path / "test_tools_needed.py").write_text(BROWSER_TEST)
    path = bare_path(tmp_path, keep=("env", "sh"))
    return subprocess.run(
        [sys.executable, *"-m pytest -q -p tests.conftest -p no:cacheprovider -ra".split()]
        + ["--rootdir", str(tmp_path), str(tmp_path / "test_tools_needed.py")],
        cwd=tree,
        env={**os.environ, "PATH": path, "PYTHONPATH": str(tree)},
        capture_output=True,
        text=True,
    )


def test_a_run_without_the_programs_and_root_skips_their_tests_with_the_line(tmp_path):
    done = run_hidden(ROOT, tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 passed, 2 skipped" in done.stdout, done.stdout
    line = "limbctl tests: chromium, chromedriver, tmux not found"
    said = [text for text in done.stdout.splitlines() if text.startswith(line)]
    assert len(said) == 1, done.stdout  # said once at the start; the skips give it as reason
    assert sum(line in text for text in done.stdout.splitlines() if "SKIPPED" in text) >= 1
