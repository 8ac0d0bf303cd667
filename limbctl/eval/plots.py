"""Tables and figures of `limbctl eval`: seed-averaged points, the papers' Figure 2 panels beside
the gate, and a markdown summary with the reproduction check."""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from limbctl.eval.metrics import METRIC_NAMES, mean_and_spread

#: The SOM paper's one published number: 900 nodes, 5000 patterns, 90 degrees -> 3D error.
PAPER_SOM_ERR3D = 5.63e-2
#: Band our SOM's RMS end-point error must land in at that setting.
REPRODUCTION_BAND = (0.035, 0.08)

#: (experiment, panel title, x-axis label) of the SOM paper's Figure 2, in its order.
SOM_PANELS = (
    ("som-range", "(a) range of the constraint", "range R (deg)"),
    ("som-patterns", "(b) training patterns", "training patterns"),
    ("som-nodes", "(c) output nodes", "output nodes"),
    ("som-ratio", "(d) boundary/central pattern density", "boundary:central density ratio"),
)

#: Columns of the markdown tables: (metric, header, format).
TABLE_COLUMNS = (
    ("mse", "quat MSE", "{:.3g}"),
    ("err3d_rms", "3D err (RMS)", "{:.4f}"),
    ("angle_mean_deg", "mean angle (deg)", "{:.2f}"),
    ("angle_p95_deg", "p95 angle (deg)", "{:.2f}"),
    ("unchanged_share", "unchanged", "{:.3f}"),
    ("inside_share", "inside true region", "{:.3f}"),
    ("outside_p95_deg", "p95 outside (deg)", "{:.2f}"),
)


@dataclass
class Point:
    """One (experiment, model, answer, x, subset) averaged over seeds: metric -> (mean, sd)."""

    experiment: str
    x_name: str
    x: float
    model: str
    answer: str
    subset: str
    seeds: int
    values: dict[str, tuple[float, float]]

    @property
    def series(self) -> str:
        return f"{self.model}: {self.answer}"


def aggregate(rows: list[dict[str, Any]]) -> list[Point]:
    """Average rows over seeds: mean and sample standard deviation of every metric."""
    groups: dict[tuple, list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        key = (row["experiment"], row["x_name"], float(row["x"]), row["model"], row["answer"])
        groups[key + (row["subset"],)].append(row)
    points = [
        Point(*key, len(group), {m: mean_and_spread([r[m] for r in group]) for m in METRIC_NAMES})
        for key, group in groups.items()
    ]
    return sorted(points, key=lambda p: (p.experiment, p.model, p.answer, p.subset, p.x))


def select(points: list[Point], experiment: str, subset: str = "all", **match: Any) -> list[Point]:
    """The points of one experiment and subset (optionally also matching model/answer/x)."""
    return [
        p
        for p in points
        if p.experiment == experiment
        and p.subset == subset
        and all(getattr(p, k) == v for k, v in match.items())
    ]


def series_of(points: list[Point]) -> dict[str, list[Point]]:
    """Group points by ``model: answer`` keeping x order."""
    out: dict[str, list[Point]] = defaultdict(list)
    for p in points:
        out[p.series].append(p)
    return {name: sorted(ps, key=lambda p: p.x) for name, ps in out.items()}


def _style(series: str) -> dict[str, Any]:
    """Paper networks solid, their threshold/gate answers dashed, the gate thick."""
    if "correct" in series:
        width = 2.4 if series.startswith(("gate", "RigidMap")) else 1.4
        return {"linestyle": "--", "linewidth": width, "marker": "s", "markersize": 3}
    return {"linestyle": "-", "linewidth": 1.3, "marker": "o", "markersize": 3}


def _panel(ax, points: list[Point], metric: str, title: str, xlabel: str, ylabel: str) -> None:
    for name, ps in series_of(points).items():
        xs = [p.x for p in ps]
        mean = [p.values[metric][0] for p in ps]
        sd = [p.values[metric][1] for p in ps]
        if len(xs) == 1:
            ax.axhline(
                mean[0], label=name, **{k: v for k, v in _style(name).items() if "marker" not in k}
            )
            continue
        ax.errorbar(xs, mean, yerr=sd, label=name, capsize=2, **_style(name))
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(xlabel, fontsize=8)
    ax.set_ylabel(ylabel, fontsize=8)
    ax.tick_params(labelsize=7)
    if points and all(
        p.values[metric][0] > 0 for p in points if math.isfinite(p.values[metric][0])
    ):
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6)


def draw_som_figure(points: list[Point], path: Path) -> Path:
    """The SOM paper's Figure 2 (a)-(d), quaternion MSE on top and 3D error below."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(18, 8.5))
    for col, (experiment, title, xlabel) in enumerate(SOM_PANELS):
        pts = select(points, experiment)
        _panel(axes[0, col], pts, "mse", f"SOM paper Fig. 2{title}", xlabel, "quaternion MSE")
        _panel(axes[1, col], pts, "err3d_rms", title, xlabel, "3D error of a unit limb (RMS)")
        if experiment == "som-patterns":
            axes[1, col].axhline(PAPER_SOM_ERR3D, color="k", linewidth=0.8, linestyle=":")
            note = "paper: 900 nodes, 5000 patterns"
            axes[1, col].annotate(note, (0.02, 0.02), xycoords="axes fraction", fontsize=6)
    return _save(
        fig,
        path,
        "SOM (Jenkins & Dacey 2011) beside the gate; test directions over the whole sphere; "
        "mean +- sd over seeds",
    )


def _save(fig, path: Path, title: str) -> Path:
    """Title ``fig``, write it to ``path`` (110 dpi) and close it; returns ``path``."""
    import matplotlib.pyplot as plt

    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def draw_rigidmap_figure(points: list[Point], path: Path) -> Path:
    """The Rigid Map paper's Figure 2 (a)-(d): range and interpolating nodes, both layouts."""
    import matplotlib.pyplot as plt

    layouts = sorted({p.model for p in select(points, "rm-k")})
    paper = [m for m in layouts if "polytope" in m] + [m for m in layouts if "uniform" in m]
    fig, axes = plt.subplots(2, 2, figsize=(13, 10))
    for col, model in enumerate(paper[:2]):
        letter_range, letter_k = ("a", "c") if col == 0 else ("b", "d")
        ranged = [
            p for p in select(points, "rm-range") if p.model == model or "correct" in p.answer
        ]
        title = f"Rigid Map paper Fig. 2({letter_range}): {model}"
        _panel(axes[0, col], ranged, "mse", title, "range R (deg)", "quaternion MSE")
        by_k = select(points, "rm-k", model=model)
        flat = [p for p in by_k if p.answer in ("respond none", "correct (gate)")]
        curves = [p for p in by_k if p not in flat]
        for p in flat:  # discrete and gate answers do not depend on k: draw them at every k
            ks = sorted({c.x for c in curves}) or [0.0]
            curves += [replace(p, x=k) for k in [0.0, *ks]]
        title = f"Fig. 2({letter_k}): interpolating nodes, {model}"
        xlabel = "interpolating nodes k (0 = discrete)"
        _panel(axes[1, col], curves, "mse", title, xlabel, "quaternion MSE")
    return _save(fig, path, "Rigid Map (Jenkins & Angel) beside the gate; mean +- sd over seeds")


def draw_gate_figure(points: list[Point], path: Path) -> Path:
    """What the gate changes: angle errors, valid commands untouched, answers inside."""
    import matplotlib.pyplot as plt

    panels = (
        ("all", "angle_p95_deg", "p95 angle error, all inputs (deg)"),
        ("valid", "angle_mean_deg", "mean angle error, valid inputs (deg)"),
        ("invalid", "angle_mean_deg", "mean angle error, invalid inputs (deg)"),
        ("valid", "unchanged_share", "valid commands left unchanged (share)"),
        ("invalid", "inside_share", "answers to invalid commands inside the true region"),
        ("invalid", "outside_p95_deg", "p95 of how far answers lie outside (deg)"),
    )
    fig, axes = plt.subplots(2, 3, figsize=(19, 9))
    for ax, (subset, metric, label) in zip(axes.flat, panels):
        pts = [
            p
            for p in select(points, "rm-range", subset)
            if p.answer in ("respond none", "respond geometric", "correct (gate)")
        ]
        _panel(ax, pts, metric, label, "range R (deg)", label)
        if metric.endswith("share") or metric.startswith("outside"):
            ax.set_yscale("linear")
            ax.set_ylim(-0.02, 1.02)
    return _save(fig, path, "Rigid Map experiments: paper answers (solid) vs the gate (dashed)")


def draw_all(points: list[Point], out: Path) -> list[Path]:
    """Write every figure whose experiments are present; returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    out = Path(out)
    written = []
    if any(p.experiment.startswith("som-") for p in points):
        written.append(draw_som_figure(points, out / "som_figure2.png"))
    if any(p.experiment.startswith("rm-") for p in points):
        written.append(draw_rigidmap_figure(points, out / "rigidmap_figure2.png"))
        written.append(draw_gate_figure(points, out / "gate_metrics.png"))
    return written


@dataclass
class Summary:
    """The markdown summary, its headline lines, and the reproduction verdict (None: not run)."""

    text: str
    headline: list[str]
    reproduction_ok: bool | None


def _cell(value: tuple[float, float], fmt: str) -> str:
    mean, sd = value
    if not math.isfinite(mean):
        return "-"
    return f"{fmt.format(mean)} ± {fmt.format(sd)}"


def table(
    points: list[Point],
    experiment: str,
    x: float,
    subsets: tuple[str, ...] = ("all",),
    answers: tuple[str, ...] | None = None,
) -> list[str]:
    """A markdown table of the models' answers at one x (optionally only ``answers``)."""
    lines = [
        "| model | answer | inputs | n | " + " | ".join(h for _, h, _ in TABLE_COLUMNS) + " |",
        "|---|---|---|---|" + "---|" * len(TABLE_COLUMNS),
    ]
    order = {"all": 0, "valid": 1, "invalid": 2}
    chosen = [
        p
        for p in points
        if p.experiment == experiment
        and p.x == x
        and p.subset in subsets
        and (answers is None or p.answer in answers)
    ]
    chosen.sort(key=lambda p: (p.model, p.answer, order[p.subset]))
    for p in chosen:
        cells = [_cell(p.values[m], f) for m, _, f in TABLE_COLUMNS]
        n = p.values["n"][0]
        lines.append(
            f"| {p.model} | {p.answer} | {p.subset} | {n:.0f} | " + " | ".join(cells) + " |"
        )
    return lines


def _mse(points: list[Point], experiment: str, x: float, model: str, answer: str) -> float:
    found = select(points, experiment, model=model, answer=answer, x=x)
    return found[0].values["mse"][0] if found else math.nan


def rigidmap_checks(points: list[Point], x: float = 20.0) -> list[str]:
    """The Rigid Map paper's qualitative claims, checked on the rm-range points at ``x``."""
    lines = []
    paper = ("polytope", "uniform")
    models = sorted(
        {p.model for p in select(points, "rm-range") if any(s in p.model for s in paper)}
    )
    gains = {}
    for model in models:
        discrete = _mse(points, "rm-range", x, model, "respond none")
        interps = {
            p.answer: p.values["mse"][0]
            for p in select(points, "rm-range", model=model)
            if p.x == x and p.answer.startswith("respond") and p.answer != "respond none"
        }
        if not interps or not math.isfinite(discrete):
            continue
        best = min(interps, key=interps.get)
        gains[model] = discrete / interps[best]
        lines.append(
            f"- {model}, R = {x:g} deg: discrete MSE {discrete:.4g}; best interpolation "
            f"`{best}` MSE {interps[best]:.4g} (discrete / best = {gains[model]:.2f}); "
            + ", ".join(f"{a.split()[-1]} {v:.4g}" for a, v in sorted(interps.items()))
        )
    poly = [m for m in gains if "polytope" in m]
    uni = [m for m in gains if "uniform" in m]
    if poly and uni:
        more = gains[uni[0]] > gains[poly[0]]
        lines.append(
            f"- interpolation helps more with the uniform layout than with 720 polytope nodes: "
            f"**{'yes' if more else 'no'}** ({gains[uni[0]]:.2f} vs {gains[poly[0]]:.2f})"
        )
    return lines


def summary_markdown(points: list[Point], scale: str) -> Summary:
    """The summary.md text: reproduction check, default-setting tables, qualitative checks."""
    text = [f"# limbctl eval — {scale} grid", ""]
    headline = []
    ok: bool | None = None
    repro = select(points, "som-patterns", model="SOM 30x30", answer="respond none", x=5000)
    text += ["## Reproduction check (SOM paper)", ""]
    if repro:
        mean, sd = repro[0].values["err3d_rms"]
        lo, hi = REPRODUCTION_BAND
        ok = lo <= mean <= hi
        verdict = "PASS" if ok else "FAIL"
        line = (
            f"SOM 30x30, 5000 patterns, R = 90 deg, test directions uniform over the sphere: "
            f"3D error (RMS) {mean:.4f} ± {sd:.4f} over {repro[0].seeds} seeds; paper "
            f"{PAPER_SOM_ERR3D:.4f}; expected band [{lo}, {hi}]: {verdict}"
        )
        text += [line, ""]
        headline.append(line)
    else:
        text += ["(not in this grid)", ""]
    som_title = "SOM paper defaults (Table I: 500 patterns, R = 90 deg; 10x10 = 100 nodes and up)"
    sections = (
        ("som-range", 90.0, som_title),
        ("rm-range", 20.0, "Rigid Map paper defaults (1000 patterns, R = 20 deg)"),
    )
    key_answers = ("respond none", "respond geometric", "data nodes geometric", "correct (gate)")
    for experiment, x, title in sections:
        rows = table(points, experiment, x)
        if len(rows) > 2:
            split = table(points, experiment, x, ("valid", "invalid"), key_answers)
            text += [f"## {title}", "", "All test inputs:", "", *rows, ""]
            text += ["Valid and invalid inputs apart (key answers):", "", *split, ""]
    checks = rigidmap_checks(points)
    if checks:
        text += ["## Rigid Map paper: qualitative claims", "", *checks, ""]
        headline += [c.lstrip("- ") for c in checks if "helps more" in c]
    return Summary("\n".join(text), headline, ok)
