"""The networks in onnxruntime and in PyTorch on this CPU: forward time per call and the
largest difference between their outputs (docs/benchmarks.md, "View network:
onnxruntime vs PyTorch").

Randomly initialised networks of the default size (their speed does not depend on the
weights), exported with ``heapgrasp.training.export_onnx``; random 40³ occupancy grids
(15 % occupied). Each call is one forward pass on a batch of 1, timed alone after
``--warmup`` calls; the median of ``--calls`` is reported. The runtimes take turns in
blocks of ``--block`` calls (each block after two untimed calls and a 50 ms pause, so
one runtime's spinning worker threads have gone idle before the other's run), so a
machine busy with other work slows both alike. The view network is also
timed through ``NetworkViewScorer.scores`` (input checks and the NumPy output included),
which is what a view waypoint costs.

Run: ``.venv/bin/python scripts/bench_onnx.py`` (needs the train extra: PyTorch, onnx,
onnxscript).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
import onnxruntime
import torch
from heapgrasp.inference import OnnxNetwork
from heapgrasp.planning.view_network import NetworkViewScorer
from heapgrasp.training import GraspNet, ViewNet, export_onnx
from heapgrasp.training.export import describe_machine


def median_ms(
    runs: dict[str, Callable[[], object]], calls: int, warmup: int, block: int
) -> dict[str, float]:
    """Median milliseconds per call of each of ``runs``, in turns of ``block`` calls."""
    for call in runs.values():
        for _ in range(warmup):
            call()
    times: dict[str, list[float]] = {name: [] for name in runs}
    while min(len(t) for t in times.values()) < calls:
        for name, call in runs.items():
            time.sleep(0.05)
            call()
            call()
            for _ in range(min(block, calls - len(times[name]))):
                t0 = time.perf_counter()
                call()
                times[name].append(time.perf_counter() - t0)
    return {name: 1e3 * statistics.median(t) for name, t in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=200, help="timed calls (median)")
    parser.add_argument("--warmup", type=int, default=20)
    parser.add_argument("--block", type=int, default=25, help="calls per turn")
    parser.add_argument("--grasp-calls", type=int, default=50, help="timed grasp-net calls")
    parser.add_argument("--grids", type=int, default=20, help="random grids for the difference")
    parser.add_argument(
        "--threads", type=int, default=os.cpu_count() or 1, help="CPU threads of both runtimes"
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(0)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, net, calls in (
            ("view network (1 channel)", ViewNet(), args.calls),
            ("view network (2 channels)", ViewNet(in_channels=2), args.calls),
            ("grasp network", GraspNet(), args.grasp_calls),
        ):
            torch.manual_seed(0)
            net = type(net)(**net.hparams()).eval()
            kind = "grasp-network" if isinstance(net, GraspNet) else "view-network"
            path = export_onnx(net, Path(tmp) / f"{kind}.onnx", provenance={"data": None})
            onnx_net = OnnxNetwork(path, kind=kind, threads=args.threads)  # type: ignore[arg-type]
            c = int(onnx_net.hparams["in_channels"])
            grids = (rng.random((args.grids, 1, c, 40, 40, 40)) > 0.85).astype(np.float32)
            diff = 0.0
            for g in grids:
                with torch.inference_mode():
                    ref = net(torch.from_numpy(g))
                refs = [ref] if isinstance(ref, torch.Tensor) else list(ref)
                for a, b in zip(onnx_net.run(g), refs, strict=True):
                    diff = max(diff, float(np.max(np.abs(a - b.numpy()))))
            x = grids[0]
            xt = torch.from_numpy(x)

            def torch_call(net: torch.nn.Module = net, xt: torch.Tensor = xt) -> object:
                with torch.inference_mode():
                    return net(xt)

            runs: dict[str, Callable[[], object]] = {
                "torch_ms": torch_call,
                "onnxruntime_ms": partial(onnx_net.run, x),
            }
            if kind == "view-network":
                scorer = NetworkViewScorer(path)
                scorer.network = onnx_net  # the same session: the same threads
                runs["scorer_ms"] = partial(scorer.scores, x[0, 0])
            row = {
                "network": name,
                **median_ms(runs, calls, args.warmup, args.block),
                "max_abs_diff": diff,
            }
            rows.append(row)
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "?"
    print(
        json.dumps(
            {
                "date": time.strftime("%Y-%m-%d"),
                "commit": commit,
                "machine": describe_machine(),
                "torch": torch.__version__,
                "threads": args.threads,
                "load_average_1min": os.getloadavg()[0],
                "onnxruntime": onnxruntime.__version__,
                "calls": args.calls,
                "block": args.block,
                "grasp_calls": args.grasp_calls,
                "rows": rows,
            },
            indent=2,
        )
    )
    print()
    print("| network, batch of 1, 40³ | PyTorch | onnxruntime | scorer.scores | max abs diff |")
    print("|---|---|---|---|---|")
    for r in rows:
        scorer = f"{r['scorer_ms']:.2f} ms" if "scorer_ms" in r else "–"
        print(
            f"| {r['network']} | {r['torch_ms']:.2f} ms | {r['onnxruntime_ms']:.2f} ms | "
            f"{scorer} | {r['max_abs_diff']:.1e} |"
        )


if __name__ == "__main__":
    main()
