"""Time one step of seed 001's benchmark, part by part (docs/benchmarks.md).

For each object (default: four of the stand-ins), from the start view and the views one
and two moves south-east of it, times: rendering a view's depth (640 × 480), its points
(back-projection and the 7.5 mm down-sampling), its unexplored-region mask, the fusion
of a set of views into the object's points, and the grasp synthesis of the set (normals,
pairs, contact patches, ranking, the collision check). Median of ``--repeat`` runs, ms.

    python scripts/time_viewsphere_steps.py [--objects A,B] [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

from heapgrasp.viewsphere.grasps import ViewsphereGrasps
from heapgrasp.viewsphere.objects import stand_in
from heapgrasp.viewsphere.policies import pose_key
from heapgrasp.viewsphere.world import ViewsphereWorld


def _ms(fn: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(1e3 * (time.perf_counter() - t))
    return statistics.median(times)


def _row(name: str, repeat: int) -> str:
    world = ViewsphereWorld(stand_in(name))
    s, start = world.sphere, world.start
    one = s.move(start, 3)[1]
    views = [start, one, s.move(one, 3)[1]]

    def fresh() -> ViewsphereGrasps:
        return ViewsphereGrasps(world.render, sphere=s, camera=world.camera, config=world.config)

    render = _ms(lambda: world.render(one), repeat)
    warm = fresh()
    depth = warm.depth(one)

    def points() -> object:
        g = fresh()
        g._depth[pose_key(one)] = depth  # the rendered view, not rendered again
        return g.points(one)

    pts = _ms(points, repeat)
    for v in views:
        warm.points(v)
    region = warm._first_region(start)
    assert region is not None
    mask = _ms(lambda: region.seen(depth, warm.camera, s.camera_pose(one)), repeat)
    fuse = _ms(lambda: warm.object_points(views), repeat)
    warm.unexplored(views)  # the views' masks, cached as in a search
    synth = _ms(lambda: warm._synthesise(views), repeat)
    found = "yes" if warm._synthesise(views) is not None else "no"
    return (
        f"| {name} | {render:.0f} | {pts:.0f} | {mask:.0f} | {fuse:.0f} | {synth:.0f} | {found} |"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--objects",
        default="005_tomato_soup_can,003_cracker_box,025_mug,072-a_toy_airplane",
        help="comma-separated stand-ins",
    )
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args()
    print("| object | render | points | unexplored mask | fuse 3 views | synthesis | found |")
    print("|---|---|---|---|---|---|---|")
    for name in args.objects.split(","):
        print(_row(name, args.repeat), flush=True)


if __name__ == "__main__":
    main()
