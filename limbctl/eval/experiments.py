"""`limbctl eval`: the seed papers' experiments, side by side with the gate, as CSV, tables, plots.
A task (one data set, every model trained on it) runs in a worker, appending its rows to
``runs.csv``; a rerun into the same ``--out`` skips tasks already there."""

from __future__ import annotations

import csv
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

from limbctl.envelope import Cone, model_class
from limbctl.envelope import interpolation as ip
from limbctl.envelope.synthetic import ConeRegion, to_quaternions
from limbctl.errors import ConfigError
from limbctl.eval.grids import DataSpec, ModelSpec, Task, build_tasks
from limbctl.eval.metrics import METRIC_NAMES, score
from limbctl.geometry.quat import swing_angle

#: Columns of runs.csv, in order.
CSV_FIELDS = (*"task grid experiment x_name x seed model answer k subset".split(), *METRIC_NAMES)
CSV_FIELDS += ("fit_seconds",)

_NO_TOPOLOGY = np.empty((0, 0), dtype=np.int64)


def draw_training(data: DataSpec, rng: np.random.Generator) -> np.ndarray:
    """Valid twist-free training orientations (patterns, 4) in the cone of ``range_deg``, the band
    (swing in (R/2, R]) ``boundary_ratio`` times as dense as the central cap."""
    radius = np.radians(data.range_deg)
    cone = ConeRegion(radius)
    if data.boundary_ratio == 1.0:
        return to_quaternions(cone.sample(data.patterns, rng))
    inner = 0.5 * radius
    # cap areas are proportional to 1 - cos(angle)
    area_centre = 1.0 - np.cos(inner)
    area_band = np.cos(inner) - np.cos(radius)
    share_band = data.boundary_ratio * area_band / (data.boundary_ratio * area_band + area_centre)
    n_band = int(round(data.patterns * share_band))
    centre = ConeRegion(inner).sample(data.patterns - n_band, rng)
    band = np.empty((0, 3))
    while len(band) < n_band:
        candidates = cone.sample(2 * n_band, rng)
        band = np.vstack([band, candidates[candidates[:, 0] < np.cos(inner)]])
    directions = np.vstack([centre, band[:n_band]])
    return to_quaternions(directions[rng.permutation(len(directions))])


def draw_test(data: DataSpec, rng: np.random.Generator) -> np.ndarray:
    """Test orientations (test_patterns, 4), twist-free, spread as ``data.test_spread`` says."""
    if data.test_spread == "sphere":
        # uniform on the sphere: normalised Gaussian 3-vectors
        d = rng.normal(size=(data.test_patterns, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    elif data.test_spread == "around":
        d = ConeRegion(np.radians(data.range_deg)).test_directions(data.test_patterns, rng)
    else:
        raise ConfigError(f"unknown test_spread {data.test_spread!r}; choose sphere or around")
    return to_quaternions(d)


def build_model(spec: ModelSpec, seed: int, range_deg: float) -> Any:
    """A fresh, untrained model for ``spec`` (the cone is the exact truth of ``range_deg``)."""
    kind = model_class(spec.kind)  # an unknown kind is refused with the list of choices
    options = dict(spec.options)
    if "seed" in kind.settable:
        options["seed"] = seed
    if kind is Cone:
        options["half_angle"] = np.radians(range_deg)
    return kind(**options)


def respond_on_data_nodes(model: Any, q: np.ndarray, interpolation: str, k: int) -> np.ndarray:
    """The papers' answers (N, 4) to ``q`` (N, 4) over a fitted Rigid Map's ``support_weights``."""
    weights = np.ascontiguousarray(model.support_weights, dtype=np.float64)
    mode = ip.interpolation_code(interpolation)
    return ip.respond_batch(weights, q, max(k, 1), ip.EUCLIDEAN, mode, _NO_TOPOLOGY)


def run_task(task: Task) -> list[dict[str, Any]]:
    """Draw the task's data, train each model, score each answer; one row per subset."""
    rng = np.random.default_rng(task.seed)
    train = draw_training(task.data, rng)
    test = draw_test(task.data, rng)
    truth = Cone(np.radians(task.data.range_deg))
    ideal = truth.correct(test)
    valid = truth.contains(test)
    rows = []
    for spec in task.models:
        start = time.perf_counter()
        model = build_model(spec, task.seed, task.data.range_deg).fit(train)
        fit_seconds = time.perf_counter() - start
        for answer in spec.answers:
            if answer.how == "correct":
                out = model.correct(test)
            elif answer.how == "data-nodes":
                out = respond_on_data_nodes(model, test, answer.interpolation, answer.k)
            else:
                out = model.respond(test, interpolation=answer.interpolation, k=max(answer.k, 1))
            # how far outside the cone an answer lies: max(swing angle - R, 0)
            outside = np.degrees(np.maximum(swing_angle(out) - truth.half_angle, 0.0))
            scores = score(test, out, ideal, valid, truth.contains(out), outside)
            x = answer.k if task.x_from_k else task.x
            head = (task.key, task.grid, task.experiment, task.x_name, x, task.seed, spec.label)
            for subset, values in scores.items():
                row = dict(zip(CSV_FIELDS, (*head, answer.label, answer.k, subset), strict=False))
                rows.append({**row, **values, "fit_seconds": round(fit_seconds, 4)})
    return rows


def _worker_init() -> None:
    """One numba thread per worker process: the pool already fills the cores."""
    import numba

    numba.set_num_threads(1)


def read_rows(csv_path: Path) -> list[dict[str, Any]]:
    """Rows of a runs.csv (numbers as float, text as str); [] when the file does not exist."""
    if not csv_path.exists():
        return []
    text_fields = {"task", "grid", "experiment", "x_name", "model", "answer", "subset"}
    with open(csv_path, newline="") as fh:
        return [
            {k: v if k in text_fields else float(v) for k, v in raw.items()}
            for raw in csv.DictReader(fh)
        ]


def run_tasks(
    tasks: list[Task], csv_path: Path, jobs: int = 0, progress: bool = True
) -> list[dict[str, Any]]:
    """Run the tasks not yet in ``csv_path`` in ``jobs`` workers (0: one per core, 1: here),
    appending each one's rows as it finishes; returns every task's rows in CSV order."""
    from tqdm import tqdm

    wanted = {t.key for t in tasks}
    done = {row["task"] for row in read_rows(csv_path)}
    todo = [t for t in tasks if t.key not in done]
    jobs = (os.cpu_count() or 1) if jobs == 0 else jobs
    if jobs < 0:
        raise ConfigError(f"--jobs must be >= 0 (0 = one per core), got {jobs}")
    new_file = not csv_path.exists()
    shown = {"initial": len(tasks) - len(todo), "disable": not progress, "unit": "task"}
    with open(csv_path, "a", newline="") as fh, tqdm(total=len(tasks), desc="eval", **shown) as bar:
        writer = csv.DictWriter(fh, fieldnames=CSV_FIELDS)
        if new_file:
            writer.writeheader()

        def record(rows: list[dict[str, Any]]) -> None:
            writer.writerows(rows)
            fh.flush()
            bar.update(1)

        if jobs == 1 or len(todo) <= 1:
            for task in todo:
                record(run_task(task))
        else:
            # spawn, not fork: numba's OpenMP threads in this process do not survive a fork
            context = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(jobs, context, initializer=_worker_init) as pool:
                futures = [pool.submit(run_task, task) for task in todo]
                for future in as_completed(futures):
                    record(future.result())
    return [row for row in read_rows(csv_path) if row["task"] in wanted]


def run_eval(
    out: Path, quick: bool = False, jobs: int = 0, progress: bool = True, smoke: bool = False
) -> int:
    """`limbctl eval` into ``out`` (a rerun resumes); 1 when the SOM reproduction failed, else 0."""
    from limbctl.eval import plots as eval_plots
    from limbctl.eval.twist import run_twist

    scale = "smoke" if smoke else "quick" if quick else "full"
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    rows = run_tasks(build_tasks(scale), out / "runs.csv", jobs=jobs, progress=progress)
    table = eval_plots.aggregate(rows)
    figures = eval_plots.draw_all(table, out)
    summary = eval_plots.summary_markdown(table, scale)
    (out / "summary.md").write_text(summary.text)
    headline = [*summary.headline, *run_twist(out, scale)]
    elapsed = time.perf_counter() - started
    print(f"limbctl eval ({scale}): {len(rows)} rows in {elapsed:.1f} s -> {out}")
    for line in headline:
        print(f"  {line}")
    for path in figures:
        print(f"  figure {path}")
    return 0 if summary.reproduction_ok is not False else 1
