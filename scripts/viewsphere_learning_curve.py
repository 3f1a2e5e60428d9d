"""The viewsphere's supervised policies against their training-set size (issue 54): each
model (PCA + LR, PCA + LDA, the imitation perceptron) fitted on nested subsets of a
paths dataset (the first N samples, in shard order) and measured on a validation
dataset: the share of validation states whose chosen direction is an optimal one
(``val_top_accuracy``) and the mean extra moves. Writes ``OUT/learning_curve.json`` and
``OUT/learning_curve.png``; each fit's policy file and metrics go to
``OUT/<model>-<N>/``.

    python scripts/viewsphere_learning_curve.py --data runs/vs-bfs-train --val runs/vs-bfs-val \\
        --sizes 229,500,1000 --out runs/vs-curve
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from heapgrasp.data.shards import read_manifest
from heapgrasp.viewsphere.data import SPEC
from heapgrasp.viewsphere.training import train_linear, train_mlp

MODELS = ("pca-lr", "pca-lda", "imitation")


def _subset(data: Path, size: int, into: Path) -> int:
    """A copy of ``data`` holding its first ``size`` samples (whole shards, the last one
    cut), as a dataset folder the trainers read. Returns the samples it holds."""
    manifest = read_manifest(data, SPEC)
    into.mkdir(parents=True)
    kept, shards = 0, {}
    for name in sorted(manifest["shards"]):
        if kept >= size:
            break
        with np.load(data / name) as shard:
            arrays = {k: np.asarray(shard[k]) for k in shard.files}
        take = min(size - kept, len(arrays["label"]))
        n = len(arrays["label"])
        cut = {k: (v[:take] if v.ndim and len(v) == n else v) for k, v in arrays.items()}
        np.savez(into / name, **cut)
        shards[name] = {**manifest["shards"][name], "samples": take}
        kept += take
    (into / "manifest.json").write_text(
        json.dumps({**manifest, "shards": shards, "samples": kept}, indent=1)
    )
    return kept


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--data", type=Path, required=True, help="the training paths dataset")
    p.add_argument("--val", type=Path, required=True, help="the validation paths dataset")
    p.add_argument(
        "--sizes",
        default="229,500,1000",
        help="comma-separated subset sizes; the whole set is added",
    )
    p.add_argument("--models", default=",".join(MODELS), help=f"among {', '.join(MODELS)}")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    models = [m.strip() for m in args.models.split(",") if m.strip()]
    bad = [m for m in models if m not in MODELS]
    if bad:
        p.error(f"unknown model(s) {', '.join(bad)}; choose from {', '.join(MODELS)}")
    total = int(read_manifest(args.data, SPEC)["samples"])
    sizes = sorted(
        {int(s) for s in args.sizes.split(",") if s.strip() and int(s) < total} | {total}
    )
    args.out.mkdir(parents=True, exist_ok=True)
    curve: dict[str, Any] = {
        "data": str(args.data),
        "val": str(args.val),
        "sizes": sizes,
        "models": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        for size in sizes:
            subset = Path(tmp) / f"n{size}"
            held = _subset(args.data, size, subset)
            for model in models:
                out = args.out / f"{model}-{size}"
                if model == "imitation":
                    metrics = train_mlp([subset], [args.val], out)
                else:
                    metrics = train_linear(model.removeprefix("pca-"), [subset], [args.val], out)
                curve["models"].setdefault(model, []).append(
                    {
                        "samples": held,
                        "val_top_accuracy": metrics["val_top_accuracy"],
                        "val_extra_moves": metrics["val_extra_moves"],
                    }
                )
                print(f"{model} n={held}: top {metrics['val_top_accuracy']:.3f}", file=sys.stderr)
            shutil.rmtree(subset)
    (args.out / "learning_curve.json").write_text(json.dumps(curve, indent=1) + "\n")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5, 3.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for model, points in curve["models"].items():
        ax.plot(
            [q["samples"] for q in points],
            [q["val_top_accuracy"] for q in points],
            "o-",
            label=model,
        )
    ax.set_xscale("log")
    ax.set_xlabel("training states")
    ax.set_ylabel("validation: an optimal first move")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "learning_curve.png", dpi=110)
    print(json.dumps(curve, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
