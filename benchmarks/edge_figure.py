"""Picture of the gate's edges on the irregular benchmark regions (docs/figures/edges.png).

Run: ``.venv/bin/python benchmarks/edge_figure.py`` (bench_envelope.py also draws it).

One panel per region (the small kidney, the egg, the BEAN; 1000 i.i.d. teaching samples,
seed 0), in pan/tilt degrees: the taught samples, the true boundary, the data-supported loops
(the region with ``RegionParams(edge="supported")``) and the edge the gate took.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from limbctl.envelope import RigidMap  # noqa: E402
from limbctl.envelope.synthetic import (  # noqa: E402
    BEAN,
    EGG,
    SMALL_KIDNEY,
    PolygonRegion,
    to_quaternions,
)
from limbctl.geometry.gimbal import direction_to_pan_tilt  # noqa: E402
from limbctl.region import RegionParams, TaughtRegion  # noqa: E402
from limbctl.region.mesh import DirectionMesh  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def mesh_segments(mesh: DirectionMesh) -> list[np.ndarray]:
    """The mesh's boundary arcs as (2, 2) pan/tilt segments in degrees."""
    pan, tilt = direction_to_pan_tilt(mesh.vertices)
    xy = np.degrees(np.column_stack([pan, tilt]))
    return [xy[list(e)] for e in mesh.edges]


def draw(ax, name: str, polygon: np.ndarray, seed: int) -> None:
    """One panel: samples, true boundary, supported loops and the gate's edge."""
    region = PolygonRegion(polygon)
    rng = np.random.default_rng(seed)
    train = region.sample(1000, rng)
    q = to_quaternions(train)
    gate = RigidMap(nodes=2000, layout="uniform", seed=seed).fit(q)
    supported = TaughtRegion(RegionParams(edge="supported")).fit(q)
    pan, tilt = direction_to_pan_tilt(train)
    ax.plot(np.degrees(pan), np.degrees(tilt), ".", ms=2, color="0.6", label="taught samples")
    closed = np.vstack([polygon, polygon[:1]])
    ax.plot(closed[:, 0], closed[:, 1], "k-", lw=1.2, label="true boundary")
    for i, seg in enumerate(mesh_segments(supported.mesh)):
        ax.plot(seg[:, 0], seg[:, 1], "-", color="tab:orange", lw=1.0,
                label="supported loops" if i == 0 else None)  # fmt: skip
    if gate.edge != "supported":
        for i, seg in enumerate(mesh_segments(gate.mesh)):
            ax.plot(seg[:, 0], seg[:, 1], "-", color="tab:blue", lw=1.0,
                    label=f"{gate.edge} edge (the gate's)" if i == 0 else None)  # fmt: skip
    ax.set_title(f"{name}: gate takes the {gate.edge} edge")
    ax.set_xlabel("pan (deg)")
    ax.set_ylabel("tilt (deg)")
    ax.set_aspect("equal")
    ax.legend(loc="lower right", fontsize=7)


def edge_figure(out: Path, seed: int = 0) -> Path:
    """Draw the three panels into ``out`` (PNG) and return it."""
    fig, axes = plt.subplots(1, 3, figsize=(16, 5))
    for ax, (name, polygon) in zip(
        axes,
        (("small kidney", SMALL_KIDNEY), ("egg", EGG), ("BEAN (sparse edge)", BEAN)),
        strict=True,
    ):
        draw(ax, name, polygon, seed)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "edges.png")
    args = parser.parse_args()
    print(edge_figure(args.out, args.seed))


if __name__ == "__main__":
    main()
