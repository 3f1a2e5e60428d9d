"""The grasp and view networks on the CPU and, where there is one, on a CUDA device.

The networks run as heapgrasp runs them: exported to ONNX and run with onnxruntime (the
CUDA execution provider needs onnxruntime-gpu). Checks that a CUDA run gives the CPU's
volumes (randomly initialised networks, random 40³ grids) and times one forward pass per
call of ``NetworkGraspPlanner.predict_batch`` and ``NetworkViewScorer.scores``
(host-device transfers and the NumPy outputs included). Run:
``.venv/bin/python scripts/net_timing.py`` (docs/benchmarks.md, "The networks on a
GPU"; needs the train extra to export the networks).
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
import onnxruntime
import torch
from heapgrasp.planning.grasp_network import NetworkGraspPlanner
from heapgrasp.planning.view_network import NetworkViewScorer
from heapgrasp.planning.volumes import GridFrame
from heapgrasp.training import GraspNet, ViewNet, export_onnx

FRAME = GridFrame((-0.15, -0.15, 0.0), 0.30, 40)


def grids(batch: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.random((batch, 40, 40, 40)) > 0.85).astype(np.float32)


def timed(call: Callable[[], object], repeats: int) -> float:
    call()  # warm-up (cuDNN picks its kernels); onnxruntime returns host arrays
    t0 = time.perf_counter()
    for _ in range(repeats):
        call()
    return (time.perf_counter() - t0) / repeats


def main() -> None:
    cuda = "CUDAExecutionProvider" in onnxruntime.get_available_providers()
    devices = ["cpu"] + (["cuda"] if cuda else [])
    print(f"onnxruntime {onnxruntime.__version__}, devices {devices}")
    torch.manual_seed(0)
    with tempfile.TemporaryDirectory() as tmp:
        grasp = export_onnx(GraspNet(40).eval(), Path(tmp) / "g.onnx", provenance={})
        view = export_onnx(ViewNet(40, (40, 20)).eval(), Path(tmp) / "v.onnx", provenance={})
        if cuda:
            g = grids(2, 1)
            cpu = NetworkGraspPlanner(grasp).predict_batch(g, FRAME)
            gpu = NetworkGraspPlanner(grasp, device="cuda").predict_batch(g, FRAME)
            pairs = list(zip(cpu, gpu, strict=True))
            dq = max(float(np.abs(a.quality - b.quality).max()) for a, b in pairs)
            dw = max(float(np.abs(a.widths - b.widths).max()) for a, b in pairs)
            print(f"grasp net, CUDA against CPU: max |Δquality| {dq:.2e}, max |Δwidth| {dw:.2e}")
            ds = np.abs(
                NetworkViewScorer(view).scores(g[0])
                - NetworkViewScorer(view, device="cuda").scores(g[0])
            ).max()
            print(f"view net, CUDA against CPU: max |Δscore| {float(ds):.2e}")
        for device in devices:
            planner = NetworkGraspPlanner(grasp, device=device)
            scorer = NetworkViewScorer(view, device=device)
            repeats = 20 if device == "cuda" else 5
            for batch in (1, 8):
                g = grids(batch, 2)
                dt = timed(partial(planner.predict_batch, g, FRAME), repeats)
                print(
                    f"{device:>4} grasp net, 40³, batch {batch}: {dt * 1e3:8.2f} ms per call, "
                    f"{dt / batch * 1e3:7.2f} ms per grid"
                )
            one = grids(1, 3)[0]
            dt = timed(partial(scorer.scores, one), repeats)
            print(f"{device:>4} view net, 40³ → 40×20: {dt * 1e3:8.2f} ms per call")


if __name__ == "__main__":
    main()
