"""The grasp and view networks on the CPU and, where there is one, on a CUDA device.

Checks that a CUDA run gives the CPU's volumes (randomly initialised networks, random
40³ grids) and times one forward pass per call of ``NetworkGraspPlanner.predict_batch``
and ``NetworkViewScorer.scores`` (host-device transfers and the NumPy outputs included).
Run: ``.venv/bin/python scripts/net_timing.py`` (docs/benchmarks.md, "The networks on a
GPU").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial

import numpy as np
import torch
from heapgrasp.planning.grasp_network import NetworkGraspPlanner
from heapgrasp.planning.volumes import GridFrame
from heapgrasp.nets import GraspNet, ViewNet
from heapgrasp.planning.view_network import NetworkViewScorer

FRAME = GridFrame((-0.15, -0.15, 0.0), 0.30, 40)


def grids(batch: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.random((batch, 40, 40, 40)) > 0.85).astype(np.float32)


def timed(call: Callable[[], object], device: str, repeats: int) -> float:
    call()  # warm-up (cuDNN picks its kernels)
    if device == "cuda":
        torch.cuda.synchronize()
    t0 = time.perf_counter()
    for _ in range(repeats):
        call()
    if device == "cuda":
        torch.cuda.synchronize()
    return (time.perf_counter() - t0) / repeats


def main() -> None:
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    print(f"torch {torch.__version__}, {torch.get_num_threads()} CPU threads, devices {devices}")
    torch.manual_seed(0)
    grasp_net, view_net = GraspNet(40).eval(), ViewNet(40, (40, 20)).eval()
    state_g, state_v = grasp_net.state_dict(), view_net.state_dict()
    if "cuda" in devices:
        g = grids(2, 1)
        cpu = NetworkGraspPlanner(grasp_net).predict_batch(g, FRAME)
        net = GraspNet(40).eval()
        net.load_state_dict(state_g)
        gpu = NetworkGraspPlanner(net, device="cuda").predict_batch(g, FRAME)
        dq = max(float(np.abs(a.quality - b.quality).max()) for a, b in zip(cpu, gpu, strict=True))
        dw = max(float(np.abs(a.widths - b.widths).max()) for a, b in zip(cpu, gpu, strict=True))
        print(f"grasp net, CUDA against CPU: max |Δquality| {dq:.2e}, max |Δwidth| {dw:.2e}")
        vnet = ViewNet(40, (40, 20)).eval()
        vnet.load_state_dict(state_v)
        ds = np.abs(
            NetworkViewScorer(view_net).scores(g[0])
            - NetworkViewScorer(vnet, device="cuda").scores(g[0])
        ).max()
        print(f"view net, CUDA against CPU: max |Δscore| {float(ds):.2e}")
    for device in devices:
        gnet = GraspNet(40).eval()
        gnet.load_state_dict(state_g)
        planner = NetworkGraspPlanner(gnet, device=device)
        vnet = ViewNet(40, (40, 20)).eval()
        vnet.load_state_dict(state_v)
        scorer = NetworkViewScorer(vnet, device=device)
        repeats = 20 if device == "cuda" else 5
        for batch in (1, 8):
            g = grids(batch, 2)
            dt = timed(partial(planner.predict_batch, g, FRAME), device, repeats)
            print(
                f"{device:>4} grasp net, 40³, batch {batch}: {dt * 1e3:8.2f} ms per call, "
                f"{dt / batch * 1e3:7.2f} ms per grid"
            )
        one = grids(1, 3)[0]
        dt = timed(partial(scorer.scores, one), device, repeats)
        print(f"{device:>4} view net, 40³ → 40×20: {dt * 1e3:8.2f} ms per call")


if __name__ == "__main__":
    main()
