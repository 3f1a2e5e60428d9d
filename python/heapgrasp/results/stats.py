"""How sure a benchmark's success rates are: confidence intervals and paired differences.

Twenty scenes give about fifty grasps per method, so a success rate is known to within
about ±10 points (95 %), and two methods three points apart may well be equally good.
``heapgrasp bench sim`` reports, beside every success rate:

* :func:`success_interval` — the Wilson score interval of the rate (attempts as
  independent trials; :func:`scipy.stats.binomtest`);
* :func:`paired_success_difference` — the difference between two methods' rates with a
  bootstrap interval that resamples *scenes* (:func:`scipy.stats.bootstrap`,
  ``paired=True``): every method runs on the same seeded scenes, and grasps within a
  scene are not independent (a hard scene is hard for every method).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "format_interval",
    "methods_differences",
    "paired_success_difference",
    "scene_counts",
    "success_interval",
]

F64 = npt.NDArray[np.float64]


def _level(level: float) -> float:
    if not (isinstance(level, int | float) and math.isfinite(level) and 0.0 < level < 1.0):
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    return float(level)


def success_interval(succeeded: int, attempted: int, level: float = 0.95) -> tuple[float, float]:
    """Wilson score interval ``(low, high)`` of a success rate ``succeeded / attempted``.

    Raises ``ValueError`` for counts that are not integers with
    ``0 <= succeeded <= attempted`` and ``attempted >= 1``.
    """
    from scipy.stats import binomtest

    for name, value in (("succeeded", succeeded), ("attempted", attempted)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise ValueError(f"{name} must be an integer, got {value!r}")
    if attempted < 1 or not 0 <= succeeded <= attempted:
        raise ValueError(
            f"need 0 <= succeeded <= attempted and attempted >= 1, got {succeeded}/{attempted}"
        )
    ci = binomtest(int(succeeded), int(attempted)).proportion_ci(
        confidence_level=_level(level), method="wilson"
    )
    return float(ci.low), float(ci.high)


def scene_counts(phases: Iterable[Mapping[str, Any]]) -> dict[int, tuple[int, int]]:
    """``{scene: (succeeded, attempted)}`` from phase records that carry ``scene`` and
    ``outcome`` (``results.json``'s ``phases``); a phase with outcome ``no_candidate``
    attempted nothing. Scenes whose phases attempted nothing count ``(0, 0)``."""
    counts: dict[int, list[int]] = {}
    for p in phases:
        try:
            scene, outcome = int(p["scene"]), str(p["outcome"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(
                f"phase record needs an integer 'scene' and an 'outcome': {p!r}"
            ) from exc
        c = counts.setdefault(scene, [0, 0])
        if outcome != "no_candidate":
            c[1] += 1
            c[0] += outcome == "success"
    return {s: (c[0], c[1]) for s, c in sorted(counts.items())}


def paired_success_difference(
    a: Mapping[int, tuple[int, int]],
    b: Mapping[int, tuple[int, int]],
    *,
    level: float = 0.95,
    resamples: int = 10_000,
    seed: int = 0,
) -> dict[str, float | int | None]:
    """Success rate of ``a`` minus that of ``b`` (percentage points) on the scenes both
    ran, with a paired percentile-bootstrap interval over those scenes.

    ``a`` and ``b`` map scene → ``(succeeded, attempted)`` (:func:`scene_counts`). Returns
    ``difference``, ``low``, ``high`` (None when a rate is undefined: no attempt, or a
    resample without one) and ``scenes``, the number of scenes compared.
    """
    if isinstance(resamples, bool) or not isinstance(resamples, int) or resamples < 100:
        raise ValueError(f"resamples must be an integer >= 100, got {resamples!r}")
    level = _level(level)
    common = sorted(set(a) & set(b))
    out: dict[str, float | int | None] = {
        "difference": None,
        "low": None,
        "high": None,
        "scenes": len(common),
    }
    if not common:
        return out
    cols = np.array([[*a[s], *b[s]] for s in common], dtype=np.float64).T
    sa, na, sb, nb = cols
    if na.sum() == 0 or nb.sum() == 0:
        return out
    out["difference"] = 100.0 * float(sa.sum() / na.sum() - sb.sum() / nb.sum())
    if len(common) < 2:
        return out

    from scipy.stats import bootstrap

    def statistic(sa: F64, na: F64, sb: F64, nb: F64, axis: int = -1) -> F64:
        with np.errstate(invalid="ignore", divide="ignore"):
            rate_a = sa.sum(axis=axis) / na.sum(axis=axis)
            rate_b = sb.sum(axis=axis) / nb.sum(axis=axis)
        return np.asarray(100.0 * (rate_a - rate_b))

    res = bootstrap(
        (sa, na, sb, nb),
        statistic,
        paired=True,
        vectorized=True,
        n_resamples=resamples,
        confidence_level=level,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
    if math.isfinite(low) and math.isfinite(high):
        out["low"], out["high"] = low, high
    return out


def format_interval(low: float | None, high: float | None, digits: int = 1) -> str:
    """``[low, high]`` or ``–``."""
    if low is None or high is None:
        return "–"
    return f"[{low:.{digits}f}, {high:.{digits}f}]"


def methods_differences(
    per_method: Mapping[str, Sequence[Mapping[str, Any]]], reference: str
) -> dict[str, dict[str, float | int | None]]:
    """:func:`paired_success_difference` of every method against ``reference``, from
    each method's phase records; empty when ``reference`` did not run."""
    if reference not in per_method:
        return {}
    ref = scene_counts(per_method[reference])
    return {
        m: paired_success_difference(scene_counts(phases), ref)
        for m, phases in per_method.items()
        if m != reference
    }
