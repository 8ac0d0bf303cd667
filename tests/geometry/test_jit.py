"""limbctl.geometry.jit: caching never stale across files, and no crash without a cache; the
subprocesses run a copy of the package, as a new install would be."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from limbctl.geometry import jit
from limbctl.region import correct_kernels as ck
from limbctl.region.mesh import DirectionMesh
from tests.region.support import circle

ROOT = Path(__file__).resolve().parents[2]
#: A command 10 deg of pan from rest: inside the test's 20 deg cap.
QUATERNION = np.array([np.cos(np.radians(5.0)), 0.0, 0.0, np.sin(np.radians(5.0))])

#: The child prints the corrected inside command and numba's cache hits and misses.
CHILD = """
import sys
import numpy as np
from limbctl.region import correct_kernels as ck
args = np.load(sys.argv[1])
arrays = [args[f"a{i}"] for i in range(len(args.files))]
q = np.array([0.9961946980917455, 0.0, 0.0, 0.08715574274765817])  # QUATERNION
out, status = ck.correct_single(q, *arrays)
stats = ck.correct_single.stats
print(repr(out.tolist()), status, sum(stats.cache_hits.values()), sum(stats.cache_misses.values()))
"""


def _package_copy(into: Path) -> Path:
    """A copy of limbctl (sources only, no compiled caches) under ``into``; returns ``into``."""
    shutil.copytree(
        ROOT / "limbctl", into / "limbctl", ignore=shutil.ignore_patterns("__pycache__")
    )
    return into


def _env(home: Path, path: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    env.update(HOME=str(home), PYTHONPATH=str(path), PYTHONDONTWRITEBYTECODE="1")
    return env


def _python(argv, env, cwd, prefix=(), check=False):
    """``python -c *argv`` (after ``prefix``) in ``cwd``, which ``-c`` puts first on sys.path."""
    command = [*prefix, sys.executable, "-c", *argv]
    return subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True, check=check)


def _run(tree: Path, home: Path, args: Path) -> tuple[list[float], int, int, int]:
    """The child's answer, status, cache hits and misses."""
    done = _python([CHILD, str(args)], _env(home, tree), tree, check=True)
    out, status, hits, misses = done.stdout.strip().rsplit(" ", 3)
    return eval(out), int(status), int(hits), int(misses)  # noqa: S307 - our own child's repr


def test_editing_an_inlined_kernel_in_another_file_changes_the_answer(tmp_path):
    """mesh_kernels.query, inlined into correct_single: edited, the cached kernel is not used."""
    tree = _package_copy(tmp_path / "tree")
    args = tmp_path / "args.npz"  # the kernel arrays of a 20 deg cap about +x
    cap = DirectionMesh.from_loops([circle(20.0, 120)], 0.0).kernel_args()
    np.savez(args, **{f"a{i}": a for i, a in enumerate(cap)})
    first = _run(tree, tmp_path, args)
    again = _run(tree, tmp_path, args)
    assert first[1] == 1 and first[3] == 1, first  # inside; compiled
    assert again == (first[0], 1, 1, 0), again  # the same answer, loaded from the cache
    # the edited query calls every direction outside: the inside command now comes back corrected
    mesh = tree / "limbctl" / "region" / "mesh_kernels.py"
    source = mesh.read_text(encoding="utf-8")
    edits = {
        "    if deep[cell]:\n        return True\n": "    if deep[cell]:\n        return False\n",
        "    if in_mesh or best <= CONTAIN_TOLERANCE:\n        return True\n": (
            "    if in_mesh or best <= CONTAIN_TOLERANCE:\n        return False\n"
        ),
    }
    for old, new in edits.items():
        assert source.count(old) == 1, old
        source = source.replace(old, new)
    mesh.write_text(source, encoding="utf-8")
    edited = _run(tree, tmp_path, args)
    assert edited[1:] == (0, 0, 1), edited  # the edited answer, compiled anew, nothing loaded
    # the unedited child answered as this process's kernels do
    arrays = np.load(args)
    here = ck.correct_single(QUATERNION, *[arrays[f"a{i}"] for i in range(len(arrays.files))])
    assert first[0] == here[0].tolist() and first[1] == here[1]


def test_the_key_names_the_folders_and_every_kernel_is_under_it(monkeypatch):
    key = jit.source_key()
    assert re.fullmatch(rf"[0-9a-f]{{{jit.KEY_DIGITS}}}", key)
    assert all(key in folder.name for folder in jit.cache_candidates())
    assert jit.cache_dir() in jit.cache_candidates()
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere")
    assert jit.cache_candidates()[0] == Path("/somewhere") / f"limbctl-{jit.source_key()}"
    # numba.njit elsewhere, or a kernel outside KERNEL_PACKAGES, would escape the key
    offenders = []
    for path in (ROOT / "limbctl").rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        if path == Path(jit.__file__):
            continue
        if re.search(r"\b(?:nb|numba)\.(?:njit|jit|vectorize|guvectorize|cfunc)\b", text):
            offenders.append(f"{path.relative_to(ROOT)}: calls numba's decorator itself")
        uses = "from limbctl.geometry.jit import njit" in text
        package = path.relative_to(ROOT / "limbctl").parts[0]
        if uses and package not in jit.KERNEL_PACKAGES:
            offenders.append(f"{path.relative_to(ROOT)}: a kernel outside {jit.KERNEL_PACKAGES}")
    assert not offenders, offenders


def _unprivileged() -> list[str]:
    """A command prefix that runs the child as a user file permissions apply to (not root)."""
    if os.geteuid() != 0:
        return []
    prefix = ["unshare", "--user", "--map-user=1000", "--map-group=1000"]
    probe = subprocess.run([*prefix, "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip("root without user namespaces: permissions cannot be made to bite")
    return prefix


def test_a_read_only_install_with_an_unwritable_home_compiles_in_memory_and_says_so_once():
    # not pytest's tmp_path: its parent is private to root, and the child runs as another user
    with tempfile.TemporaryDirectory(prefix="limbctl_ro_") as tmp:
        tree = _package_copy(Path(tmp) / "tree")
        home = Path(tmp) / "home"
        home.mkdir()
        for folder in [home, *(p for p in tree.rglob("*") if p.is_dir()), tree]:
            folder.chmod(0o555)
        Path(tmp).chmod(0o755)
        child = (
            "import numpy as np\n"
            "import limbctl.envelope, limbctl.region\n"  # every kernel module, decorated
            "from limbctl.region import mesh_kernels as m\n"
            "print(m._angle(np.array([1.0, 0, 0]), np.array([0.0, 1, 0])))\n"
            "print(m._angle(np.array([1.0, 0, 0]), np.array([0.0, 0, 1])))\n"
        )
        try:
            done = _python([child], _env(home, tree), tree, _unprivileged())
        finally:
            for folder in [Path(tmp), home, tree, *(p for p in tree.rglob("*") if p.is_dir())]:
                folder.chmod(0o755)
        assert done.returncode == 0, done.stderr
        assert [float(x) for x in done.stdout.split()] == [np.pi / 2, np.pi / 2]
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and "no writable folder" in lines[0], done.stderr
        assert "NUMBA_CACHE_DIR" in lines[0] and str(home) in lines[0]
        assert not list(tree.rglob("*.nbi")) and not list(home.rglob("*"))


def test_a_drop_in_for_numbas_njit_in_every_form(tmp_path):
    """Bare, with options, eager (that signature only), and without a source file (in memory)."""
    (tmp_path / "kernels_here.py").write_text(
        "from limbctl.geometry.jit import njit\n"
        "@njit('f8(f8)')\n"
        "def eager(x):\n    return 2.0 * x\n"
        "@njit\n"
        "def bare(x):\n    return x + 1\n"
        "@njit(inline='always', cache=False)\n"
        "def inlined(x):\n    return bare(x) - 2\n"
    )
    child = (
        "import kernels_here as k\n"
        "from limbctl.geometry.jit import njit\n"
        "print(k.eager(2.0), k.bare(1), k.inlined(3), len(k.eager.signatures))\n"
        "try:\n    k.eager(1j)\nexcept TypeError:\n    print('eager only')\n"
        "print(njit(lambda x: 3 * x)(2))\n"
    )
    env = {**_env(tmp_path, ROOT), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{tmp_path}"
    done = _python([child], env, tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:3] == ["4.0 2 2 1", "eager only", "6"]
    assert list((tmp_path / "cache").rglob("kernels_here.bare-*.nbi"))
