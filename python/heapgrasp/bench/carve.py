"""``heapgrasp bench carve``: Shape-from-Silhouette carving, Rust against Python baselines.

Every method counts, for each voxel of a cubic grid, in how many of N frames its centre
projects inside the image (``visible``) and onto a set silhouette pixel (``segmented``):
the counts behind HEAPGrasp's occupancy (eq. 10). The methods run in one process on
the same masks (the scene of :mod:`heapgrasp.bench.scenes`, which mirrors the criterion
fixtures in ``benches/src/lib.rs``):

``rust``
    :meth:`heapgrasp.OccupancyGrid.integrate_many` (the SIMD, multi-threaded kernel).
``numpy``
    :func:`carve_numpy`, the plain NumPy reference: per frame, all voxel centres are
    projected at once, looked up in the mask by fancy indexing and the counts are added.
``numba``
    :func:`carve_numba`, an ``@njit(parallel=True)`` loop (when numba is importable).
``open3d``
    ``open3d.geometry.VoxelGrid.carve_silhouette`` (when open3d is importable). Open3D
    *removes* voxels whose eight corners all miss the mask instead of counting, so its
    result is not compared, only timed.

The Rust and numba counts are checked against the NumPy reference: they must agree
except for voxels whose centre lies within ``BORDER_TOL`` px of a pixel border in some
frame, where the f32 arithmetic of the Rust kernel may pick the neighbouring pixel.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import json
import os
import platform
import statistics
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

import heapgrasp
from heapgrasp.bench.scenes import CUBE, CameraSpec, camera_spec, ring, sphere_masks

__all__ = [
    "BORDER_TOL",
    "METHODS",
    "Check",
    "Counts",
    "Result",
    "carve_numba",
    "carve_numpy",
    "compare_counts",
    "machine_info",
    "near_pixel_border",
    "run",
]

METHODS: tuple[str, ...] = ("rust", "numpy", "numba", "open3d")
"""Methods in the order they run and are reported."""

BORDER_TOL: float = 1e-3
"""Counts may differ from the reference only for voxels this close (px) to a pixel border."""

DEFAULT_SIZES: tuple[int, ...] = (40, 80, 160)
DEFAULT_IMAGES: tuple[tuple[int, int], ...] = ((320, 240), (640, 480))
QUICK_SIZES: tuple[int, ...] = (40, 80)
QUICK_IMAGES: tuple[tuple[int, int], ...] = ((320, 240),)
DEFAULT_REPEATS: dict[str, int] = {"rust": 10, "numpy": 3, "numba": 5, "open3d": 3}
ORIGIN: tuple[float, float, float] = (0.0, 0.0, 0.0)

Counts = tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint32]]
"""``(segmented, visible)`` counts, uint32 ``(R, R, R)`` arrays indexed ``[x, y, z]``."""


@dataclass
class Result:
    """Timing of one method on one (grid, image) configuration.

    Attributes
    ----------
    resolution : int
        Grid resolution R (the grid has R³ voxels).
    width, height : int
        Image size in pixels.
    views : int
        Number of frames carved per run.
    method : str
        One of :data:`METHODS`.
    status : str
        ``"ok"`` or ``"skipped"``.
    note : str
        Why the method was skipped, or remarks on the run.
    times_s : list of float
        Wall-clock seconds of every timed run.
    median_s : float or None
        Median of ``times_s``.
    projections_per_s : float or None
        ``R³ * views / median_s``.
    speedup_vs_numpy : float or None
        NumPy reference median divided by this median.
    """

    resolution: int
    width: int
    height: int
    views: int
    method: str
    status: str = "ok"
    note: str = ""
    times_s: list[float] = field(default_factory=list)
    median_s: float | None = None
    projections_per_s: float | None = None
    speedup_vs_numpy: float | None = None


@dataclass
class Check:
    """Agreement of one method's counts with the NumPy reference.

    Attributes
    ----------
    resolution, width, height : int
        The configuration.
    method : str
        The method checked.
    differing_voxels : int
        Voxels whose segmented or visible count differs from the reference.
    unexplained_voxels : int
        Differing voxels *not* within :data:`BORDER_TOL` px of a pixel border in any frame.
    agrees : bool
        ``unexplained_voxels == 0``.
    """

    resolution: int
    width: int
    height: int
    method: str
    differing_voxels: int
    unexplained_voxels: int
    agrees: bool


# --------------------------------------------------------------------------------------
# Implementations
# --------------------------------------------------------------------------------------


def _world2cam(cam2world: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Rigid inverse of a ``(4, 4)`` pose."""
    out = np.eye(4)
    rot = cam2world[:3, :3]
    out[:3, :3] = rot.T
    out[:3, 3] = -rot.T @ cam2world[:3, 3]
    return out


def _voxel_centres(origin: Sequence[float], size: float, r: int) -> npt.NDArray[np.float64]:
    """World coordinates of all voxel centres, ``(R³, 3)`` in C order of ``[x, y, z]``."""
    h = size / r
    axes = [o + (np.arange(r, dtype=np.float64) + 0.5) * h for o in origin]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.reshape(-1) for g in grid], axis=1)


def _project(
    centres: npt.NDArray[np.float64], cam: CameraSpec, cam2world: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
    """Continuous pixel coordinates ``(u + 0.5, v + 0.5)`` and the in-image flag.

    The pixel of a point is ``(floor(uf), floor(vf))``; NaN where the point is behind
    the camera.
    """
    w2c = _world2cam(cam2world)
    xw, yw, zw = centres[:, 0], centres[:, 1], centres[:, 2]
    # Element-wise rather than ``centres @ R.T``: no BLAS threads, and the same order of
    # operations as the numba kernel.
    x, y, z = ((w2c[i, 0] * xw + w2c[i, 1] * yw + w2c[i, 3]) + w2c[i, 2] * zw for i in range(3))
    front = z > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        uf = np.where(front, cam.fx * x / z + (cam.cx + 0.5), np.nan)
        vf = np.where(front, cam.fy * y / z + (cam.cy + 0.5), np.nan)
    inside = front & (uf >= 0.0) & (uf < cam.width) & (vf >= 0.0) & (vf < cam.height)
    return uf, vf, inside


def carve_numpy(
    origin: Sequence[float],
    size: float,
    resolution: int,
    cam: CameraSpec,
    cam2worlds: npt.NDArray[np.float64],
    masks: npt.NDArray[np.uint8],
) -> Counts:
    """Plain NumPy reference of ``OccupancyGrid.integrate_many`` (float64 throughout).

    Parameters
    ----------
    origin : sequence of float
        Minimum corner of the grid cube.
    size : float
        Side of the cube.
    resolution : int
        Voxels per side R.
    cam : CameraSpec
        The camera of every frame.
    cam2worlds : numpy.ndarray, shape (N, 4, 4)
        Camera poses.
    masks : numpy.ndarray, shape (N, H, W), uint8
        Silhouettes (nonzero = set).

    Returns
    -------
    Counts
        ``(segmented, visible)`` as uint32 ``(R, R, R)`` arrays.
    """
    centres = _voxel_centres(origin, size, resolution)
    seg = np.zeros(len(centres), dtype=np.uint32)
    vis = np.zeros(len(centres), dtype=np.uint32)
    flat = masks.reshape(len(masks), -1)
    for pose, mask in zip(cam2worlds, flat, strict=True):
        uf, vf, inside = _project(centres, cam, pose)
        u = np.where(inside, uf, 0.0).astype(np.intp)
        v = np.where(inside, vf, 0.0).astype(np.intp)
        hit = (mask[v * cam.width + u] != 0) & inside
        np.add(vis, inside, out=vis, casting="unsafe")
        np.add(seg, hit, out=seg, casting="unsafe")
    shape = (resolution,) * 3
    return seg.reshape(shape), vis.reshape(shape)


_NUMBA_KERNEL: Callable[..., None] | None = None


def _numba_kernel() -> Callable[..., None]:
    """Compiles (once) and returns the numba carving kernel.

    Raises
    ------
    ImportError
        When numba is not installed.
    """
    global _NUMBA_KERNEL
    if _NUMBA_KERNEL is not None:
        return _NUMBA_KERNEL
    numba = importlib.import_module("numba")
    prange = numba.prange

    def kernel(
        rot: Any,
        trans: Any,
        masks: Any,
        origin: Any,
        h: float,
        r: int,
        fx: float,
        fy: float,
        cxh: float,
        cyh: float,
        width: int,
        height: int,
        seg: Any,
        vis: Any,
    ) -> None:  # pragma: no cover - runs compiled
        n = rot.shape[0]
        for a in prange(r):
            xw = origin[0] + (a + 0.5) * h
            for b in range(r):
                yw = origin[1] + (b + 0.5) * h
                for f in range(n):
                    x0 = rot[f, 0, 0] * xw + rot[f, 0, 1] * yw + trans[f, 0]
                    y0 = rot[f, 1, 0] * xw + rot[f, 1, 1] * yw + trans[f, 1]
                    z0 = rot[f, 2, 0] * xw + rot[f, 2, 1] * yw + trans[f, 2]
                    for c in range(r):
                        zw = origin[2] + (c + 0.5) * h
                        x = x0 + rot[f, 0, 2] * zw
                        y = y0 + rot[f, 1, 2] * zw
                        z = z0 + rot[f, 2, 2] * zw
                        if z > 0.0:
                            uf = fx * x / z + cxh
                            vf = fy * y / z + cyh
                            if uf >= 0.0 and uf < width and vf >= 0.0 and vf < height:
                                vis[a, b, c] += 1
                                if masks[f, int(vf), int(uf)] != 0:
                                    seg[a, b, c] += 1

    compiled: Callable[..., None] = numba.njit(parallel=True, cache=False)(kernel)
    _NUMBA_KERNEL = compiled
    return compiled


def carve_numba(
    origin: Sequence[float],
    size: float,
    resolution: int,
    cam: CameraSpec,
    cam2worlds: npt.NDArray[np.float64],
    masks: npt.NDArray[np.uint8],
) -> Counts:
    """The reference as an ``@njit(parallel=True)`` loop over x-slabs (needs numba).

    Parameters and return value as for :func:`carve_numpy`. The first call compiles
    the kernel.

    Raises
    ------
    ImportError
        When numba is not installed.
    """
    kernel = _numba_kernel()
    w2c = np.stack([_world2cam(p) for p in cam2worlds])
    shape = (resolution,) * 3
    seg = np.zeros(shape, dtype=np.uint32)
    vis = np.zeros(shape, dtype=np.uint32)
    kernel(
        np.ascontiguousarray(w2c[:, :3, :3]),
        np.ascontiguousarray(w2c[:, :3, 3]),
        np.ascontiguousarray(masks),
        np.asarray(origin, dtype=np.float64),
        size / resolution,
        resolution,
        cam.fx,
        cam.fy,
        cam.cx + 0.5,
        cam.cy + 0.5,
        cam.width,
        cam.height,
        seg,
        vis,
    )
    return seg, vis


# --------------------------------------------------------------------------------------
# Verification
# --------------------------------------------------------------------------------------


def near_pixel_border(
    flat_indices: npt.NDArray[np.intp],
    origin: Sequence[float],
    size: float,
    resolution: int,
    cam: CameraSpec,
    cam2worlds: npt.NDArray[np.float64],
    tol: float = BORDER_TOL,
) -> npt.NDArray[np.bool_]:
    """Which voxels project within ``tol`` px of a pixel border in at least one frame.

    Parameters
    ----------
    flat_indices : numpy.ndarray of int
        Flat (C-order) indices of the voxels to test.
    origin, size, resolution, cam, cam2worlds
        As for :func:`carve_numpy`.
    tol : float, optional
        Distance in pixels.

    Returns
    -------
    numpy.ndarray of bool
        One flag per entry of ``flat_indices``.
    """
    centres = _voxel_centres(origin, size, resolution)[flat_indices]
    near = np.zeros(len(centres), dtype=bool)
    for pose in cam2worlds:
        uf, vf, _ = _project(centres, cam, pose)
        with np.errstate(invalid="ignore"):
            du = np.abs(uf - np.round(uf))
            dv = np.abs(vf - np.round(vf))
            near |= (du < tol) | (dv < tol)
    return near


def compare_counts(
    counts: Counts,
    reference: Counts,
    origin: Sequence[float],
    size: float,
    resolution: int,
    cam: CameraSpec,
    cam2worlds: npt.NDArray[np.float64],
) -> tuple[int, int]:
    """Counts voxels that differ from ``reference``, and those not explained by rounding.

    Returns
    -------
    differing : int
        Voxels whose segmented or visible count differs.
    unexplained : int
        Differing voxels not within :data:`BORDER_TOL` px of a pixel border in any frame.
    """
    differ = (counts[0] != reference[0]) | (counts[1] != reference[1])
    idx = np.flatnonzero(differ)
    if idx.size == 0:
        return 0, 0
    near = near_pixel_border(idx, origin, size, resolution, cam, cam2worlds)
    return int(idx.size), int(np.count_nonzero(~near))


# --------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------


def _timed_runs(
    run_once: Callable[[], object],
    setup: Callable[[], object] | None,
    repeats: int,
    max_seconds: float,
) -> list[float]:
    """Times ``run_once`` up to ``repeats`` times (at least once).

    Stops early when the next run would take the total past ``max_seconds`` (the
    estimate being the last run's time). ``setup`` runs before each run, untimed.
    """
    times: list[float] = []
    while len(times) < repeats:
        if times and sum(times) + times[-1] > max_seconds:
            break
        if setup is not None:
            setup()
        t0 = time.perf_counter()
        run_once()
        times.append(time.perf_counter() - t0)
    return times


def _optional_module(name: str) -> Any | None:
    """The module ``name``, or ``None`` when it cannot be imported."""
    try:
        return importlib.import_module(name)
    except Exception:  # ImportError, or a broken binary wheel (missing shared library)
        return None


def _dist_version(name: str) -> str | None:
    """Installed version of distribution ``name`` (without importing it), or ``None``."""
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None


def machine_info() -> dict[str, Any]:
    """Describes the machine and the library builds the benchmark ran with.

    Returns
    -------
    dict
        CPU model and count, platform, Python, heapgrasp (version, kernel level, threads),
        NumPy and the installed numba / Open3D versions (read from the package metadata,
        without importing them).
    """
    cpu_model = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu_model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "cpu_model": cpu_model,
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "heapgrasp": heapgrasp.__version__,
        "kernel_level": heapgrasp.kernel_level(),
        "num_threads": heapgrasp.num_threads(),
        "numpy": np.__version__,
        "numba": _dist_version("numba"),
        "open3d": _dist_version("open3d"),
    }


def _median(times: list[float]) -> float:
    return float(statistics.median(times))


def _bench_rust(
    r: int,
    cam: CameraSpec,
    poses: npt.NDArray[np.float64],
    masks: npt.NDArray[np.uint8],
    repeats: int,
    max_seconds: float,
) -> tuple[list[float], Counts]:
    grid = heapgrasp.OccupancyGrid(ORIGIN, CUBE, r)
    pcam = heapgrasp.PinholeCamera(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
    grid.integrate_many(masks, pcam, poses)  # warm-up (thread pool, page faults)
    times = _timed_runs(
        lambda: grid.integrate_many(masks, pcam, poses), grid.reset, repeats, max_seconds
    )
    seg, vis = grid.counts()
    return times, (np.asarray(seg, dtype=np.uint32), np.asarray(vis, dtype=np.uint32))


def _bench_counting(
    fn: Callable[..., Counts],
    r: int,
    cam: CameraSpec,
    poses: npt.NDArray[np.float64],
    masks: npt.NDArray[np.uint8],
    repeats: int,
    max_seconds: float,
) -> tuple[list[float], Counts]:
    out: list[Counts] = []
    times = _timed_runs(
        lambda: out.append(fn(ORIGIN, CUBE, r, cam, poses, masks)),
        out.clear,
        repeats,
        max_seconds,
    )
    return times, out[-1]


def _bench_open3d(
    o3d: Any,
    r: int,
    cam: CameraSpec,
    poses: npt.NDArray[np.float64],
    masks: npt.NDArray[np.uint8],
    repeats: int,
    max_seconds: float,
) -> tuple[list[float], int]:
    h = CUBE / r
    params = []
    for pose in poses:
        p = o3d.camera.PinholeCameraParameters()
        p.intrinsic = o3d.camera.PinholeCameraIntrinsic(
            cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy
        )
        p.extrinsic = _world2cam(pose)
        params.append(p)
    images = [o3d.geometry.Image(np.ascontiguousarray(m, dtype=np.float32)) for m in masks]
    state: dict[str, Any] = {}

    def setup() -> None:
        state["grid"] = o3d.geometry.VoxelGrid.create_dense(
            np.asarray(ORIGIN, dtype=np.float64), np.zeros(3), h, CUBE, CUBE, CUBE
        )

    def run_once() -> None:
        grid = state["grid"]
        for img, p in zip(images, params, strict=True):
            grid.carve_silhouette(img, p, keep_voxels_outside_image=True)

    times = _timed_runs(run_once, setup, repeats, max_seconds)
    return times, len(state["grid"].get_voxels())


def run(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp bench carve`` with parsed arguments.

    Parameters
    ----------
    args : argparse.Namespace
        The options declared by :func:`heapgrasp.cli.bench.add_carve`.

    Returns
    -------
    int
        0 when every checked method agrees with the NumPy reference, 1 otherwise.
    """
    sizes: tuple[int, ...] = args.sizes or (QUICK_SIZES if args.quick else DEFAULT_SIZES)
    images: tuple[tuple[int, int], ...] = args.images or (
        QUICK_IMAGES if args.quick else DEFAULT_IMAGES
    )
    methods: tuple[str, ...] = args.methods
    views: int = args.views
    info = machine_info()
    poses = ring(views)
    scenes = {
        (w, h): (camera_spec(w, h), sphere_masks(camera_spec(w, h), poses)) for w, h in images
    }
    configs = [(r, w, h) for w, h in images for r in sizes]

    results: list[Result] = []
    checks: list[Check] = []
    counts: dict[tuple[int, int, int], dict[str, Counts]] = {c: {} for c in configs}
    numba_compile_s: float | None = None
    bar = tqdm(
        total=len(configs) * len(methods),
        file=sys.stderr,
        unit="run",
        disable=args.no_progress,
        dynamic_ncols=True,
    )
    # Methods form the outer loop, Rust first: numba's OpenMP pool and Open3D are only
    # loaded after the Rust kernel has been timed (loading them was seen to slow the
    # threaded Rust kernel down in the same process).
    for method in methods:
        module: Any | None = None
        if method in ("numba", "open3d"):
            module = _optional_module(method)
        if method == "numba" and module is not None:
            t0 = time.perf_counter()
            tiny = camera_spec(8, 6)
            one = ring(1)
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message=".*TBB threading layer.*")
                carve_numba(ORIGIN, CUBE, 2, tiny, one, sphere_masks(tiny, one))
            numba_compile_s = time.perf_counter() - t0
        for r, width, height in configs:
            cam, masks = scenes[(width, height)]
            bar.set_description(f"{r}^3 {width}x{height} {method}")
            res = Result(r, width, height, views, method)
            repeats = args.repeats or DEFAULT_REPEATS[method]
            got = counts[(r, width, height)]
            if method == "rust":
                res.times_s, got[method] = _bench_rust(
                    r, cam, poses, masks, repeats, args.max_seconds
                )
            elif method == "numpy":
                res.times_s, got[method] = _bench_counting(
                    carve_numpy, r, cam, poses, masks, repeats, args.max_seconds
                )
            elif module is None:
                res.status, res.note = "skipped", "skipped (not installed)"
            elif method == "numba":
                res.times_s, got[method] = _bench_counting(
                    carve_numba, r, cam, poses, masks, repeats, args.max_seconds
                )
            else:
                res.times_s, left = _bench_open3d(
                    module, r, cam, poses, masks, repeats, args.max_seconds
                )
                res.note = f"removes voxels ({left} of {r**3} left); not compared"
            if res.times_s:
                res.median_s = _median(res.times_s)
                res.projections_per_s = r**3 * views / res.median_s
            results.append(res)
            bar.update(1)
    bar.close()

    for (r, width, height), got in counts.items():
        if "numpy" not in got:
            continue
        cam = scenes[(width, height)][0]
        for method in ("rust", "numba"):
            if method in got:
                diff, unexplained = compare_counts(
                    got[method], got["numpy"], ORIGIN, CUBE, r, cam, poses
                )
                checks.append(Check(r, width, height, method, diff, unexplained, unexplained == 0))
    del counts

    for res in results:
        ref = next(
            (
                x
                for x in results
                if x.method == "numpy"
                and x.median_s is not None
                and (x.resolution, x.width, x.height) == (res.resolution, res.width, res.height)
            ),
            None,
        )
        if ref is not None and ref.median_s is not None and res.median_s is not None:
            res.speedup_vs_numpy = ref.median_s / res.median_s

    print(format_report(info, results, checks, numba_compile_s))
    sys.stdout.flush()  # before any native runtime's teardown at exit
    if args.json is not None:
        payload = {
            "benchmark": "carve",
            "command": " ".join(["heapgrasp", *getattr(args, "argv", ["bench", "carve"])]),
            "machine": info,
            "config": {
                "sizes": list(sizes),
                "images": [f"{w}x{h}" for w, h in images],
                "views": views,
                "methods": list(methods),
                "repeats": args.repeats,
                "default_repeats": DEFAULT_REPEATS,
                "max_seconds": args.max_seconds,
                "border_tol_px": BORDER_TOL,
                "cube": CUBE,
                "origin": list(ORIGIN),
            },
            "numba_compile_s": numba_compile_s,
            "results": [asdict(r) for r in results],
            "checks": [asdict(c) for c in checks],
        }
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(payload, fh, indent=2)
            fh.write("\n")
    return 0 if all(c.agrees for c in checks) else 1


# --------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------

_LABELS = {"rust": "Rust", "numpy": "NumPy", "numba": "numba", "open3d": "Open3D"}


def _fmt(x: float | None, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def format_report(
    info: dict[str, Any],
    results: Sequence[Result],
    checks: Sequence[Check],
    numba_compile_s: float | None = None,
) -> str:
    """Renders the results as a plain-text (Markdown-compatible) table.

    Parameters
    ----------
    info : dict
        :func:`machine_info`.
    results : sequence of Result
        Timings.
    checks : sequence of Check
        Agreement with the NumPy reference.
    numba_compile_s : float, optional
        numba's compile time, reported separately (not in the timings).

    Returns
    -------
    str
        The report.
    """
    lines = [
        f"machine: {info['cpu_model']}, {info['cpu_count']} CPUs, "
        f"heapgrasp {info['heapgrasp']} (kernel {info['kernel_level']}, "
        f"{info['num_threads']} threads), numpy {info['numpy']}, "
        f"numba {info['numba'] or '-'}, open3d {info['open3d'] or '-'}",
        "",
        "| grid | image | method | runs | median [s] | voxel-proj/s | vs NumPy |",
        "|---|---|---|--:|--:|--:|--:|",
    ]
    notes: list[str] = []
    for r in results:
        label = _LABELS.get(r.method, r.method)
        if r.status != "ok":
            lines.append(
                f"| {r.resolution}³ | {r.width}x{r.height} | {label} | - | {r.note} | - | - |"
            )
            continue
        speed = "-" if r.speedup_vs_numpy is None else f"{r.speedup_vs_numpy:.1f}x"
        lines.append(
            f"| {r.resolution}³ | {r.width}x{r.height} | {label} | {len(r.times_s)} "
            f"| {_fmt(r.median_s, '.4g')} | {_fmt(r.projections_per_s, '.2e')} | {speed} |"
        )
        if r.note:
            notes.append(f"{label} {r.resolution}³ {r.width}x{r.height}: {r.note}")
    lines.append("")
    skipped = sorted({_LABELS[r.method] for r in results if r.status != "ok"})
    for name in skipped:
        lines.append(f"{name}: skipped (not installed)")
    if numba_compile_s is not None:
        lines.append(f"numba compile time (excluded): {numba_compile_s:.2f} s")
    lines.extend(notes)
    if checks:
        lines.append("")
        lines.append(
            f"counts vs NumPy reference (tolerance: voxels within {BORDER_TOL:g} px "
            "of a pixel border):"
        )
        for c in checks:
            if c.differing_voxels == 0:
                verdict = "agree (identical)"
            elif c.agrees:
                verdict = (
                    f"agree ({c.differing_voxels} voxels differ, all within "
                    f"{BORDER_TOL:g} px of a pixel border)"
                )
            else:
                verdict = (
                    f"DISAGREE ({c.differing_voxels} voxels differ, "
                    f"{c.unexplained_voxels} not near a pixel border)"
                )
            lines.append(
                f"  {_LABELS[c.method]:<6} {c.resolution}³ {c.width}x{c.height}: {verdict}"
            )
    else:
        lines.append("counts not checked (the NumPy reference did not run)")
    return "\n".join(lines)
