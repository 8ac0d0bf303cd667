"""Node positions on S^3 (unit quaternions) for Rigid Map output layers, by name: on w >= 0
(polytopes folded, each antipodal pair keeping its canonical member), or the papers' node sets."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np

from limbctl.errors import ConfigError

#: Golden ratio phi = (1 + sqrt 5) / 2.
PHI = (1.0 + np.sqrt(5.0)) / 2.0
#: Super-Fibonacci constant: the real root of psi^4 = psi + 4.
PSI = 1.533751168755204288118041


def _signed_variants(base: tuple[float, ...]) -> set[tuple[float, ...]]:
    """All sign changes of the non-zero entries of ``base``."""
    out = set()
    for signs in itertools.product((1.0, -1.0), repeat=len(base)):
        out.add(tuple(s * v if v != 0.0 else 0.0 for s, v in zip(signs, base, strict=True)))
    return out


def _is_even(perm: tuple[int, ...]) -> bool:
    """Parity of a permutation of 0..n-1 (True for an even number of transpositions)."""
    perm = list(perm)
    swaps = 0
    for i in range(len(perm)):
        while perm[i] != i:
            j = perm[i]
            perm[i], perm[j] = perm[j], perm[i]
            swaps += 1
    return swaps % 2 == 0


def _permuted(base: tuple[float, ...], parity: str) -> np.ndarray:
    """Sign changes of ``base`` under all / even / odd coordinate permutations, de-duplicated."""
    points = set()
    for perm in itertools.permutations(range(len(base))):
        if parity == "even" and not _is_even(perm):
            continue
        if parity == "odd" and _is_even(perm):
            continue
        for signed in _signed_variants(tuple(base[p] for p in perm)):
            points.add(signed)
    return np.array(sorted(points), dtype=np.float64)


def _normalise_rows(p: np.ndarray) -> np.ndarray:
    """Rows of ``p`` (n, 4) scaled to unit length."""
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def fold_to_hemisphere(points: np.ndarray, decimals: int = 9) -> np.ndarray:
    """Unit quaternions (n, 4) folded to w >= 0, duplicates dropped, order kept: (m, 4)."""
    points = np.asarray(points, dtype=np.float64)
    rounded = np.round(points, decimals) + 0.0  # + 0.0 turns -0.0 into 0.0
    nonzero = rounded != 0.0
    first = np.argmax(nonzero, axis=1)
    sign = np.sign(rounded[np.arange(len(points)), first])
    sign[sign == 0.0] = 1.0
    folded = points * sign[:, None]
    _, keep = np.unique(np.round(folded, decimals) + 0.0, axis=0, return_index=True)
    return folded[np.sort(keep)]


def cell_24() -> np.ndarray:
    """The 24-cell's 24 vertices: permutations of (+-1, 0, 0, 0) and (+-1/2, ..., +-1/2)."""
    axes = _permuted((1.0, 0.0, 0.0, 0.0), "all")
    halves = _permuted((0.5, 0.5, 0.5, 0.5), "all")
    return np.concatenate([axes, halves])


def cell_600(parity: str = "odd") -> np.ndarray:
    """The 600-cell's 120 unit vertices: the 24-cell's plus the 96 ``parity`` permutations of
    (+-phi, +-1, +-1/phi, 0) / 2 (``"odd"``: dual to :func:`cell_120`; ``"even"``: textbook)."""
    if parity not in ("odd", "even"):
        raise ConfigError(f"600-cell parity must be 'odd' or 'even', got {parity!r}")
    snub = _permuted((PHI / 2.0, 0.5, 0.5 / PHI, 0.0), parity)
    return np.concatenate([cell_24(), snub])


def cell_120() -> np.ndarray:
    """The 120-cell's 600 vertices (unit length; Coxeter's coordinates over sqrt 8)."""
    s5 = np.sqrt(5.0)
    groups = [
        _permuted((0.0, 0.0, 2.0, 2.0), "all"),
        _permuted((1.0, 1.0, 1.0, s5), "all"),
        _permuted((PHI**-2, PHI, PHI, PHI), "all"),
        _permuted((1 / PHI, 1 / PHI, 1 / PHI, PHI**2), "all"),
        _permuted((0.0, PHI**-2, 1.0, PHI**2), "even"),
        _permuted((0.0, 1 / PHI, PHI, s5), "even"),
        _permuted((1 / PHI, 1.0, PHI, 2.0), "even"),
    ]
    # the circumradius of these coordinates is sqrt(8)
    return np.concatenate(groups) / np.sqrt(8.0)


def union_720(parity: str = "odd") -> np.ndarray:
    """The papers' 720 nodes: :func:`cell_600` (``parity``) followed by :func:`cell_120`."""
    return np.concatenate([cell_600(parity), cell_120()])


def uniform(n: int, rng: np.random.Generator, hemisphere: bool) -> np.ndarray:
    """``n`` points (n, 4) uniform on S^3 (or on w >= 0): normalised Gaussian 4-vectors."""
    g = rng.standard_normal((n, 4))
    p = _normalise_rows(g)
    if hemisphere:
        p = p * np.where(p[:, :1] < 0.0, -1.0, 1.0)
    return p


def super_fibonacci(n: int, hemisphere: bool) -> np.ndarray:
    """Alexa's super-Fibonacci spiral: ``n`` near-uniform points (n, 4) on S^3 (or on w >= 0)."""
    s = np.arange(n, dtype=np.float64) + 0.5
    t = s / n
    r = np.sqrt(t)
    big_r = np.sqrt(1.0 - t)
    alpha_span = np.pi if hemisphere else 2.0 * np.pi  # [0, pi): w = r sin alpha >= 0
    # alpha = span * frac(s / sqrt 2), beta = 2 pi * frac(s / psi);
    # q = (r sin alpha, r cos alpha, R sin beta, R cos beta), r = sqrt(s / n), R = sqrt(1 - s / n)
    alpha = alpha_span * np.mod(s / np.sqrt(2.0), 1.0)
    beta = 2.0 * np.pi * np.mod(s / PSI, 1.0)
    return np.stack(
        [r * np.sin(alpha), r * np.cos(alpha), big_r * np.sin(beta), big_r * np.cos(beta)], axis=1
    )


def _fixed(builder: Callable[[], np.ndarray]) -> Callable[..., np.ndarray]:
    def make(n: int | None, rng: np.random.Generator, hemisphere: bool) -> np.ndarray:
        points = _normalise_rows(builder())
        if hemisphere:
            points = fold_to_hemisphere(points)
        if n is not None and n != len(points):
            raise ConfigError(
                f"this polytope layout has {len(points)} nodes"
                f"{' on the w >= 0 hemisphere' if hemisphere else ''}; got n={n} "
                f"(leave n unset, or use 'uniform' / 'super-fibonacci' for any n)"
            )
        return points

    return make


def _sized(builder: Callable[[int, np.random.Generator, bool], np.ndarray]):
    def make(n: int | None, rng: np.random.Generator, hemisphere: bool) -> np.ndarray:
        if n is None or isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ConfigError(f"this layout needs a node count n >= 1 (e.g. n=2000), got {n!r}")
        return builder(int(n), rng, hemisphere)

    return make


#: Layout strategies by name: callables (n, rng, hemisphere) -> (n, 4) unit quaternions.
LAYOUTS: dict[str, Callable[[int | None, np.random.Generator, bool], np.ndarray]] = {
    "24-cell": _fixed(cell_24),
    "600-cell": _fixed(lambda: cell_600("odd")),
    "120-cell": _fixed(cell_120),
    "polytope-720": _fixed(lambda: union_720("odd")),
    "polytope-720-even": _fixed(lambda: union_720("even")),
    "uniform": _sized(uniform),
    "super-fibonacci": _sized(lambda n, rng, hemisphere: super_fibonacci(n, hemisphere)),
}


def make_layout(
    name: str, n: int | None = None, seed: int | np.random.Generator = 0, hemisphere: bool = True
) -> np.ndarray:
    """Node positions on S^3 by layout ``name`` (of :data:`LAYOUTS`): ``n`` nodes (required for
    ``uniform`` and ``super-fibonacci``, a polytope's count), ``seed`` for ``uniform``, on w >= 0
    (polytopes folded) or, without ``hemisphere``, the papers' node sets. ConfigError for an
    unknown name (listing the choices) or an ``n`` the layout cannot give.

    Returns
    -------
    ndarray, shape (n, 4)
        Unit quaternions, float64.
    """
    try:
        build = LAYOUTS[name]
    except (KeyError, TypeError):
        raise ConfigError(
            f"unknown layout {name!r}; choose one of: {', '.join(sorted(LAYOUTS))}"
        ) from None
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    return np.ascontiguousarray(build(n, rng, hemisphere), dtype=np.float64)
