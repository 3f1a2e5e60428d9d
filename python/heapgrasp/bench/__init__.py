"""Benchmarks behind ``heapgrasp bench``.

Each benchmark is a module with an ``add_parser(subparsers)`` function that registers
its subcommand (and sets ``func``, the function that runs it, as a parser default):

* :mod:`heapgrasp.bench.carve` -- ``heapgrasp bench carve``: Shape-from-Silhouette
  carving, the Rust kernel against NumPy, numba and Open3D;
* :mod:`heapgrasp.bench.world` -- ``heapgrasp bench world``: ground-truth masks vs
  PyBullet rendering, seconds per simulated grasp phase;
* :mod:`heapgrasp.bench.sim` -- ``heapgrasp bench sim``: the closed loop of HEAPGrasp and
  its baselines on seed 000's protocol (Tables II/III, Fig. 4/5);
* :mod:`heapgrasp.bench.grasp` -- ``heapgrasp bench grasp``: the analytic antipodal grasp
  planner on circle / dense Shape-from-Silhouette grids, one executed grasp per scene;
* :mod:`heapgrasp.bench.topk` -- ``heapgrasp bench topk``: each grasp planner's best
  few grasps on the grids the closed loop meets, labelled on the true meshes;
* :mod:`heapgrasp.bench.compare` -- ``heapgrasp bench compare``: two finished runs on
  the same scenes, success rates with intervals and their paired difference;
* :mod:`heapgrasp.bench.seg` -- ``heapgrasp bench seg``: the segmentation network's CPU
  time per frame, per encoder;
* :mod:`heapgrasp.bench.paper_tables` -- ``heapgrasp bench noise`` and ``heapgrasp bench
  clutter``: HEAPGrasp's Tables V (mask noise) and IV (clutter) in simulation.

Scenes shared by the benchmarks live in :mod:`heapgrasp.bench.scenes`. The viewsphere
benchmark (``heapgrasp bench viewsphere``) lives with the rest of its system in
:mod:`heapgrasp.viewsphere`; the command line registers it on the subparsers this
module's :func:`add_parser` returns.
"""

from __future__ import annotations

import argparse

from heapgrasp.bench import (
    carve,
    compare,
    grasp,
    paper_tables,
    seg,
    sim,
    topk,
    world,
)

__all__ = ["add_parser"]


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse._SubParsersAction[argparse.ArgumentParser]:
    """Adds the ``bench`` command group and its benchmarks to a CLI.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The top-level subparsers of ``heapgrasp``.

    Returns
    -------
    argparse._SubParsersAction
        The ``bench`` group's subparsers: further benchmarks (``bench viewsphere``, ...)
        register on them the way :func:`heapgrasp.bench.carve.add_parser` does.
    """
    p = subparsers.add_parser(
        "bench",
        help="benchmarks: the closed loop on the papers' protocols (sim, noise, clutter, "
        "viewsphere), run comparisons, and the Rust core's speed",
        description="Benchmarks: the closed loop on the papers' protocols (sim: Tables II/III; "
        "noise: Table V; clutter: Table IV; viewsphere: the active-vision benchmark), "
        "comparisons of finished runs, and the speed of the Rust core and the networks.",
    )
    benches = p.add_subparsers(
        dest="benchmark", metavar="BENCHMARK", title="benchmarks", required=True
    )
    carve.add_parser(benches)
    world.add_parser(benches)
    sim.add_parser(benches)
    grasp.add_parser(benches)
    topk.add_parser(benches)
    compare.add_parser(benches)
    seg.add_parser(benches)
    paper_tables.add_parsers(benches)
    return benches
