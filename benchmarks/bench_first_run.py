"""A new user's wait: record, train, teleop on a fresh clone, venv and home, first and second.

Run: ``.venv/bin/python benchmarks/bench_first_run.py --out docs/bench_first_run.md``
(``--rev REV`` measures another revision of this repository the same way, e.g. the one before a
change; ``--seconds`` is the teaching's length; ``--rig sim3`` runs every command on the
simulated three-servo rig, ``--library N`` adds a first fit from Python of N orientations, 0
leaves it out; ``--after-prepare``: that fit on both rigs, cold, then after ``limbctl prepare``).

Steps, each timed from outside (the wall time a person waits, Python's start included):

1. ``git clone`` this repository at ``--rev`` into a temporary folder, make a fresh venv there and
   ``pip install -e ".[test]"`` as the README says, with ``HOME`` a fresh empty folder (so no numba
   cache of any earlier run exists anywhere: ``NUMBA_CACHE_DIR`` and ``XDG_CACHE_HOME`` are unset).
2. As a user does: ``limbctl record`` (a teaching of ``--seconds`` on the embedded simulator),
   ``limbctl train``, ``limbctl teleop`` of two commands from stdin, each twice in a row: first and
   second run side by side.
3. Without anything compiled before: the kernel cache emptied, ``train`` first and second; emptied
   again, ``teleop`` first and second (with no train before it).
4. From Python (``--library N``): the cache emptied, a fresh process fits a Rigid Map to N
   orientations of the synthetic shoulder (``RigidMap(twist=True)`` on ``--rig sim3``, the same
   teaching's twist-free directions with ``RigidMap()`` on ``sim``), then a second process does it
   again: what a library user waits.

Each command runs under a probe that records numba's compile events (``numba:compile``): which
dispatchers compiled, how long each took with the compiles it started (inclusive) and without
them (self), and how many kernels were loaded from the cache. A background process a command
starts (the warm-up) compiles outside the probe: its work shows as kernels loaded later.
Timings are of one machine at one moment; the load average is printed beside them, and the ratios
(first / second) are what to compare between runs.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The probe each command runs under: numba's compile events, timed inclusive and self, written as
#: JSON to the file named by the first argument when the command ends.
PROBE = r"""
import atexit, json, sys, time
import numba.core.event as ev

compiles = []
stack = []

class Timer(ev.Listener):
    def on_start(self, event):
        stack.append([time.perf_counter(), 0.0])

    def on_end(self, event):
        start, inner = stack.pop()
        total = time.perf_counter() - start
        if stack:
            stack[-1][1] += total
        f = event.data["dispatcher"].py_func
        compiles.append({
            "name": f"{f.__module__}.{f.__qualname__}",
            "args": str(event.data["args"]),
            "total": total,
            "self": total - inner,
            "nested": bool(stack),
        })

ev.register("numba:compile", Timer())

def loaded():
    from numba.core.registry import CPUDispatcher
    hits = 0
    for name, module in list(sys.modules.items()):
        if name.startswith("limbctl") and module is not None:
            for value in vars(module).values():
                if isinstance(value, CPUDispatcher):
                    hits += sum(value.stats.cache_hits.values())
    return hits

def dump():
    with open(out, "w") as f:
        json.dump({"compiles": compiles, "loaded": loaded()}, f)

atexit.register(dump)
out = sys.argv[1]
sys.argv = ["limbctl", *sys.argv[2:]]
from limbctl.cli import main
sys.exit(main())
"""

#: What teleop is fed: two commands, the second far outside any taught region; a three-servo
#: rig's first also turns the limb about its axis.
COMMANDS = '{"pan": 20, "tilt": 10}\n{"pan": 120, "tilt": 80}\n'
COMMANDS3 = '{"pan": 20, "tilt": 10, "roll": 15}\n{"pan": 120, "tilt": 80}\n'
#: The simulated rigs: two servos, three.
RIGS = ("sim", "sim3")

#: A library user's fit (step 4): N orientations of the synthetic shoulder (its teaching mix:
#: half uniform, a quarter along the edge, a quarter at the twist stops), seed 0; prints the fit's
#: wall and CPU seconds (the process's start and import not included).
LIBRARY = r"""
import sys, time
import numba.core.event as ev
import numpy as np
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.geometry.quat import limb_direction, swing_from_direction
n, twist = int(sys.argv[1]), sys.argv[2] == "sim3"
q = ShoulderRegion().teaching(n - n // 2, n // 4, n // 4, np.random.default_rng(0))
if not twist:
    q = swing_from_direction(limb_direction(q))
compiled = []
class Count(ev.Listener):
    def on_start(self, event):
        pass
    def on_end(self, event):
        compiled.append(event.data["dispatcher"].py_func.__module__)
ev.register("numba:compile", Count())
start, cpu = time.perf_counter(), time.process_time()
RigidMap(seed=0, twist=twist).fit(q)
print(f"{time.perf_counter() - start:.3f} {time.process_time() - cpu:.3f} {len(compiled)}")
"""


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


#: Commands that talk to the simulated servos: on a machine too loaded for the simulator to keep
#: its reply deadlines one may fail on the bus ("did not answer", "kept DRIVE_MODE=..."); such
#: a run is tried again, up to TRIES times in all.
BUS_COMMANDS = ("record", "teleop")
TRIES = 3


def run(cmd, cwd: Path, env: dict, stdin: str | None = None) -> tuple[float, float, int]:
    """Run ``cmd``; returns its wall time and its CPU time (user + system, the processes it
    waited for included) in seconds, and the tries it took. Fails loudly with its output. The
    CPU time is what the compiler costs whatever else the machine runs; the wall time is what a
    person waits."""
    for tries in range(1, TRIES + 1):
        start, cpu = time.perf_counter(), _children_cpu()
        done = subprocess.run(cmd, cwd=cwd, env=env, input=stdin, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - start, _children_cpu() - cpu
        if done.returncode == 0:
            return wall, cpu, tries
        if not set(BUS_COMMANDS) & set(map(str, cmd)) or tries == TRIES:
            raise SystemExit(f"{' '.join(map(str, cmd))} failed:\n{done.stdout}\n{done.stderr}")
        for out in cmd:  # a record that failed leaves its file: the next try needs the name free
            if str(out).endswith(".limb") and Path(cwd, out).exists() and "record" in cmd:
                Path(cwd, out).unlink()
    raise AssertionError("unreachable")


def install(rev: str, work: Path) -> tuple[Path, dict, float]:
    """Clone at ``rev``, make a venv, install per the README; returns (clone, env, seconds)."""
    clone = work / "clone"
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "--quiet", rev], check=True)
    home = work / "home"
    home.mkdir()
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "PYTHONPATH", "VIRTUAL_ENV")
    }
    # pip's own download cache is not a limbctl cache: reuse it so the install does not download
    env["PIP_CACHE_DIR"] = os.environ.get("PIP_CACHE_DIR", str(Path.home() / ".cache" / "pip"))
    env["HOME"] = str(home)
    bin_dir = clone / ".venv" / "bin"
    env["PATH"] = f"{bin_dir}:{env.get('PATH', '/usr/bin:/bin')}"
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "venv", ".venv"], cwd=clone, check=True)
    subprocess.run(
        [str(bin_dir / "pip"), "install", "--quiet", "-e", ".[test]"],
        cwd=clone,
        env=env,
        check=True,
    )
    return clone, env, time.perf_counter() - start


def empty_caches(clone: Path, home: Path) -> None:
    """Remove every numba cache a run could have left: in the tree and under the home."""
    for path in clone.joinpath("limbctl").rglob("__pycache__"):
        for cached in [*path.glob("numba-*"), *path.glob("*.nbi"), *path.glob("*.nbc")]:
            shutil.rmtree(cached) if cached.is_dir() else cached.unlink()
    shutil.rmtree(home / ".cache" / "limbctl", ignore_errors=True)
    shutil.rmtree(home / ".cache" / "numba", ignore_errors=True)


#: What a recording's sampling was: its rate and its largest gaps (ms), from the file itself.
SAMPLING = r"""
import sys, numpy as np
from limbctl.teach.dataset import load_dataset
t = load_dataset(sys.argv[1]).t
gaps = 1000.0 * np.diff(t)
print(f"{(len(t) - 1) / (t[-1] - t[0]):.1f} Hz, gaps p99 {np.percentile(gaps, 99):.1f} ms, "
      f"largest {gaps.max():.1f} ms")
"""


def measure(clone: Path, env: dict, probe: Path, label: str, args: list[str], stdin=None) -> dict:
    log = clone / f"compiles-{label}.json"
    python = str(clone / ".venv" / "bin" / "python")
    wall, cpu, tries = run([python, str(probe), str(log), *args], clone, env, stdin)
    result = json.loads(log.read_text())
    result.update(label=label, wall=wall, cpu=cpu, tries=tries, note="")
    if args[0] == "record":
        result["note"] = subprocess.run(
            [python, "-c", SAMPLING, args[args.index("--out") + 1]],
            cwd=clone,
            env=env,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    return result


def scenario(
    clone: Path, env: dict, probe: Path, seconds: float, rig: str = "sim"
) -> dict[str, list[dict]]:
    """Every command first and second, in the order a user runs them, then from an empty cache;
    on the simulated rig ``rig`` (``sim``: two servos, ``sim3``: three)."""
    commands = COMMANDS3 if rig == "sim3" else COMMANDS

    def record(i):
        return ["record", "--rig", rig, "--out", f"teach-{i}.limb", "--duration", f"{seconds:g}"]

    def train(i):
        return ["train", "teach-1.limb", "--out", f"model-{i}.npz"]

    def teleop(i):
        # a three-servo recording may end, and its learned region leave, the limb a fraction of a
        # degree outside in twist: the servos drive it in (at 30 deg/s) rather than wait for a hand
        approach = ["--approach", "30"] if rig == "sim3" else []
        return ["teleop", "--rig", rig, "--model", "model-1.npz", "--source", "stdin", *approach]

    found: dict[str, list[dict]] = {}
    for name, args, stdin in (("record", record, ""), ("train", train, None)):
        found[name] = [measure(clone, env, probe, f"{name}-{i}", args(i), stdin) for i in (1, 2)]
    found["teleop"] = [
        measure(clone, env, probe, f"teleop-{i}", teleop(i), commands) for i in (1, 2)
    ]
    home = Path(env["HOME"])
    for name, args, stdin in (("train", train, None), ("teleop", teleop, commands)):
        empty_caches(clone, home)
        found[f"{name}, cache empty"] = [
            measure(clone, env, probe, f"{name}-cold-{i}", args(f"cold-{i}"), stdin) for i in (1, 2)
        ]
    return found


def library(clone: Path, env: dict, n: int, rig: str, empty: bool = True) -> list[dict]:
    """Step 4: the fit from Python in a fresh process from an empty cache (``empty``; else from
    the cache as it is), then in a second one; each its fit's seconds, its numba compiles, the
    process's wall and CPU seconds."""
    if empty:
        empty_caches(clone, Path(env["HOME"]))
    python = str(clone / ".venv" / "bin" / "python")
    found = []
    for _ in (1, 2):
        start, cpu = time.perf_counter(), _children_cpu()
        done = subprocess.run(
            [python, "-c", LIBRARY, str(n), rig],
            cwd=clone,
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        wall, cpu = time.perf_counter() - start, _children_cpu() - cpu
        fit, fit_cpu, compiles = done.stdout.split()[-3:]
        fits = {"fit": float(fit), "fit_cpu": float(fit_cpu), "compiles": int(compiles)}
        found.append({**fits, "wall": wall, "cpu": cpu})
    return found


def library_report(fits: list[dict], n: int, rig: str) -> list[str]:
    """The step 4 table."""
    first, second = fits
    kind = "RigidMap(twist=True)" if rig == "sim3" else "RigidMap()"
    return [
        "",
        f"From Python: `{kind}.fit` of {n} orientations (the synthetic shoulder, seed 0), a "
        "fresh process from an empty cache, then a second process:",
        "",
        "| | first (cache empty) | second | first / second |",
        "|---|---|---|---|",
        f"| the fit | {first['fit']:.2f} s | {second['fit']:.2f} s |"
        f" {first['fit'] / second['fit']:.1f} |",
        f"| the fit, CPU | {first['fit_cpu']:.2f} s | {second['fit_cpu']:.2f} s |"
        f" {first['fit_cpu'] / second['fit_cpu']:.1f} |",
        f"| the process (start, import, teaching, fit), wall | {first['wall']:.2f} s |"
        f" {second['wall']:.2f} s | {first['wall'] / second['wall']:.1f} |",
        f"| the same, CPU | {first['cpu']:.1f} s | {second['cpu']:.1f} s |"
        f" {first['cpu'] / second['cpu']:.1f} |",
    ]


def after_prepare(clone: Path, env: dict, n: int, probe: Path) -> dict:
    """``--after-prepare``: each rig's library fit from an empty cache (first, second); the
    cache emptied, ``limbctl prepare`` (timed), each rig's fit again; a three-servo ``record``
    (no warm-up: all is prepared), its ``train`` first and second."""
    found: dict = {"cold": {rig: library(clone, env, n, rig) for rig in RIGS}}
    empty_caches(clone, Path(env["HOME"]))
    found["prepare"] = run([str(clone / ".venv" / "bin" / "limbctl"), "prepare"], clone, env)
    found["prepared"] = {rig: library(clone, env, n, rig, empty=False) for rig in RIGS}
    record = ["record", "--rig", "sim3", "--out", "teach3.limb", "--duration", "30"]
    found["record"] = measure(clone, env, probe, "record3", record, "")
    train = ["train", "teach3.limb", "--out"]
    found["train"] = [measure(clone, env, probe, f"t3-{i}", [*train, f"{i}.npz"]) for i in (1, 2)]
    return found


def after_prepare_report(found: dict, rev: str, install_s: float, load: tuple, n: int) -> str:
    """The ``--after-prepare`` tables."""
    prepare, record, (first, second) = found["prepare"], found["record"], found["train"]
    ours = [sum(limbctl_kernel(c["name"]) for c in r["compiles"]) for r in (record, first)]
    helpers = [len(r["compiles"]) - k for r, k in zip((record, first), ours, strict=True)]
    lines = [
        "# The first fit from Python after `limbctl prepare`",
        "",
        "Reproduce: `.venv/bin/python benchmarks/bench_first_run.py --out docs/bench_first_run.md"
        f" --rev {rev} --after-prepare --library {n}`. Revision `{rev}`; install (`pip install -e"
        f' ".[test]"` into a fresh venv, fresh HOME) {install_s:.0f} s; load average {load[0]}'
        f" before, {load[1]} after (2 cores, shared). `limbctl prepare` (both rigs, from an empty"
        f" cache): {prepare[0]:.1f} s wall, {prepare[1]:.1f} s CPU.",
        "",
        f"A library fit of {n} orientations (the synthetic shoulder, seed 0; the two-servo fit its"
        " directions) in a fresh process, then a second; compiles: numba's, in the first fit.",
        "",
        "| rig, fit | cache before the first | the fit, wall: first / second (ratio) |"
        " the fit, CPU | the process, CPU | compiles first |",
        "|---|---|---|---|---|---|",
    ]
    times = ("fit", "fit_cpu", "cpu")  # the table's columns
    for rig in RIGS:
        kind = "RigidMap(twist=True)" if rig == "sim3" else "RigidMap()"
        for key, cache in (("cold", "empty"), ("prepared", "after `limbctl prepare`")):
            one, two = found[key][rig]
            cells = [f"{one[k]:.2f} / {two[k]:.2f} s ({one[k] / two[k]:.1f})" for k in times]
            lines.append(
                f"| {rig} `{kind}.fit` | {cache} | {' | '.join(cells)} | {one['compiles']} |"
            )
    lines += [
        "",
        "Then `limbctl record --rig sim3 --duration 30` (no warm-up starts: all is prepared) "
        f"compiled {ours[0]} limbctl kernels + {helpers[0]} helpers ({record['note']}); its "
        f"`limbctl train`, first / second: {first['wall']:.2f} / {second['wall']:.2f} s wall "
        f"({first['wall'] / second['wall']:.1f}), {first['cpu']:.1f} / {second['cpu']:.1f} s CPU "
        f"({first['cpu'] / second['cpu']:.1f}); the first compiled {ours[1]} + {helpers[1]}.",
    ]
    return "\n".join(lines) + "\n"


def limbctl_kernel(name: str) -> bool:
    return name.startswith("limbctl.")


def report(
    found: dict[str, list[dict]],
    rev: str,
    install_s: float,
    load: tuple,
    rig: str = "sim",
    fits: tuple[int, list[dict]] | None = None,
) -> str:
    lines = [
        f"# First run: record, train, teleop on a fresh clone, venv and home (`--rig {rig}`)",
        "",
        "Reproduce: `.venv/bin/python benchmarks/bench_first_run.py --out docs/bench_first_run.md"
        f" --rev {rev} --rig {rig}"
        + (f" --library {fits[0]}" if fits else " --library 0")
        + (" --library-only`." if fits and not found else "`."),
        f'Revision `{rev}`; install (`pip install -e ".[test]"` into a fresh venv) '
        f"{install_s:.0f} s; load average {load[0]} before, {load[1]} after (2 cores, shared).",
    ]
    lines += (
        []
        if not found
        else [
            "",
            "| command | first run | second run | first / second | CPU first, second (s) |"
            " compiled first: limbctl kernels + numba's helpers | compile s (top level) |"
            " loaded from cache first |",
            "|---|---|---|---|---|---|---|---|",
        ]
    )
    for name, (first, second) in found.items():
        ours = sum(limbctl_kernel(c["name"]) for c in first["compiles"])
        helpers = len(first["compiles"]) - ours
        compile_s = sum(c["total"] for c in first["compiles"] if not c["nested"])
        lines.append(
            f"| {name} | {first['wall']:.2f} s | {second['wall']:.2f} s | "
            f"{first['wall'] / second['wall']:.1f} | {first['cpu']:.1f}, {second['cpu']:.1f} |"
            f" {ours} + {helpers} | {compile_s:.2f} |"
            f" {first['loaded']} |"
        )
    retried = [f"{r['label']} ({r['tries']} tries)" for runs in found.values() for r in runs]
    retried = [text for text in retried if not text.endswith("(1 tries)")]
    if retried:
        again = "Tried again after a bus failure of the simulated servos under load: "
        lines += ["", again + ", ".join(retried)]
    if found:
        lines += ["", "Sampling of the recordings (the first ran beside the warm-up):", ""]
        lines += [f"- record {i}: {run_['note']}" for i, run_ in enumerate(found["record"], 1)]
    if fits:
        lines += library_report(fits[1], fits[0], rig)
    for name, (first, _) in found.items():
        if not first["compiles"]:
            continue
        lines += [
            "",
            f"## {name}, first run: each compile, largest first",
            "",
            "| dispatcher | signature | with its compiles (s) | alone (s) |",
            "|---|---|---|---|",
        ]
        for c in sorted(first["compiles"], key=lambda c: -c["total"]):
            args = c["args"] if len(c["args"]) < 60 else c["args"][:57] + "..."
            lines.append(f"| `{c['name']}` | `{args}` | {c['total']:.2f} | {c['self']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rev", default="HEAD", help="revision of this repository to measure")
    parser.add_argument("--seconds", type=float, default=30.0, help="teaching length (s)")
    parser.add_argument("--out", type=Path, help="write the Markdown report here")
    parser.add_argument("--keep", action="store_true", help="keep the temporary folder")
    parser.add_argument(
        "--rig", default="sim", choices=("sim", "sim3"), help="simulated rig (sim3: three servos)"
    )
    parser.add_argument(
        "--library",
        type=int,
        default=8000,
        help="orientations of the fit from Python, a fresh process from an empty cache and a "
        "second one (0: leave it out)",
    )
    parser.add_argument(
        "--library-only",
        action="store_true",
        help="measure only the fit from Python (step 4), not record, train and teleop",
    )
    parser.add_argument(
        "--after-prepare",
        action="store_true",
        help="both rigs' fit from Python, from an empty cache, then after `limbctl prepare`",
    )
    options = parser.parse_args()
    rev = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", options.rev],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    work = Path(tempfile.mkdtemp(prefix="bench_first_run_"))
    try:
        before = os.getloadavg()
        clone, env, install_s = install(rev, work)
        # alone in its folder: python puts the script's folder first on sys.path
        probe = work / "probe" / "probe.py"
        probe.parent.mkdir()
        probe.write_text(PROBE)
        if options.after_prepare:
            done = after_prepare(clone, env, options.library, probe)
            loads = tuple(f"{x[0]:.1f}" for x in (before, os.getloadavg()))
            text = after_prepare_report(done, rev, install_s, loads, options.library)
        else:
            found = {}
            if not options.library_only:
                found = scenario(clone, env, probe, options.seconds, options.rig)
            fits = None
            if options.library > 0:
                fits = (options.library, library(clone, env, options.library, options.rig))
            after = os.getloadavg()
            loads = (f"{before[0]:.1f}", f"{after[0]:.1f}")
            text = report(found, rev, install_s, loads, options.rig, fits)
    finally:
        if options.keep:
            print(f"kept {work}", file=sys.stderr)
        else:
            shutil.rmtree(work, ignore_errors=True)
    print(text)
    if options.out:
        options.out.write_text(text)


if __name__ == "__main__":
    main()
