"""Does a calibration map fitted on one ``heapgrasp bench topk`` run hold on another?

Reads the labelled top-k grasps of ``--planner`` in two topk runs' ``results.json``: the
*fit* run (e.g. training-object piles, ``--set split=train``) and the *check* run (e.g.
test-object piles). Fits an isotonic map from score to the share held on the fit run's
grasps (scikit-learn) and prints, as one JSON object, the calibration error
(:func:`heapgrasp.bench.topk.reliability`) of the check run's grasps with their raw scores
and with the mapped ones, the mapped reliability bins, and the map's knots.

    python scripts/calibration_transfer.py FIT/results.json CHECK/results.json --planner network
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt
from heapgrasp.bench.topk import reliability


def labelled(path: Path, planner: str) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Scores and labels (1 held) of every labelled grasp of ``planner`` in a topk run."""
    payload = json.loads(path.read_text())
    scores: list[float] = []
    labels: list[bool] = []
    for record in payload["records"]:
        for phase in record.get("phases", []):
            ranking = phase["rankings"].get(planner)
            if ranking is None:
                raise SystemExit(f"{path}: no ranking of planner {planner!r}")
            scores += ranking["scores"][: len(ranking["labels"])]
            labels += ranking["labels"]
    return np.asarray(scores, dtype=np.float64), np.asarray(labels, dtype=np.float64)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("fit", type=Path, help="results.json the map is fitted on")
    parser.add_argument("check", type=Path, help="results.json the map is checked on")
    parser.add_argument("--planner", default="network", help="planner name (network)")
    args = parser.parse_args(argv)
    from sklearn.isotonic import IsotonicRegression

    fit_s, fit_y = labelled(args.fit, args.planner)
    check_s, check_y = labelled(args.check, args.planner)
    if len(fit_s) == 0 or len(check_s) == 0:
        print("no labelled grasps to fit or check", file=sys.stderr)
        return 1
    iso = IsotonicRegression(out_of_bounds="clip", y_min=0.0, y_max=1.0).fit(fit_s, fit_y)
    mapped = np.asarray(iso.predict(check_s), dtype=np.float64)
    out = {
        "planner": args.planner,
        "fit": {
            "run": str(args.fit),
            "grasps": len(fit_s),
            "ece": reliability(fit_s, fit_y)["ece"],
        },
        "check": {
            "run": str(args.check),
            "grasps": len(check_s),
            "ece_raw": reliability(check_s, check_y)["ece"],
            "ece_mapped": reliability(mapped, check_y)["ece"],
            "bins_mapped": reliability(mapped, check_y)["bins"],
        },
        "map": {
            "scores": [float(v) for v in iso.X_thresholds_],
            "probabilities": [float(v) for v in iso.y_thresholds_],
        },
    }
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
