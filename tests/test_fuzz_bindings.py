"""Fuzzing every entry point of ``heapgrasp._core`` (issue 36).

Each test draws the arguments of one entry point around a valid call and corrupts some
of them: wrong dtypes (big-endian ones included), shapes and numbers of dimensions,
memory layouts (Fortran, strided, negative strides, broadcast, unaligned, read-only,
ndarray subclasses), NaN / inf / extreme values, empty arrays, sizes far beyond any
allocation (integers up to 2**80, arrays whose shape claims terabytes), booleans where
numbers are expected, and objects of the wrong type. The call must either

- return a result that passes the entry point's invariants (shapes, dtypes, value
  ranges, and where cheap the documented definition), or
- raise a ``heapgrasp.HeapgraspError`` subclass whose message names one of the entry
  point's arguments; a failed call that mutates must change nothing.

Any other exception (``TypeError``, ``OverflowError``, pyo3's ``PanicException``) fails
the test. A call running longer than ``HEAPGRASP_FUZZ_HANG_S`` seconds (default 120)
aborts the process with every thread's traceback (``faulthandler``): a hang cannot
pass. Examples are kept small (grids of at most 8³ voxels, images of at most 12 × 10
pixels), and valid sizes are drawn small while invalid ones are drawn huge, so a size
that is accepted when it should be refused shows up as a failure or an abort, never as
a silent allocation.

Budget: ``HEAPGRASP_FUZZ_EXAMPLES`` examples per test (default 25: the normal suite).
``scripts/fuzz`` runs the same tests with many more and prints the tally of calls per
entry point and outcome (written to ``HEAPGRASP_FUZZ_REPORT`` when set).
"""

from __future__ import annotations

import copy
import faulthandler
import json
import math
import os
import pickle
from collections import Counter, defaultdict
from collections.abc import Callable, Sequence
from datetime import timedelta
from types import MappingProxyType
from typing import Any

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref
from heapgrasp import _core
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

EXAMPLES = int(os.environ.get("HEAPGRASP_FUZZ_EXAMPLES", "25"))
HANG_S = float(os.environ.get("HEAPGRASP_FUZZ_HANG_S", "120"))

FUZZ = settings(
    max_examples=EXAMPLES,
    # A generous per-example deadline (examples take milliseconds); real hangs are caught
    # by the faulthandler watchdog in `call`.
    deadline=timedelta(seconds=20),
    database=None,
    suppress_health_check=list(HealthCheck),
    print_blob=True,
)

# entry point -> outcome ("ok", an error class name, "FAILED") -> calls
TALLY: defaultdict[str, Counter[str]] = defaultdict(Counter)
EXAMPLES_RUN: Counter[str] = Counter()

MAX_SIDE = 16_384  # heapgrasp-core camera::MAX_IMAGE_SIDE
MAX_RES = 512  # heapgrasp-core grid::MAX_RESOLUTION


@pytest.fixture(scope="module", autouse=True)
def _report():
    yield
    path = os.environ.get("HEAPGRASP_FUZZ_REPORT")
    if path:
        with open(path, "w", encoding="utf-8") as f:
            json.dump(
                {"examples": dict(EXAMPLES_RUN), "calls": {k: dict(v) for k, v in TALLY.items()}},
                f,
                indent=1,
                sort_keys=True,
            )


class Refused:
    """A call that raised a HeapgraspError."""

    def __init__(self, error: hg.HeapgraspError) -> None:
        self.error = error


def call(entry: str, names: Sequence[str], fn: Callable[..., Any], *args: Any, **kw: Any) -> Any:
    """``fn(*args, **kw)``, or a :class:`Refused` for a HeapgraspError naming one of
    ``names``; anything else fails."""
    faulthandler.dump_traceback_later(HANG_S, exit=True)
    try:
        out = fn(*args, **kw)
    except hg.HeapgraspError as e:
        TALLY[entry][type(e).__name__] += 1
        msg = str(e)
        assert any(n in msg for n in names), (
            f"{entry}: {type(e).__name__}({msg!r}) names none of its arguments {list(names)}"
        )
        return Refused(e)
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as e:  # PanicException derives from BaseException
        TALLY[entry]["FAILED"] += 1
        raise AssertionError(
            f"{entry} raised {type(e).__module__}.{type(e).__qualname__}: {e}"
        ) from e
    finally:
        faulthandler.cancel_dump_traceback_later()
    TALLY[entry]["ok"] += 1
    return out


def ok(x: Any) -> bool:
    return not isinstance(x, Refused)


def is_bool(x: Any) -> bool:
    return isinstance(x, bool | np.bool_)


def has_bool(v: Any) -> bool:
    """Whether ``v`` is a bool, holds one, or is a bool array."""
    if isinstance(v, np.ndarray):
        return v.dtype == np.bool_
    return is_bool(v) or (isinstance(v, list | tuple) and any(is_bool(x) for x in v))


# ---------------------------------------------------------------------------- scalars
OBJECTS = st.sampled_from(
    [None, "1", "nan", b"4", 1j, [], [1.0], (2,), {}, {"a": 1}, object(), np.zeros(2), Ellipsis]
)
BOOLS = st.sampled_from([True, False, np.True_, np.False_])
HUGE_INTS = st.one_of(
    st.sampled_from([2**31 - 1, 2**31, 2**32 - 1, 2**32, 2**63 - 1, 2**63, 2**64, -(2**63)]),
    st.integers(min_value=2**20, max_value=2**80),
    st.integers(min_value=-(2**80), max_value=-1),
)
EXTREME_FLOATS = st.sampled_from(
    [
        0.0,
        -0.0,
        5e-324,
        -5e-324,
        1e-300,
        1.4e-45,
        1.1754943508222875e-38,
        3.4028234663852886e38,
        3.5e38,
        1e300,
        1.7976931348623157e308,
        -1.7976931348623157e308,
        math.nan,
        math.inf,
        -math.inf,
    ]
)
ANY_FLOAT = st.one_of(EXTREME_FLOATS, st.floats(allow_nan=True, allow_infinity=True))


def numpy_scalars(values: st.SearchStrategy[Any]) -> st.SearchStrategy[Any]:
    """The same values as NumPy scalars of a few types (where representable)."""

    def conv(x: Any, t: type) -> Any:
        with np.errstate(all="ignore"):
            try:
                return t(x)
            except (OverflowError, ValueError):
                return x

    return st.tuples(values, st.sampled_from([np.int64, np.int32, np.uint64, np.float64])).map(
        lambda p: conv(*p)
    )


def int_arg(lo: int, hi: int) -> st.SearchStrategy[Any]:
    """An integer argument whose valid range is ``lo..=hi`` (drawn small)."""
    near = st.integers(min_value=lo - 3, max_value=min(hi, lo + 12) + 3)
    return st.one_of(
        near,
        near,
        near,
        st.integers(min_value=hi - 2, max_value=hi + 2),
        HUGE_INTS,
        BOOLS,
        numpy_scalars(st.one_of(near, HUGE_INTS)),
        st.floats(min_value=lo, max_value=lo + 8),
        EXTREME_FLOATS,
        OBJECTS,
    )


def float_arg(valid: st.SearchStrategy[float]) -> st.SearchStrategy[Any]:
    """A float argument: mostly ``valid``, else extreme values, ints, bools, objects."""
    return st.one_of(
        valid,
        valid,
        valid,
        ANY_FLOAT,
        st.integers(min_value=-3, max_value=3),
        HUGE_INTS,
        BOOLS,
        numpy_scalars(valid),
        valid.map(np.float32),
        OBJECTS,
    )


def vec3_arg(valid: st.SearchStrategy[tuple[float, float, float]]) -> st.SearchStrategy[Any]:
    """A 3-vector argument in many containers, with bad lengths and elements."""
    return st.one_of(
        valid,
        valid,
        valid.map(list),
        valid.map(np.array),
        valid.map(lambda v: np.array(v, np.float32)),
        st.lists(ANY_FLOAT, min_size=0, max_size=5).map(tuple),
        st.lists(st.one_of(BOOLS, OBJECTS, HUGE_INTS), min_size=3, max_size=3),
        st.sampled_from(
            [range(3), range(10**18), "abc", b"abc", np.zeros((1, 3)), np.zeros((3, 1))]
        ),
        BOOLS,
        OBJECTS,
    )


# ----------------------------------------------------------------------------- arrays
class Sub(np.ndarray):
    """An ndarray subclass (accepted as the ndarray it is)."""


def unaligned(a: np.ndarray) -> np.ndarray:
    buf = np.zeros(a.nbytes + a.itemsize + 1, np.uint8)
    u = np.frombuffer(buf.data, dtype=a.dtype, count=a.size, offset=1).reshape(a.shape)
    u[...] = a
    return u


def negative_strides(a: np.ndarray) -> np.ndarray:
    if a.ndim == 0:
        return a
    return np.flip(np.flip(a, 0).copy(), 0)


def strided(a: np.ndarray) -> np.ndarray:
    if a.ndim == 0:
        return a
    return np.repeat(a, 2, axis=-1)[..., ::2]


def readonly(a: np.ndarray) -> np.ndarray:
    b = a.copy()
    b.setflags(write=False)
    return b


def swapped(a: np.ndarray) -> np.ndarray:
    return a.astype(a.dtype.newbyteorder())


# Layouts holding the same values as the C-contiguous array: a call that accepts one
# must give the same result as with the C array.
SAME_VALUES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "readonly": readonly,
    "subclass": lambda a: a.view(Sub),
    "fortran": np.asfortranarray,
    "strided": strided,
    "negative_strides": negative_strides,
    "unaligned": unaligned,
    "byteswapped": swapped,
}

OTHER_DTYPES = [
    np.bool_,
    np.uint8,
    np.int8,
    np.int16,
    np.int32,
    np.uint32,
    np.int64,
    np.uint64,
    np.float16,
    np.float32,
    np.float64,
    np.complex128,
    np.dtype(">f8"),
    np.dtype(">u4"),
    object,
]


def recast(a: np.ndarray, dtype: Any) -> np.ndarray:
    with np.errstate(all="ignore"):
        if a.dtype.kind == "c" and np.dtype(dtype).kind != "c":
            a = a.real
        return a.astype(dtype)


@st.composite
def array_variant(draw: st.DrawFn, a: np.ndarray) -> tuple[Any, bool]:
    """``(x, same)``: ``a`` (C-contiguous) or a variant of it; ``same``: ``x`` holds
    ``a``'s values in ``a``'s dtype (only the layout may differ; see ``maybe_array``)."""
    kind = draw(
        st.sampled_from(
            [
                "c",
                *SAME_VALUES,
                *["dtype", "list", "broadcast", "ndim+", "ndim-", "reshape", "0d"],
                *["empty", "huge_empty", "huge_broadcast", "object"],
            ]
        )
    )
    if kind == "c":
        return a, True
    if kind in SAME_VALUES:
        return SAME_VALUES[kind](a), True
    if kind == "dtype":
        return recast(a, draw(st.sampled_from(OTHER_DTYPES))), False
    if kind == "list":
        return a.tolist(), False
    if kind == "broadcast":
        if a.ndim == 0 or a.size == 0:
            return a, True
        return np.broadcast_to(a[..., :1], a.shape), False
    if kind == "ndim+":
        return a[None], False
    if kind == "ndim-":
        return (a[0] if a.ndim and a.shape[0] else a.reshape(-1)), False
    if kind == "reshape":
        shape = draw(st.lists(st.integers(0, 6), min_size=0, max_size=5).map(tuple))
        return np.resize(a, shape) if a.size else np.zeros(shape, a.dtype), False
    if kind == "0d":
        return np.asarray(a.flat[0] if a.size else 0, dtype=a.dtype), False
    if kind == "empty":
        shape = tuple(0 if i == 0 else s for i, s in enumerate(a.shape)) or (0,)
        return np.zeros(shape, a.dtype), False
    if kind == "huge_empty":
        # Zero elements, but sides far beyond any grid or image: never allocated.
        sides = [draw(st.sampled_from([1, 3, 2**20, 2**31])) for _ in range(max(a.ndim, 1))]
        sides[draw(st.integers(0, len(sides) - 1))] = 0
        while math.prod(x for x in sides if x) > 2**52:  # NumPy's limit on nbytes
            sides[sides.index(max(sides))] = 3
        return np.empty(tuple(sides), a.dtype), False
    if kind == "huge_broadcast":
        # Terabytes of elements that share one: refused as not C-contiguous.
        sides = [2**20] * max(a.ndim, 1)
        while math.prod(sides) > 2**56:  # NumPy's limit on nbytes
            sides[sides.index(max(sides))] = 3
        return np.broadcast_to(np.zeros((), a.dtype), tuple(sides)), False
    return np.array(a.tolist() if a.ndim else a.item(), dtype=object), False


def borrowable(x: Any, dtypes: Sequence[Any]) -> bool:
    """Whether ``x`` is an array the bindings can borrow as one of ``dtypes`` (native byte
    order): C-contiguous and aligned. Any other array must be refused."""
    return (
        isinstance(x, np.ndarray)
        and any(x.dtype == np.dtype(d) for d in dtypes)
        and x.flags.c_contiguous
        and x.flags.aligned
    )


def same_array(x: Any, a: np.ndarray) -> bool:
    """Whether ``x`` is a borrowable array of ``a``'s dtype, shape and values."""
    if not borrowable(x, [a.dtype]) or x.shape != a.shape:
        return False
    if a.dtype == np.bool_:
        return bool(np.array_equal(np.asarray(x).view(np.uint8), a.view(np.uint8)))
    return bool(np.array_equal(x, a, equal_nan=a.dtype.kind in "fc"))


def valid_cloud(x: Any) -> bool:
    """Whether ``x`` is a point cloud the bindings must accept: a borrowable float64
    ``(m, 3)`` array of finite values, ``m`` ≥ 0."""
    return (
        borrowable(x, [np.float64])
        and x.ndim == 2
        and x.shape[1] == 3
        and bool(np.isfinite(x).all())
    )


def maybe_array(a: np.ndarray, bad: bool = True) -> st.SearchStrategy[tuple[Any, bool]]:
    """``(x, same)``: ``a`` (C-contiguous) itself unless ``bad``, else a variant of it or a
    non-array object; ``same``: ``x`` is ``a`` to the bindings, a borrowable array of
    ``a``'s dtype, shape and values (a read-only array, a subclass, a copy), which must
    give ``a``'s result. A call that accepts anything else fails its test."""
    if not bad:
        return st.just((a, True))
    return st.one_of(
        array_variant(a).map(lambda xs: (xs[0], same_array(xs[0], a))),
        array_variant(a).map(lambda xs: (xs[0], same_array(xs[0], a))),
        st.tuples(st.one_of(OBJECTS, BOOLS, HUGE_INTS), st.just(False)),
    )


class Plan:
    """Which arguments of one call to corrupt: none a third of the time, else one or two
    (the others are drawn valid, so that every error path and the valid path are both
    reached often)."""

    def __init__(self, data: Any, names: Sequence[str]) -> None:
        k = min(data.draw(st.sampled_from([0, 0, 1, 1, 2])), len(names))
        pick = st.lists(st.sampled_from(list(names)), min_size=k, max_size=k, unique=True)
        self.bad = frozenset(data.draw(pick))

    def __contains__(self, name: str) -> bool:
        return name in self.bad


def canonical(x: Any, dtype: Any) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=dtype)


def bool_bytes(draw: st.DrawFn, shape: tuple[int, ...]) -> np.ndarray:
    """A bool array; sometimes holding bytes other than 0 / 1 (a uint8 view)."""
    raw = draw(hnp.arrays(np.uint8, shape, elements=st.sampled_from([0, 1, 1, 2, 255])))
    if draw(st.booleans()):
        return raw.view(np.bool_)
    return (raw != 0).astype(np.bool_)


def f_elements(width: int, lo: float = -1e3, hi: float = 1e3) -> st.SearchStrategy[float]:
    return st.one_of(
        st.floats(lo, hi, width=width),
        st.floats(lo, hi, width=width),
        st.floats(width=width, allow_nan=True, allow_infinity=True),
    )


# ----------------------------------------------------------------------------- poses
@st.composite
def rigid_pose(draw: st.DrawFn, centre=(0.0, 0.0, 0.0), radius: float = 0.6) -> np.ndarray:
    """A cam2world pose looking at (near) ``centre`` from ``radius`` away, or any rotation."""
    q = np.array(draw(st.lists(st.floats(-1, 1), min_size=4, max_size=4)))
    d = np.array(draw(st.lists(st.floats(-1, 1), min_size=3, max_size=3)))
    if np.linalg.norm(d) < 1e-3:
        d = np.array([0.3, -0.2, 0.9])
    eye = np.asarray(centre) + radius * d / np.linalg.norm(d)
    if draw(st.integers(0, 3)) > 0 or np.linalg.norm(q) < 1e-3:
        target = np.asarray(centre) + np.array(
            draw(st.lists(st.floats(-0.05, 0.05), min_size=3, max_size=3))
        )
        return ref.look_at(eye, target)
    w, x, y, z = q / np.linalg.norm(q)
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    return ref.pose_from(rot, eye)


@st.composite
def corrupt_pose(draw: st.DrawFn, p: np.ndarray) -> np.ndarray:
    """A (4, 4) float64 matrix close to or far from the rigid ``p``."""
    p = p.copy()
    kind = draw(st.sampled_from(["scale", "shear", "reflect", "last_row", "value", "translate"]))
    i, j = draw(st.integers(0, 3)), draw(st.integers(0, 3))
    if kind == "scale":
        p[:3, :3] *= draw(st.sampled_from([1 + 1e-12, 1 + 1e-6, 1.01, 0.0, -1.0, 1e300]))
    elif kind == "shear":
        p[0, 1] += draw(st.sampled_from([1e-12, 1e-7, 1e-3, 0.5]))
    elif kind == "reflect":
        p[:3, 0] *= -1
    elif kind == "last_row":
        p[3, j] += draw(st.sampled_from([1e-12, 1e-6, 0.1, 1.0]))
    elif kind == "value":
        p[i, j] = draw(EXTREME_FLOATS)
    else:
        p[:3, 3] = draw(st.sampled_from([1e300, -1e300, 1e30, 3.5e38, 1e-300, 0.0]))
    return p


def rigid_stack(x: Any) -> bool:
    """Whether ``x`` is a borrowable float64 ``(N, 4, 4)`` stack of rigid transforms by the
    core's test (finite, last row exactly [0, 0, 0, 1], |RᵀR - I| and |det R - 1| within
    1e-4)."""
    if not borrowable(x, [np.float64]) or x.ndim != 3 or x.shape[1:] != (4, 4):
        return False
    if not np.isfinite(x).all() or not (x[:, 3] == [0, 0, 0, 1]).all():
        return False
    r = x[:, :3, :3]
    with np.errstate(all="ignore"):
        ortho = np.abs(np.swapaxes(r, 1, 2) @ r - np.eye(3)).max(initial=0)
        det = np.linalg.det(r)
    return bool(ortho <= 1e-4 and (np.abs(det - 1) <= 1e-4).all())


@st.composite
def pose_arg(
    draw: st.DrawFn, centre=(0.0, 0.0, 0.0), radius: float = 0.6, bad: bool = False
) -> tuple[Any, bool]:
    """``(pose, valid)``: a rigid pose unless ``bad``, else a corrupted matrix or a bad
    array / object; ``valid``: a borrowable rigid ``(4, 4)`` float64 transform."""
    p = draw(rigid_pose(centre, radius))
    if not bad:
        return p, True
    if draw(st.booleans()):
        x = draw(corrupt_pose(p))
    else:
        x, _ = draw(maybe_array(p))
    return x, isinstance(x, np.ndarray) and x.ndim == 2 and rigid_stack(x[None])


@st.composite
def poses_arg(
    draw: st.DrawFn, n: int, centre=(0.0, 0.0, 0.0), bad: bool = False
) -> tuple[Any, bool]:
    """``(stack, valid)``: an ``(n, 4, 4)`` stack of rigid poses unless ``bad``, else a
    corrupted one, one of another length, or a bad array / object; ``valid``: a borrowable
    rigid stack (of any length)."""
    ps = np.stack([draw(rigid_pose(centre)) for _ in range(n)]) if n else np.zeros((0, 4, 4))
    if not bad:
        return ps, True
    kind = draw(st.sampled_from(["corrupt", "array", "count"]))
    if kind == "corrupt" and n:
        k = draw(st.integers(0, n - 1))
        x = ps.copy()
        x[k] = draw(corrupt_pose(ps[k]))
    elif kind == "count":
        m = draw(st.integers(0, n + 2))
        x = np.stack([draw(rigid_pose(centre)) for _ in range(m)]) if m else ps[:0]
    else:
        x, _ = draw(maybe_array(ps))
    return x, rigid_stack(x)


# ---------------------------------------------------------------------------- cameras
@st.composite
def small_camera(draw: st.DrawFn) -> _core.PinholeCamera:
    w, h = draw(st.integers(1, 12)), draw(st.integers(1, 10))
    f = draw(st.floats(2.0, 40.0))
    return _core.PinholeCamera(
        w, h, f, f * draw(st.floats(0.8, 1.25)), draw(st.floats(-1, w)), draw(st.floats(-1, h))
    )


NOT_A_CAMERA = st.one_of(OBJECTS, BOOLS, st.just(_core.MeshScene()))


def camera_or_junk(cam: _core.PinholeCamera, bad: bool) -> st.SearchStrategy[Any]:
    return NOT_A_CAMERA if bad else st.just(cam)


# ========================================================================== the tests
SIDE = st.one_of(st.integers(1, 64), st.just(MAX_SIDE))


@FUZZ
@given(data=st.data())
def test_pinhole_camera(data):
    EXAMPLES_RUN["test_pinhole_camera"] += 1
    names = ["width", "height", "fx", "fy", "cx", "cy"]
    plan = Plan(data, names)
    valid = {
        "width": SIDE,
        "height": SIDE,
        "fx": st.floats(0.1, 1e4),
        "fy": st.floats(0.1, 1e4),
        "cx": st.floats(-100, 1e4),
        "cy": st.floats(-100, 1e4),
    }
    bad = {
        "width": int_arg(1, MAX_SIDE),
        "height": int_arg(1, MAX_SIDE),
        "fx": float_arg(st.floats(0.1, 1e4)),
        "fy": float_arg(st.floats(0.1, 1e4)),
        "cx": float_arg(st.floats(-100, 1e4)),
        "cy": float_arg(st.floats(-100, 1e4)),
    }
    args = [data.draw(bad[n] if n in plan else valid[n], label=n) for n in names]
    cam = call("PinholeCamera", names, _core.PinholeCamera, *args)
    if not ok(cam):
        assert plan.bad, "a valid camera was refused"
        return
    assert not any(is_bool(a) for a in args), "a bool was taken for a number"
    assert cam.width == int(args[0]) and cam.height == int(args[1])
    assert 1 <= cam.width <= MAX_SIDE and 1 <= cam.height <= MAX_SIDE
    got = (cam.fx, cam.fy, cam.cx, cam.cy)
    assert got == tuple(float(a) for a in args[2:])
    assert all(math.isfinite(x) for x in got) and cam.fx > 0 and cam.fy > 0
    assert cam.__getnewargs__() == (cam.width, cam.height, *got)
    assert pickle.loads(pickle.dumps(cam)) == cam
    assert copy.deepcopy(cam) == cam and cam != object()


OMIT = object()


@FUZZ
@given(data=st.data(), kind=st.sampled_from(["OccupancyGrid", "TSDFVolume"]))
def test_grid_constructors(data, kind):
    EXAMPLES_RUN["test_grid_constructors"] += 1
    names = ["origin", "size", "resolution"] + (["truncation"] if kind == "TSDFVolume" else [])
    plan = Plan(data, names)
    valid = {
        "origin": st.tuples(*[st.floats(-10, 10)] * 3),
        "size": st.one_of(st.just(OMIT), st.floats(1e-3, 10)),
        "resolution": st.one_of(st.just(OMIT), st.just(None), st.integers(1, 24)),
        "truncation": st.one_of(st.just(OMIT), st.floats(1e-4, 1.0)),
    }
    bad = {
        "origin": vec3_arg(st.tuples(*[st.floats(-10, 10)] * 3)),
        "size": float_arg(st.floats(1e-3, 10)),
        "resolution": int_arg(1, MAX_RES),
        "truncation": float_arg(st.floats(1e-4, 1.0)),
    }
    drawn = {n: data.draw(bad[n] if n in plan else valid[n], label=n) for n in names}
    origin = drawn.pop("origin")
    kw = {k: v for k, v in drawn.items() if v is not OMIT}
    g = call(kind, names, getattr(_core, kind), origin, **kw)
    if not ok(g):
        assert plan.bad, "a valid grid was refused"
        return
    assert not any(is_bool(v) for v in kw.values()), "a bool was taken for a number"
    assert not has_bool(origin), "a bool was taken for a coordinate"
    r = g.resolution
    want_r = 40 if kw.get("resolution") is None else int(kw["resolution"])
    assert r == want_r and 1 <= r <= MAX_RES
    assert g.size == float(kw.get("size", 0.30)) and math.isfinite(g.size) and g.size > 0
    assert g.origin == tuple(float(x) for x in origin)
    if r > 64:
        return  # valid but large (up to 512³ voxels): allocated lazily, not read here
    if kind == "OccupancyGrid":
        assert math.isclose(g.voxel_size, g.size / r, rel_tol=1e-12)
        for c in g.counts():
            assert c.shape == (r, r, r) and c.dtype == np.uint32 and not c.any()
    else:
        assert g.truncation == float(kw.get("truncation", 0.03))
        assert math.isfinite(g.truncation) and g.truncation > 0
        for a in (g.values(), g.weights()):
            assert a.shape == (r, r, r) and a.dtype == np.float32 and not a.any()


# ------------------------------------------------------------------- OccupancyGrid
U32_MAX = 2**32 - 1
COUNT_VALUES = st.one_of(
    st.integers(0, 6),
    st.integers(0, 6),
    st.sampled_from([2**16 - 1, 2**16, 2**24, U32_MAX - 5, U32_MAX - 1, U32_MAX]),
    st.integers(0, U32_MAX),
)


@st.composite
def counts_pair(draw: st.DrawFn, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Valid ``(segmented, visible)`` counts (seg <= vis), often near 2**32 - 1."""
    vis = draw(hnp.arrays(np.uint32, (r, r, r), elements=COUNT_VALUES))
    frac = draw(hnp.arrays(np.float64, (r, r, r), elements=st.sampled_from([0, 0.5, 0.9, 1])))
    seg = np.floor(vis.astype(np.float64) * frac).astype(np.uint32)
    return seg, vis


def check_grid(g: _core.OccupancyGrid, lam: float | None = None) -> None:
    """A grid's reads agree with each other and with eq. 10 in float32."""
    r = g.resolution
    s, v = g.counts()
    assert s.shape == v.shape == (r, r, r) and s.dtype == v.dtype == np.uint32
    assert (s <= v).all()
    occ = g.occupancy()
    assert occ.shape == (r, r, r) and occ.dtype == np.float32
    want = np.zeros_like(occ)
    nz = v > 0
    want[nz] = s[nz].astype(np.float32) / v[nz].astype(np.float32)
    np.testing.assert_array_equal(occ, want)
    assert ((occ >= 0) & (occ <= 1)).all()
    for la in [0.9, 0.0, 1.0] if lam is None else [lam]:
        hc = g.high_confidence(la)
        assert hc.shape == (r, r, r) and hc.dtype == np.float32
        np.testing.assert_array_equal(hc, np.where(occ >= np.float32(la), occ, 0))
        assert g.count_high_confidence(la) == int(np.count_nonzero(hc))


@FUZZ
@given(data=st.data(), r=st.integers(1, 6))
def test_from_counts(data, r):
    EXAMPLES_RUN["test_from_counts"] += 1
    names = ["origin", "size", "segmented", "visible"]
    plan = Plan(data, [*names, "order"])
    seg, vis = data.draw(counts_pair(r))
    if "order" in plan:  # some segmented count above its visible one
        i = data.draw(st.integers(0, seg.size - 1))
        if vis.flat[i] < U32_MAX:
            seg.flat[i] = vis.flat[i] + 1
    seg_x, seg_same = data.draw(maybe_array(seg, "segmented" in plan))
    vis_x, vis_same = data.draw(maybe_array(vis, "visible" in plan))
    vec = st.tuples(*[st.floats(-1, 1)] * 3)
    origin = data.draw(vec3_arg(vec) if "origin" in plan else vec)
    size = data.draw(float_arg(st.floats(0.01, 2.0)) if "size" in plan else st.floats(0.01, 2))
    g = call(
        "OccupancyGrid.from_counts",
        names,
        _core.OccupancyGrid.from_counts,
        origin,
        size,
        seg_x,
        vis_x,
    )
    if not ok(g):
        assert plan.bad, "valid counts were refused"
        return
    assert seg_same and vis_same, "a non-uint32 or reshaped array was taken for counts"
    assert not is_bool(size) and not has_bool(origin)
    assert (seg <= vis).all(), "segmented > visible was accepted"
    s, v = g.counts()
    np.testing.assert_array_equal(s, seg)
    np.testing.assert_array_equal(v, vis)
    check_grid(g)


@st.composite
def grid_with_counts(draw: st.DrawFn) -> _core.OccupancyGrid:
    r = draw(st.integers(1, 8))
    origin = (-0.15, -0.15, draw(st.floats(-0.1, 0.1)))
    if draw(st.booleans()):
        return _core.OccupancyGrid(origin, 0.3, r)
    seg, vis = draw(counts_pair(r))
    return _core.OccupancyGrid.from_counts(origin, 0.3, seg, vis)


GRID_CENTRE = (0.0, 0.0, 0.15)


@st.composite
def masks_arg(
    draw: st.DrawFn, shape: tuple[int, ...], bad: bool = False
) -> tuple[Any, np.ndarray | None]:
    """``(x, as_u8)``: a bool / uint8 mask of ``shape`` (any bytes), or unless ``bad`` a
    variant; ``as_u8``: the 0 / 1 bytes the kernel must see (nonzero = set), or None when
    ``x`` is not a borrowable bool or uint8 array of ``shape``."""
    if draw(st.booleans()):
        m = bool_bytes(draw, shape)
    else:
        m = draw(hnp.arrays(np.uint8, shape, elements=st.integers(0, 255)))
    x, _ = draw(maybe_array(m, bad))
    if not borrowable(x, [np.bool_, np.uint8]) or x.shape != shape:
        return x, None
    return x, (x.view(np.uint8) != 0).astype(np.uint8)


def grid_state(g: _core.OccupancyGrid) -> tuple[np.ndarray, ...]:
    return tuple(a.copy() for a in g.counts())


def assert_state(g: _core.OccupancyGrid, state) -> None:
    for a, b in zip(g.counts(), state, strict=True):
        np.testing.assert_array_equal(a, b)


def reference_integrate(origin, size, counts, masks_u8, cam, poses) -> tuple[np.ndarray, ...]:
    """The counts after integrating frame by frame on one thread into a grid of
    ``counts``."""
    h = _core.OccupancyGrid.from_counts(origin, size, *counts)
    for m, p in zip(masks_u8, poses, strict=True):
        h.integrate_many(m[None], cam, p[None], threads=1)
    return h.counts()


@FUZZ
@given(data=st.data())
def test_occupancy_grid_methods(data):
    EXAMPLES_RUN["test_occupancy_grid_methods"] += 1
    g = data.draw(grid_with_counts())
    cam = data.draw(small_camera())
    for _ in range(data.draw(st.integers(1, 4))):
        op = data.draw(
            st.sampled_from(["integrate", "integrate_many", "lam", "reads", "copy", "reset"])
        )
        before = grid_state(g)
        if op == "integrate":
            names = ["mask", "camera", "cam2world"]
            plan = Plan(data, names)
            mask, as_u8 = data.draw(masks_arg((cam.height, cam.width), "mask" in plan))
            pose, pose_ok = data.draw(pose_arg(GRID_CENTRE, bad="cam2world" in plan))
            camera = data.draw(camera_or_junk(cam, "camera" in plan))
            out = call("OccupancyGrid.integrate", names, g.integrate, mask, camera, pose)
            if not ok(out):
                assert plan.bad, "a valid silhouette was refused"
                assert_state(g, before)
                continue
            assert out is None and as_u8 is not None and camera is cam and pose_ok
            want = reference_integrate(
                g.origin, g.size, before, [as_u8], cam, canonical(pose, np.float64)[None]
            )
            assert_state(g, want)
        elif op == "integrate_many":
            names = ["masks", "camera", "cam2worlds", "threads"]
            plan = Plan(data, names)
            n = data.draw(st.integers(0, 3))
            masks, as_u8 = data.draw(masks_arg((n, cam.height, cam.width), "masks" in plan))
            poses, poses_ok = data.draw(poses_arg(n, GRID_CENTRE, "cam2worlds" in plan))
            camera = data.draw(camera_or_junk(cam, "camera" in plan))
            kw = {}
            if "threads" in plan:
                kw["threads"] = data.draw(int_arg(1, 256))
            elif data.draw(st.booleans()):
                kw["threads"] = data.draw(st.one_of(st.none(), st.integers(1, 8)))
            out = call(
                "OccupancyGrid.integrate_many", names, g.integrate_many, masks, camera, poses, **kw
            )
            if not ok(out):
                assert plan.bad, "valid silhouettes were refused"
                assert_state(g, before)
                continue
            assert out is None and as_u8 is not None and camera is cam
            assert poses_ok and len(poses) == n and not is_bool(kw.get("threads"))
            want = reference_integrate(
                g.origin, g.size, before, as_u8, cam, canonical(poses, np.float64)
            )
            assert_state(g, want)
        elif op == "lam":
            bad = data.draw(st.booleans())
            lam = data.draw(float_arg(st.floats(0, 1)) if bad else st.floats(0, 1))
            for name in ("high_confidence", "count_high_confidence"):
                out = call(f"OccupancyGrid.{name}", ["lam"], getattr(g, name), lam)
                if ok(out):
                    assert not is_bool(lam) and 0 <= float(lam) <= 1
                    check_grid(g, float(lam))
                else:
                    assert bad, "a valid lam was refused"
            assert_state(g, before)
        elif op == "reads":
            check_grid(g)
            TALLY["OccupancyGrid.counts/occupancy/high_confidence"]["ok"] += 1
            assert g.voxel_size == g.size / g.resolution and len(g.origin) == 3
        elif op == "copy":
            for h in (g.copy(), copy.copy(g), copy.deepcopy(g)):
                assert h is not g
                assert_state(h, before)
                h.reset()
                assert_state(g, before)
            TALLY["OccupancyGrid.copy/__copy__/__deepcopy__"]["ok"] += 1
        else:
            g.reset()
            assert not any(a.any() for a in g.counts())
            TALLY["OccupancyGrid.reset"]["ok"] += 1


# ------------------------------------------------------------------------ TSDFVolume
DEPTHS = st.one_of(
    st.floats(0.0625, 2.0, width=32),
    st.floats(0.0625, 2.0, width=32),
    st.sampled_from([0.0, -1.0, 1e-30, 3e38, np.nan, np.inf, -np.inf]),
)


@FUZZ
@given(data=st.data())
def test_tsdf_volume(data):
    EXAMPLES_RUN["test_tsdf_volume"] += 1
    r = data.draw(st.integers(1, 8))
    trunc = data.draw(st.sampled_from([1e-4, 0.01, 0.03, 0.3, 1e30]))
    vol = _core.TSDFVolume((-0.15, -0.15, 0.0), 0.3, r, trunc)
    cam = data.draw(small_camera())
    for _ in range(data.draw(st.integers(1, 3))):
        before = (vol.values().copy(), vol.weights().copy())
        op = data.draw(st.sampled_from(["integrate"] * 3 + ["copy", "reset"]))
        if op == "integrate":
            names = ["depth_m", "camera", "cam2world"]
            plan = Plan(data, names)
            depth = data.draw(hnp.arrays(np.float32, (cam.height, cam.width), elements=DEPTHS))
            depth_x, same = data.draw(maybe_array(depth, "depth_m" in plan))
            pose, pose_ok = data.draw(pose_arg(GRID_CENTRE, bad="cam2world" in plan))
            camera = data.draw(camera_or_junk(cam, "camera" in plan))
            out = call("TSDFVolume.integrate", names, vol.integrate, depth_x, camera, pose)
            if not ok(out):
                assert plan.bad, "a valid depth image was refused"
                np.testing.assert_array_equal(vol.values(), before[0])
                np.testing.assert_array_equal(vol.weights(), before[1])
            else:
                assert same and camera is cam and pose_ok
                assert (vol.weights() >= before[1]).all()
        elif op == "copy":
            c = vol.copy()
            np.testing.assert_array_equal(c.values(), before[0])
            c.reset()
            np.testing.assert_array_equal(vol.weights(), before[1])
            TALLY["TSDFVolume.copy"]["ok"] += 1
        else:
            vol.reset()
            TALLY["TSDFVolume.reset"]["ok"] += 1
        values, weights = vol.values(), vol.weights()
        assert values.shape == weights.shape == (r, r, r)
        assert values.dtype == weights.dtype == np.float32
        assert np.isfinite(values).all() and np.isfinite(weights).all()
        assert ((values >= -1) & (values <= 1)).all() and (weights >= 0).all()
        assert not values[weights == 0].any()
        assert (vol.resolution, vol.size, vol.truncation) == (r, 0.3, trunc)
        assert vol.origin == (-0.15, -0.15, 0.0)


# ------------------------------------------------------------------------- MeshScene
@st.composite
def mesh_arrays(draw: st.DrawFn, bad: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A box (closed), or if ``bad`` a random triangle soup (NaN / extreme vertices,
    out-of-range faces at times)."""
    if not bad:
        half = draw(st.tuples(*[st.floats(1e-3, 0.2)] * 3))
        v, f = ref.box_mesh(half)
        return np.ascontiguousarray(v, np.float64), np.ascontiguousarray(f, np.int64)
    nv = draw(st.integers(0, 6))
    v = draw(
        hnp.arrays(
            np.float64,
            (nv, 3),
            elements=st.one_of(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), EXTREME_FLOATS),
        )
    )
    nf = draw(st.integers(0, 4))
    f = draw(
        hnp.arrays(
            np.int64,
            (nf, 3),
            elements=st.one_of(
                st.integers(0, max(nv - 1, 0)),
                st.sampled_from([-1, nv, 2**31, 2**32 - 1, 2**32, -(2**63), 2**63 - 1]),
            ),
        )
    )
    return v, f


FACE_DTYPES = [np.int64, np.int32, np.uint32, np.int16, np.uint64, np.uint8, np.float64]


@st.composite
def faces_arg(draw: st.DrawFn, f: np.ndarray, bad: bool = False) -> tuple[Any, bool]:
    """``(faces, valid)``: ``f`` cast to int64 / int32 / uint32 (wrapping), or if ``bad``
    to another dtype or layout; ``valid``: a borrowable int64, int32 or uint32 array
    holding the cast values."""
    dt = draw(st.sampled_from(FACE_DTYPES if bad else [np.int64, np.int32, np.uint32]))
    with np.errstate(all="ignore"):
        g = np.ascontiguousarray(f.astype(dt))
    x, _ = draw(maybe_array(g, bad))
    valid = (
        borrowable(x, [np.int64, np.int32, np.uint32])
        and x.shape == g.shape
        and np.array_equal(x.astype(np.float64), g.astype(np.float64))
    )
    return x, valid


ID_ARG = st.one_of(
    st.integers(-2, 6),
    HUGE_INTS,
    BOOLS,
    OBJECTS,
    st.floats(0, 3),
    numpy_scalars(st.integers(0, 4)),
)


def check_renders(scene: _core.MeshScene, cam: _core.PinholeCamera, pose: np.ndarray) -> None:
    mask = scene.render_mask(cam, pose)
    depth = scene.render_depth(cam, pose)
    labels = scene.render_labels(cam, pose)
    shape = (cam.height, cam.width)
    assert mask.shape == depth.shape == labels.shape == shape
    assert (mask.dtype, depth.dtype, labels.dtype) == (np.bool_, np.float32, np.uint32)
    assert np.isfinite(depth).all() and (depth >= 0).all()
    assert set(np.unique(labels).tolist()) <= {0, *scene.ids()}
    np.testing.assert_array_equal(labels > 0, depth > 0)
    np.testing.assert_array_equal(mask, labels > 0)


@FUZZ
@given(data=st.data())
def test_mesh_scene(data):
    EXAMPLES_RUN["test_mesh_scene"] += 1
    scene = _core.MeshScene()
    cam = data.draw(small_camera())
    for _ in range(data.draw(st.integers(1, 5))):
        ids_before = scene.ids()
        poses_before = {i: scene.pose(i).copy() for i in ids_before}
        tri_before = scene.triangle_count
        op = data.draw(
            st.sampled_from(
                ["add"] * 3 + ["set_pose", "pose", "remove", "is_closed", "render", "cast_ray"]
            )
        )
        if op == "add":
            names = ["vertices", "faces", "obj2world"]
            plan = Plan(data, [*names, "mesh"])
            v, f = data.draw(mesh_arrays("mesh" in plan))
            vx, v_same = data.draw(maybe_array(v, "vertices" in plan))
            fx, f_same = data.draw(faces_arg(f, "faces" in plan))
            pose, pose_ok = data.draw(pose_arg((0.0, 0.0, 0.0), 0.1, "obj2world" in plan))
            out = call("MeshScene.add_mesh", names, scene.add_mesh, vx, fx, pose)
            if not ok(out):
                assert plan.bad, "a valid mesh was refused"
            else:
                assert v_same and f_same, "a mesh was taken from arrays of the wrong kind"
                assert pose_ok
                assert isinstance(out, int) and out >= 1 and out not in ids_before
                assert scene.ids() == sorted([*ids_before, out])
                assert scene.triangle_count == tri_before + len(f)
                np.testing.assert_array_equal(scene.pose(out), canonical(pose, np.float64))
                assert isinstance(scene.is_closed(out), bool)
                continue
        elif op in ("set_pose", "pose", "remove", "is_closed"):
            known = bool(ids_before) and data.draw(st.integers(0, 3)) > 0
            i = data.draw(st.sampled_from(ids_before) if known else ID_ARG)
            if op == "set_pose":
                pose_bad = data.draw(st.booleans())
                pose, pose_ok = data.draw(pose_arg(bad=pose_bad))
                out = call("MeshScene.set_pose", ["id", "obj2world"], scene.set_pose, i, pose)
                if ok(out):
                    assert i in ids_before and not is_bool(i) and pose_ok
                    np.testing.assert_array_equal(scene.pose(i), canonical(pose, np.float64))
                    poses_before[i] = scene.pose(i)
                else:
                    assert pose_bad or not known, "a valid pose was refused"
            else:
                out = call(f"MeshScene.{op}", ["id"], getattr(scene, op), i)
                if ok(out):
                    assert i in ids_before and not is_bool(i)
                    if op == "remove":
                        ids_before.remove(i)
                        del poses_before[i]
                    elif op == "pose":
                        assert out.shape == (4, 4) and out.dtype == np.float64
                    else:
                        assert isinstance(out, bool)
                else:
                    assert not known, "a mesh id of the scene was refused"
        elif op == "render":
            plan = Plan(data, ["camera", "cam2world"])
            pose, pose_ok = data.draw(pose_arg((0.0, 0.0, 0.0), 0.5, "cam2world" in plan))
            camera = data.draw(camera_or_junk(cam, "camera" in plan))
            outs = [
                call(f"MeshScene.{fn}", ["camera", "cam2world"], getattr(scene, fn), camera, pose)
                for fn in ("render_mask", "render_depth", "render_labels")
            ]
            assert len({ok(o) for o in outs}) == 1
            if ok(outs[0]):
                assert camera is cam and pose_ok
                check_renders(scene, cam, canonical(pose, np.float64))
            else:
                assert plan.bad, "a valid view was refused"
        else:
            plan = Plan(data, ["origin", "direction"])
            vec = st.tuples(*[st.floats(-1, 1)] * 3)
            o = data.draw(vec3_arg(vec) if "origin" in plan else vec)
            d = data.draw(vec3_arg(vec) if "direction" in plan else vec)
            out = call("MeshScene.cast_ray", ["origin", "direction"], scene.cast_ray, o, d)
            if ok(out) and out is not None:
                dist, mid = out
                assert math.isfinite(dist) and dist >= 0 and mid in ids_before
        # Nothing else changed.
        assert scene.ids() == sorted(poses_before) and len(scene) == len(poses_before)
        for i, p in poses_before.items():
            np.testing.assert_array_equal(scene.pose(i), p)
        TALLY["MeshScene.ids/__len__/triangle_count"]["ok"] += 1


# ------------------------------------------------------------------------ score_views
@st.composite
def scored_scene(draw: st.DrawFn) -> _core.MeshScene:
    scene = _core.MeshScene()
    for _ in range(draw(st.integers(0, 2))):
        half = draw(st.tuples(*[st.floats(0.01, 0.08)] * 3))
        v, f = ref.box_mesh(half)
        centre = draw(st.tuples(*[st.floats(-0.08, 0.08)] * 2, st.floats(0.02, 0.2)))
        scene.add_mesh(v, f, ref.pose_from(np.eye(3), centre))
    return scene


@FUZZ
@given(data=st.data())
def test_score_views(data):
    EXAMPLES_RUN["test_score_views"] += 1
    names = ["grid", "scene", "camera", "trajectories", "lam", "region"]
    plan = Plan(data, names)
    g = data.draw(grid_with_counts())
    scene = data.draw(scored_scene())
    cam = data.draw(small_camera())
    k = data.draw(st.integers(0, 3))
    trajs, valid = [], True
    for _ in range(k):
        bad_t = "trajectories" in plan and data.draw(st.booleans())
        t, t_ok = data.draw(
            poses_arg(data.draw(st.integers(0 if bad_t else 1, 3)), GRID_CENTRE, bad_t)
        )
        trajs.append(t)
        valid = valid and t_ok and len(t) > 0
    container = data.draw(st.sampled_from(["list", "tuple", "iter"]))
    if "trajectories" in plan and data.draw(st.booleans()):
        container = "junk"
    if container == "tuple":
        trajs_x: Any = tuple(trajs)
    elif container == "iter":
        trajs_x = iter(trajs)
    elif container == "junk":
        # Not a sequence of trajectories (an empty one, [] or {}, would be valid).
        junk = [None, "abc", b"ab", 1.5, 1j, [1.0], (2,), {"a": 1}, object(), range(10**18)]
        trajs_x = data.draw(st.one_of(st.sampled_from(junk), BOOLS, HUGE_INTS))
    else:
        trajs_x = trajs
    lam_valid = st.sampled_from([0.9, 0.5, 1.0, 0.0])
    lam = data.draw(float_arg(lam_valid) if "lam" in plan else lam_valid)
    r = g.resolution
    kw: dict[str, Any] = {"lam": lam}
    region = None
    region_kind = data.draw(st.sampled_from(["none", "omit", "mask"]))
    if "region" in plan:
        region_kind = "mask"
    if region_kind == "none":
        kw["region"] = None
    elif region_kind == "mask":
        kw["region"], region = data.draw(masks_arg((r, r, r), "region" in plan))
        if kw["region"] is None:  # drawn as a bad object, but None means no region
            region_kind = "none"
    grid_x = data.draw(st.one_of(OBJECTS, st.just(scene)) if "grid" in plan else st.just(g))
    scene_x = data.draw(st.one_of(OBJECTS, st.just(g)) if "scene" in plan else st.just(scene))
    camera = data.draw(camera_or_junk(cam, "camera" in plan))
    before = grid_state(g)
    out = call("score_views", names, _core.score_views, grid_x, scene_x, camera, trajs_x, **kw)
    assert_state(g, before)
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    assert grid_x is g and scene_x is scene and camera is cam and container != "junk"
    assert valid and not is_bool(lam), "an invalid trajectory or lam was accepted"
    assert region_kind != "mask" or region is not None, "a bad region was accepted"
    assert out.shape == (k,) and out.dtype == np.float32
    assert np.isfinite(out).all() and (out <= 1).all()
    # Eq. 14 by its definition: render the masks, integrate them into a copy, count.
    lam32 = np.float32(float(lam))

    def count(grid: _core.OccupancyGrid) -> int:
        s, v = grid.counts()
        occ = np.zeros(s.shape, np.float32)
        occ[v > 0] = s[v > 0].astype(np.float32) / v[v > 0].astype(np.float32)
        hc = (s > 0) & (occ >= lam32)
        if region is not None:
            hc &= region.astype(bool)
        return int(hc.sum())

    n_before = count(g)
    for j, t in enumerate(trajs):
        t = canonical(t, np.float64)
        if n_before == 0:
            assert out[j] == 0
            continue
        h = g.copy()
        h.integrate_many(np.stack([scene.render_mask(cam, p) for p in t]), cam, t)
        want = np.float32(1) - np.float32(count(h)) / np.float32(n_before)
        assert out[j] == want, (j, out[j], want)


def test_score_views_counts_beyond_f32_integers():
    """Found by test_score_views: with counts beyond 2**24 (f32 cannot hold every integer)
    the pruning of score_views dropped a voxel that stays high-confidence: a frame that
    sees it without segmenting it leaves 15099494 / f32(2**24 + 1) >= 0.9, while the
    pruning tried (s + 1) / (v + 2) < 0.9. Score 1.0 instead of eq. 14's 0.0."""
    cam = _core.PinholeCamera(1, 1, 2.0, 2.0, 0.0, 0.0)
    scene = _core.MeshScene()  # nothing is ever segmented
    eye = (0.1857, -0.1238, 0.707)
    sees = ref.look_at(eye, (0.0, 0.0, 0.15))
    away = ref.look_at(eye, (eye[0], eye[1], 2.0), up=(0.0, 1.0, 0.0))
    for v in [2**24 - 1, 2**24, 2**24 + 1, U32_MAX - 1, U32_MAX]:
        for s in [int(v * 0.9) + d for d in range(-2, 3)]:
            g = _core.OccupancyGrid.from_counts(
                (-0.15, -0.15, 0.0),
                0.3,
                np.full((1, 1, 1), s, np.uint32),
                np.full((1, 1, 1), v, np.uint32),
            )
            if g.count_high_confidence(0.9) == 0:
                continue
            for traj in ([away, sees], [sees], [sees, away, sees]):
                t = np.stack(traj)
                got = _core.score_views(g, scene, cam, [t])[0]
                h = g.copy()
                h.integrate_many(np.stack([scene.render_mask(cam, p) for p in t]), cam, t)
                want = np.float32(1) - np.float32(h.count_high_confidence(0.9))
                assert got == want, (s, v, len(traj), got, want)


# ------------------------------------------------------------------------ filters, NMS
@st.composite
def volume_arg(draw: st.DrawFn, bad: bool) -> tuple[Any, np.ndarray | None]:
    r = draw(st.integers(1, 6))
    v = draw(hnp.arrays(np.float32, (r, r, r), elements=f_elements(32)))
    x, same = draw(maybe_array(v, bad))
    return x, (v if same else None)


WINDOW = st.one_of(st.just(OMIT), st.just(None), st.integers(1, 9), st.just(1 << 16))


@FUZZ
@given(data=st.data())
def test_gaussian_filter3d(data):
    EXAMPLES_RUN["test_gaussian_filter3d"] += 1
    plan = Plan(data, ["volume", "sigma"])
    x, v = data.draw(volume_arg("volume" in plan))
    sigma = data.draw(float_arg(st.floats(0, 3)) if "sigma" in plan else st.floats(0, 3))
    out = call("gaussian_filter3d", ["volume", "sigma"], _core.gaussian_filter3d, x, sigma)
    if not ok(out):
        assert plan.bad, "a valid volume and sigma were refused"
        return
    assert v is not None and not is_bool(sigma), "a bad volume or sigma was accepted"
    assert out.shape == v.shape and out.dtype == np.float32
    if np.isfinite(v).all() and np.abs(v).max() < 1e30:
        want = ref.gaussian_filter3d(v, float(sigma))
        np.testing.assert_allclose(out, want, rtol=1e-5, atol=1e-5 * np.abs(v).max())
        assert (out >= v.min() - 1e-3).all() and (out <= v.max() + 1e-3).all()


@FUZZ
@given(data=st.data())
def test_maximum_filter3d(data):
    EXAMPLES_RUN["test_maximum_filter3d"] += 1
    plan = Plan(data, ["volume", "window"])
    x, v = data.draw(volume_arg("volume" in plan))
    window = data.draw(int_arg(1, 1 << 16) if "window" in plan else WINDOW)
    args = () if window is OMIT else (window,)
    out = call("maximum_filter3d", ["volume", "window"], _core.maximum_filter3d, x, *args)
    if not ok(out):
        assert plan.bad, "a valid volume and window were refused"
        return
    assert v is not None and not is_bool(window), "a bad volume or window was accepted"
    w = 4 if window in (OMIT, None) else int(window)
    assert out.shape == v.shape and out.dtype == np.float32
    np.testing.assert_array_equal(out, ref.maximum_filter3d(v, w))


@FUZZ
@given(data=st.data())
def test_nms3d(data):
    EXAMPLES_RUN["test_nms3d"] += 1
    names = ["volume", "threshold", "window"]
    plan = Plan(data, names)
    x, v = data.draw(volume_arg("volume" in plan))
    thr_valid = st.floats(-2, 2)
    threshold = data.draw(float_arg(thr_valid) if "threshold" in plan else thr_valid)
    window = data.draw(int_arg(1, 1 << 16) if "window" in plan else WINDOW)
    args = () if window is OMIT else (window,)
    out = call("nms3d", names, _core.nms3d, x, threshold, *args)
    if not ok(out):
        assert plan.bad, "a valid volume, threshold and window were refused"
        return
    assert v is not None and not is_bool(threshold) and not is_bool(window)
    w = 4 if window in (OMIT, None) else int(window)
    assert out.dtype == np.int64 and out.ndim == 2 and out.shape[1] == 3
    with np.errstate(over="ignore"):
        want = ref.nms3d(v, float(threshold), w)
    np.testing.assert_array_equal(out, want)


# -------------------------------------------------------------------- antipodal_grasps
#: The Panda hand as GripperGeometry's fields (heapgrasp-core's HandGeometry::panda).
PANDA_FIELDS = {
    "finger_width": 0.021,
    "finger_tip": 0.0072,
    "finger_base": -0.0466,
    "finger_split": -0.02,
    "tip_thickness": 0.016,
    "base_thickness": 0.026,
    "palm_front": -0.039,
    "palm_split": -0.075,
    "palm_back": -0.131,
    "palm_front_half": (0.022, 0.101),
    "palm_back_half": (0.032, 0.104),
    "max_opening": 0.08,
}


def panda_params(voxel_size: float, origin_z: float) -> dict[str, Any]:
    """heapgrasp-core's AntipodalParams::panda as the Python planner passes it."""
    return {
        "voxel_size": voxel_size,
        "origin_z": origin_z,
        **PANDA_FIELDS,  # the hand's boxes and max_opening
        "opening_margin": 0.01,
        "clearance": 0.003,
        "pregrasp_distance": 0.05,
        "table_z": 0.0,
        "table_clearance": 0.005,
        "min_depth": 0.012,
        "target_depth": 0.022,
        "min_patch": 2,
        "min_contact_height": 0.0075,
        "ledge_factor": 0.4,
        "friction_angle": math.radians(35),
    }


@st.composite
def params_arg(draw: st.DrawFn, bad: bool) -> tuple[Any, bool | None]:
    """``(params, valid)``: the Panda's parameters, or if ``bad`` with one or two entries
    changed, dropped or replaced, or not a mapping. ``valid``: True, False (must be
    refused) or None (a changed value that may still be valid)."""
    p = panda_params(draw(st.sampled_from([0.0075, 0.01, 0.02])), draw(st.floats(-0.05, 0.05)))
    if not bad:
        container = draw(st.sampled_from(["dict", "dict", "mapping"]))
        return (MappingProxyType(p) if container == "mapping" else p), True
    valid: bool | None = True
    for _ in range(draw(st.integers(0, 2))):
        key = draw(st.sampled_from(sorted(p)))
        kind = draw(st.sampled_from(["scale", "value", "drop", "pair", "junk"]))
        if kind == "scale" and isinstance(p[key], int | float) and not is_bool(p[key]):
            p[key] = p[key] * draw(st.sampled_from([0, -1, 1e-300, 1e-6, 2, 1e6, 1e300]))
            valid = valid and None
        elif kind == "value":
            p[key] = draw(st.one_of(ANY_FLOAT, HUGE_INTS, BOOLS))
            invalid = is_bool(p[key]) or not math.isfinite(p[key])
            valid = False if invalid else valid and None
        elif kind == "drop":
            del p[key]
            valid = False
        elif kind == "pair":
            p[key] = draw(st.sampled_from([(1.0,), (1.0, 2.0, 3.0), [0.02, 0.1], "ab", 1.0]))
            valid = valid and None
        else:
            p[key] = draw(OBJECTS)
            valid = valid and None
    container = draw(st.sampled_from(["dict", "dict", "mapping", "list", "junk"]))
    if container == "mapping":
        return MappingProxyType(p), valid
    if container == "list":
        return list(p.items()), False
    if container == "junk":
        return draw(OBJECTS), False
    return p, valid


@st.composite
def rotations_arg(draw: st.DrawFn, bad: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(K, 3, 3)`` TCP rotations and their tilts; if ``bad``, at times a matrix that is
    not a rotation or a tilt that is not finite."""
    k = draw(st.integers(0, 4))
    rots = [draw(rigid_pose())[:3, :3] for _ in range(k)]
    rots = np.stack(rots) if k else np.zeros((0, 3, 3))
    tilts = draw(hnp.arrays(np.float64, (k,), elements=st.floats(0, 1.5)))
    if bad and k:
        rots = rots.copy()
        kind = draw(st.sampled_from(["value", "scale", "reflect", "tilt"]))
        if kind == "value":
            rots[0, draw(st.integers(0, 2)), draw(st.integers(0, 2))] = draw(EXTREME_FLOATS)
        elif kind == "scale":
            rots[0] *= draw(st.sampled_from([1 + 1e-9, 1.01, 1e6, 1e300, 0.0]))
        elif kind == "reflect":
            rots[0, :, 0] *= -1
        else:
            tilts[0] = draw(EXTREME_FLOATS)
    return np.ascontiguousarray(rots), tilts


@FUZZ
@given(data=st.data())
def test_antipodal_grasps(data):
    EXAMPLES_RUN["test_antipodal_grasps"] += 1
    names = [
        "occupied",
        "gradient",
        "labels",
        "centroids",
        "candidates",
        "rotations",
        "tilts",
        "params",
    ]
    plan = Plan(data, [*names, "values"])
    r = data.draw(st.integers(1, 8))
    occ = bool_bytes(data.draw, (r, r, r))
    bad_values = "values" in plan
    grad = data.draw(
        hnp.arrays(
            np.float64,
            (3, r, r, r),
            elements=f_elements(64, -1, 1) if bad_values else st.floats(-1, 1),
        )
    )
    n_labels = data.draw(st.integers(1, 3))
    label_values = st.integers(-1 if bad_values else 0, n_labels if bad_values else n_labels - 1)
    labels = data.draw(hnp.arrays(np.int32, (r, r, r), elements=label_values))
    centroids = data.draw(hnp.arrays(np.float64, (n_labels, 3), elements=f_elements(64, 0, 0.1)))
    n_cand = data.draw(st.integers(0, 4))
    cand_values = st.integers(-1, r) if bad_values else st.integers(0, r - 1)
    cand = data.draw(hnp.arrays(np.int64, (n_cand, 3), elements=cand_values))
    rots, tilts = data.draw(rotations_arg("rotations" in plan or "tilts" in plan))
    if "tilts" in plan and data.draw(st.booleans()):
        tilts = tilts[:-1] if len(tilts) else np.zeros(1)
    params, params_ok = data.draw(params_arg("params" in plan))
    arrays = [occ, grad, labels, centroids, cand, rots, tilts]
    drawn = [data.draw(maybe_array(a, n in plan)) for a, n in zip(arrays, names, strict=False)]
    args = [x for x, _ in drawn]
    out = call("antipodal_grasps", names, _core.antipodal_grasps, *args, params)
    if not ok(out):
        assert plan.bad, "a valid scene was refused"
        return
    # Any array accepted is borrowable in its dtype (a variant may still be valid: an
    # empty candidate list, say); the invariants below hold for the arrays passed.
    dtypes = [np.bool_, np.float64, np.int32, np.float64, np.int64, np.float64, np.float64]
    for (x, _), d, name in zip(drawn, dtypes, names, strict=False):
        assert borrowable(x, [d]), f"{name}: an array of the wrong dtype or layout was accepted"
    occ, grad, labels, centroids, cand, rots, tilts = args
    r = occ.shape[0]
    assert params_ok is not False, "bad params were accepted"
    assert occ.shape == (r, r, r) and grad.shape == (3, r, r, r) and labels.shape == occ.shape
    assert np.isfinite(grad).all() and ((labels >= 0) & (labels < len(centroids))).all()
    assert ((cand >= 0) & (cand < r)).all() and len(rots) == len(tilts)
    assert np.isfinite(tilts).all() and np.isfinite(rots).all()
    for m in rots:  # rotations (orthonormal, det +1) within 1e-4
        assert np.abs(m.T @ m - np.eye(3)).max() <= 1e-4 and abs(np.linalg.det(m) - 1) <= 1e-4
    quality, orientation, width = out
    n = len(cand)
    assert quality.shape == orientation.shape == width.shape == (n,)
    assert (quality.dtype, orientation.dtype, width.dtype) == (np.float64, np.int64, np.float64)
    assert np.isfinite(quality).all() and ((quality >= 0) & (quality <= 1)).all()
    assert np.isfinite(width).all() and (width >= 0).all()
    assert ((orientation >= 0) & (orientation < max(len(rots), 1))).all()
    assert (orientation[quality == 0] == 0).all()
    # Bytes other than 0 / 1 in `occupied` mean True, as NumPy reads them.
    if occ.view(np.uint8).max(initial=0) > 1:
        again = _core.antipodal_grasps(occ.view(np.uint8) != 0, *args[1:], params)
        for a, b in zip(out, again, strict=True):
            np.testing.assert_array_equal(a, b)


# -------------------------------------------------------------------- keep_silhouettes
@FUZZ
@given(data=st.data())
def test_keep_silhouettes(data):
    EXAMPLES_RUN["test_keep_silhouettes"] += 1
    names = ["full", "trimmed", "origin", "voxel_size", "cameras", "poses", "masks"]
    plan = Plan(data, names)
    r = data.draw(st.integers(1, 6))
    full = bool_bytes(data.draw, (r, r, r))
    trimmed = bool_bytes(data.draw, (r, r, r))
    n = data.draw(st.integers(0, 3))
    cams = [data.draw(small_camera()) for _ in range(n)]
    masks = [bool_bytes(data.draw, (c.height, c.width)) for c in cams]
    poses, poses_ok = data.draw(poses_arg(n, GRID_CENTRE, "poses" in plan))
    vec = st.tuples(st.just(-0.15), st.just(-0.15), st.floats(-0.1, 0.1))
    origin = data.draw(vec3_arg(vec) if "origin" in plan else vec)
    vs_valid = st.floats(0.005, 0.06)
    voxel_size = data.draw(float_arg(vs_valid) if "voxel_size" in plan else vs_valid)
    full_x, full_same = data.draw(maybe_array(full, "full" in plan))
    trimmed_x, trimmed_same = data.draw(maybe_array(trimmed, "trimmed" in plan))
    cams_x: Any = data.draw(st.sampled_from([cams, tuple(cams), iter(cams)]))
    masks_x: Any = data.draw(st.sampled_from([masks, tuple(masks)]))
    masks_same = True
    if "cameras" in plan:
        cams_x = data.draw(
            st.one_of(OBJECTS, st.just(range(10**18)), st.just([*cams, None]), st.just(cams[:-1]))
        )
    if "masks" in plan:
        if masks and data.draw(st.booleans()):
            i = data.draw(st.integers(0, n - 1))
            masks_x = list(masks)
            masks_x[i], masks_same = data.draw(maybe_array(masks[i]))
        else:
            masks_x = data.draw(
                st.one_of(
                    OBJECTS,
                    st.just(range(10**18)),
                    st.just([*masks, masks[:1]]),
                    st.just(masks[1:]),
                )
            )

    def entries(x: Any) -> list[Any] | None:
        return list(x) if isinstance(x, list | tuple | dict) else None

    cams_l, masks_l = entries(cams_x), entries(masks_x)
    args = (full_x, trimmed_x, origin, voxel_size, cams_x, poses, masks_x)
    out = call("keep_silhouettes", names, _core.keep_silhouettes, *args)
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    assert full_same and trimmed_same and masks_same and not is_bool(voxel_size)
    assert "cameras" not in plan or (
        cams_l is not None
        and len(cams_l) == n
        and all(isinstance(c, _core.PinholeCamera) for c in cams_l)
    )
    assert "masks" not in plan or (masks_l is not None and len(masks_l) == n)
    assert poses_ok and len(poses) == n and not has_bool(origin)
    assert out.shape == (r, r, r) and out.dtype == np.bool_
    assert out.view(np.uint8).max(initial=0) <= 1
    f, t = full.view(np.uint8) != 0, trimmed.view(np.uint8) != 0
    assert not (out & ~(f & ~t)).any(), "kept a voxel that trimming did not cut"
    # Non-0/1 bytes mean True.
    clean = _core.keep_silhouettes(
        f, t, origin, voxel_size, cams, poses, [m.view(np.uint8) != 0 for m in masks]
    )
    np.testing.assert_array_equal(out, clean)


# ---------------------------------------------------------------------- GraspLabeller
LABELLER_KW = {
    "table_z": 0.0,
    "friction": 1.0,
    "pregrasp_distance": 0.05,
    "hand_margin": 0.001,
    "object_margin": 0.001,
    "min_width": 0.004,
}


def corners(lo: Sequence[float], hi: Sequence[float]) -> np.ndarray:
    return np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )


def hand_parts() -> dict[str, Any]:
    """The Panda's boxes as convex parts (the other form ``hand`` takes)."""
    return {
        "palm": [corners((-0.03, -0.1, -0.13), (0.03, 0.1, -0.039))],
        "left": [corners((-0.01, 0.04, -0.047), (0.01, 0.056, 0.0072))],
        "right": [corners((-0.01, -0.056, -0.047), (0.01, -0.04, 0.0072))],
        "max_opening": 0.08,
        "palm_threshold": 0.0027,
        "finger_threshold": 0.0012,
    }


@st.composite
def hand_arg(draw: st.DrawFn, bad: bool) -> Any:
    hand = dict(PANDA_FIELDS) if draw(st.booleans()) else hand_parts()
    if not bad:
        return hand
    kind = draw(st.sampled_from(["drop", "value", "part", "object"]))
    key = draw(st.sampled_from(sorted(hand)))
    if kind == "drop":
        del hand[key]
    elif kind == "value" or not isinstance(hand[key], list):
        hand[key] = draw(float_arg(st.floats(-0.2, 0.2)))
    elif kind == "part":
        hand[key] = [draw(maybe_array(hand[key][0]))[0]]
    else:
        return draw(st.one_of(OBJECTS, BOOLS, st.just(MappingProxyType(hand))))
    return hand


def check_labels(out: Any, n: int, ids: Sequence[int], opening: float) -> None:
    ok_, width, obj, reason = out
    assert ok_.shape == width.shape == obj.shape == reason.shape == (n,)
    assert (ok_.dtype, width.dtype, obj.dtype, reason.dtype) == (
        np.bool_,
        np.float32,
        np.int32,
        np.uint8,
    )
    assert (reason < len(_core.GraspLabeller.reasons())).all()
    np.testing.assert_array_equal(ok_, reason == 0)
    assert (width[~ok_] == np.float32(opening)).all() and (obj[~ok_] == -1).all()
    assert ((width >= 0) & (width <= np.float32(opening))).all()
    assert np.isin(obj[ok_], list(ids)).all()


@FUZZ
@given(data=st.data())
def test_grasp_labeller(data):
    EXAMPLES_RUN["test_grasp_labeller"] += 1
    names = ["hand", *LABELLER_KW]
    plan = Plan(data, names)
    kw = {
        k: data.draw(float_arg(st.floats(0.0, 0.01))) if k in plan else v
        for k, v in LABELLER_KW.items()
    }
    hand = data.draw(hand_arg("hand" in plan))
    labeller = call("GraspLabeller", names, _core.GraspLabeller, hand, **kw)
    if not ok(labeller):
        assert plan.bad, "a valid labeller was refused"
        return
    ids: list[int] = []
    for _ in range(data.draw(st.integers(0, 3))):
        names = ["id", "obj2world", "pieces", "threshold"]
        plan = Plan(data, names)
        centre = data.draw(
            st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(0.01, 0.05))
        )
        half = data.draw(st.floats(0.005, 0.04))
        piece = corners([-half] * 3, [half] * 3)
        pieces: Any = [piece]
        if "pieces" in plan:
            pieces = data.draw(
                st.one_of(
                    maybe_array(piece).map(lambda x: [x[0]]),
                    st.just([]),
                    st.just([np.zeros((5, 3))]),
                    OBJECTS,
                    st.just(piece),
                )
            )
        pose, _ = data.draw(pose_arg(centre, 0.3, "obj2world" in plan))
        if "obj2world" not in plan:
            pose = ref.pose_from(np.eye(3), np.asarray(centre))
        oid = (
            data.draw(int_arg(0, 2**31 - 1))
            if "id" in plan
            else min(set(range(1, len(ids) + 2)) - set(ids))
        )
        threshold = data.draw(float_arg(st.floats(0.0, 0.003))) if "threshold" in plan else 0.001
        before = (labeller.object_count, labeller.piece_count)
        out = call(
            "GraspLabeller.add_object", names, labeller.add_object, oid, pose, pieces, threshold
        )
        if ok(out):
            ids.append(int(oid))
        else:
            assert plan.bad, "a valid object was refused"
            assert (labeller.object_count, labeller.piece_count) == before
    names = ["tcp2world", "threads"]
    plan = Plan(data, names)
    n = data.draw(st.integers(0, 6))
    poses, valid = data.draw(poses_arg(n, (0.0, 0.0, 0.05), "tcp2world" in plan))
    threads = data.draw(int_arg(0, 4096)) if "threads" in plan else None
    out = call("GraspLabeller.label", names, labeller.label, poses, threads=threads)
    if ok(out):
        assert valid
        check_labels(out, len(poses), ids, float(hand["max_opening"]))
        again = labeller.label(canonical(poses, np.float64), threads=1)
        for a, b in zip(out, again, strict=True):
            np.testing.assert_array_equal(a, b)
    else:
        assert plan.bad, "valid grasps were refused"


# ----------------------------------------------------------------------- module level
def test_module_functions():
    assert call("kernel_level", [], _core.kernel_level) in {"avx512", "avx2", "baseline"}
    problem = call("kernel_request_problem", [], _core.kernel_request_problem)
    assert problem is None or "HEAPGRASP_KERNEL" in problem
    n = call("num_threads", [], _core.num_threads)
    assert isinstance(n, int) and n >= 1
    assert isinstance(_core.__version__, str) and _core.__version__


# ------------------------------------------------------------------ hand_point_counts
@FUZZ
@given(data=st.data())
def test_hand_point_counts(data):
    EXAMPLES_RUN["test_hand_point_counts"] += 1
    names = ["hand", "tcp2world", "openings", "points", "cell", "threads"]
    plan = Plan(data, names)
    hand: Any = dict(PANDA_FIELDS)
    if "hand" in plan:
        hand = data.draw(st.one_of(hand_arg(True), st.just(hand_parts())))
    n = data.draw(st.integers(0, 5))
    poses, poses_valid = data.draw(poses_arg(n, (0.0, 0.0, 0.05), "tcp2world" in plan))
    widths = np.asarray(data.draw(st.lists(st.floats(0.001, 0.08), min_size=n, max_size=n)))
    openings: Any = widths
    openings_same = True
    if "openings" in plan:
        openings, openings_same = data.draw(
            st.one_of(
                maybe_array(widths),
                st.tuples(st.just(np.append(widths, 0.2)), st.just(False)),
                st.tuples(st.just(np.full(n + 1, np.nan)), st.just(False)),
            )
        )
    pts = np.asarray(
        data.draw(
            hnp.arrays(
                np.float64, (data.draw(st.integers(0, 40)), 3), elements=st.floats(-0.2, 0.2)
            )
        )
    )
    points: Any = pts
    points_same = True
    if "points" in plan:
        bad_pts = pts.copy()
        if len(bad_pts):
            bad_pts[0, 0] = np.nan
        points, points_same = data.draw(
            st.one_of(
                maybe_array(pts),
                st.tuples(st.just(np.zeros((3, 2))), st.just(False)),
                st.tuples(st.just(bad_pts), st.just(not len(pts))),
            )
        )
    cell = data.draw(float_arg(st.floats(-1.0, 0.05))) if "cell" in plan else 0.01
    threads = data.draw(int_arg(0, 4096)) if "threads" in plan else None
    out = call(
        "hand_point_counts",
        names,
        _core.hand_point_counts,
        hand,
        poses,
        openings,
        points,
        cell=cell,
        threads=threads,
    )
    free = call(
        "first_free_pose",
        names,
        _core.first_free_pose,
        hand,
        poses,
        openings,
        points,
        cell=cell,
        threads=threads,
    )
    assert ok(free) == ok(out), "first_free_pose and hand_point_counts disagree on validity"
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    if not points_same and valid_cloud(points):
        # A variant that is itself a valid cloud (an empty one, a reshape to (m, 3)): the
        # call must count against that cloud.
        pts, points_same = points, True
    assert poses_valid and openings_same and points_same
    assert out.dtype == np.uint32 and out.shape == (len(poses),)
    again = _core.hand_point_counts(
        hand, canonical(poses, np.float64), widths[: len(poses)], pts, threads=1
    )
    np.testing.assert_array_equal(out, again)
    zeros = np.flatnonzero(out == 0)
    assert free == (int(zeros[0]) if len(zeros) else None)


# ----------------------------------------------- point_normals, contact_patches, pairs
def cloud_arg(data: Any, n: int, bad: bool) -> tuple[Any, bool, np.ndarray]:
    """``(x, same, valid)``: a cloud of ``n`` points, sometimes corrupted."""
    pts = np.asarray(data.draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-0.2, 0.2))))
    if not bad:
        return pts, True, pts
    nan = pts.copy()
    if n:
        nan[0, 1] = np.nan
    x, same = data.draw(
        st.one_of(
            maybe_array(pts),
            st.tuples(st.just(np.zeros((n, 2))), st.just(False)),
            st.tuples(st.just(nan), st.just(not n)),
        )
    )
    return x, same, pts


def unit_rows(data: Any, n: int) -> np.ndarray:
    raw = np.asarray(data.draw(hnp.arrays(np.float64, (n, 3), elements=st.floats(-1.0, 1.0))))
    raw[np.linalg.norm(raw, axis=1) < 1e-3] = [0.0, 0.0, 1.0]
    return np.ascontiguousarray(raw / np.linalg.norm(raw, axis=1)[:, None])


@FUZZ
@given(data=st.data())
def test_point_normals(data):
    EXAMPLES_RUN["test_point_normals"] += 1
    names = ["points", "k", "threads"]
    plan = Plan(data, names)
    n = data.draw(st.integers(0, 30))
    points, same, pts = cloud_arg(data, n, "points" in plan)
    k = data.draw(int_arg(-3, 40)) if "k" in plan else min(10, max(n, 3))
    threads = data.draw(int_arg(0, 4096)) if "threads" in plan else None
    out = call("point_normals", names, _core.point_normals, points, k=k, threads=threads)
    if not ok(out):
        assert plan.bad or n < 3, "a valid call was refused"
        return
    assert same and 3 <= int(k) <= n
    normals, curvature = out
    assert normals.shape == (n, 3) and curvature.shape == (n,)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9)
    again = _core.point_normals(pts, k=int(k), threads=1)
    np.testing.assert_array_equal(normals, again[0])
    np.testing.assert_array_equal(curvature, again[1])


@FUZZ
@given(data=st.data())
def test_contact_patches_and_antipodal_pairs(data):
    EXAMPLES_RUN["test_contact_patches_and_antipodal_pairs"] += 1
    names = ["points", "normals", "candidates", "threads"]
    plan = Plan(data, names)
    n = data.draw(st.integers(0, 30))
    points, same, pts = cloud_arg(data, n, "points" in plan)
    nrm = unit_rows(data, n)
    normals: Any = nrm
    normals_same = True
    if "normals" in plan:
        normals, normals_same = data.draw(
            st.one_of(
                maybe_array(nrm),
                st.tuples(st.just(nrm * 2.0 + 1.0), st.just(not n)),
                st.tuples(st.just(nrm[:-1] if n else np.zeros((1, 3))), st.just(False)),
            )
        )
    raw = np.asarray(data.draw(hnp.arrays(np.bool_, (n,))))
    candidates: Any = raw
    mask_same = True
    if "candidates" in plan:
        candidates, mask_same = data.draw(
            st.one_of(maybe_array(raw), st.tuples(st.just(np.ones(n + 1, bool)), st.just(False)))
        )
    threads = data.draw(int_arg(0, 4096)) if "threads" in plan else None
    out = call(
        "contact_patches",
        names,
        _core.contact_patches,
        points,
        normals,
        candidates,
        threads=threads,
    )
    if ok(out):
        assert same and normals_same and mask_same
        assert out.dtype == np.bool_ and out.shape == (n,) and not out[~raw].any()
        np.testing.assert_array_equal(out, _core.contact_patches(pts, nrm, raw, threads=1))
    else:
        assert plan.bad, "a valid call was refused"
    names = ["points", "normals", "usable", "voxel", "max_width", "min_quality", "threads"]
    plan = Plan(data, names)
    points, same, pts = cloud_arg(data, n, "points" in plan)
    usable: Any = raw
    kw = {
        "voxel": data.draw(float_arg(st.floats(0.0, 0.01))) if "voxel" in plan else 0.0075,
        "max_width": data.draw(float_arg(st.floats(0.01, 0.5))) if "max_width" in plan else 0.08,
        "min_quality": (
            data.draw(float_arg(st.floats(-10.0, 190.0))) if "min_quality" in plan else 150.0
        ),
        "threads": data.draw(int_arg(0, 4096)) if "threads" in plan else None,
    }
    normals, normals_same = data.draw(maybe_array(nrm, "normals" in plan))
    usable, usable_same = data.draw(maybe_array(raw, "usable" in plan))
    out = call("antipodal_pairs", names, _core.antipodal_pairs, points, normals, usable, **kw)
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    assert same and normals_same and usable_same
    first, second, quality, width = out
    assert first.dtype == second.dtype == np.int64
    assert len(first) == len(second) == len(quality) == len(width)
    if len(first):
        assert (first < second).all() and second.max() < n
        assert quality.min() >= float(kw["min_quality"]) and quality.max() <= 180.0 + 1e-9


# ------------------------------------------------------------------------- seen_empty
def _depth_view(data: Any, plan: Any) -> tuple[Any, ...]:
    """A depth view's arguments, sometimes corrupted: ``(cam, raw depth, depth,
    depth_same, camera, pose, pose_valid)``."""
    cam = data.draw(small_camera())
    raw = np.asarray(
        data.draw(
            hnp.arrays(np.float32, (cam.height, cam.width), elements=st.floats(0.0, 2.0, width=32))
        )
    )
    depth, depth_same = data.draw(maybe_array(raw, "depth" in plan))
    camera = data.draw(camera_or_junk(cam, "camera" in plan))
    pose, pose_valid = data.draw(pose_arg((0.0, 0.0, 0.0), 0.6, "cam2world" in plan))
    return cam, raw, depth, depth_same, camera, pose, pose_valid


@FUZZ
@given(data=st.data())
def test_seen_empty(data):
    EXAMPLES_RUN["test_seen_empty"] += 1
    names = ["points", "depth", "camera", "cam2world", "min_range", "max_range", "occlusion"]
    names += ["floor_z", "threads"]
    plan = Plan(data, names)
    n = data.draw(st.integers(0, 30))
    points, same, pts = cloud_arg(data, n, "points" in plan)
    cam, raw, depth, depth_same, camera, pose, pose_valid = _depth_view(data, plan)
    kw = {
        "min_range": data.draw(float_arg(st.floats(0.0, 0.5))) if "min_range" in plan else 0.1,
        "max_range": data.draw(float_arg(st.floats(0.0, 5.0))) if "max_range" in plan else 3.0,
        "occlusion": data.draw(float_arg(st.floats(0.0, 2.0))) if "occlusion" in plan else 0.99,
        "floor_z": data.draw(float_arg(st.floats(-1.0, 1.0))) if "floor_z" in plan else -0.01,
        "threads": data.draw(int_arg(0, 4096)) if "threads" in plan else None,
    }
    out = call("seen_empty", names, _core.seen_empty, points, depth, camera, pose, **kw)
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    assert depth_same and pose_valid
    del same, pts  # any (N, 3) points are valid: compare with what was passed
    passed = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    assert out.dtype == np.bool_ and out.shape == (len(passed),)
    kw["threads"] = 1
    again = _core.seen_empty(passed, raw, cam, canonical(pose, np.float64), **kw)
    np.testing.assert_array_equal(out, again)


# ------------------------------------------------- grasp_region and surfel_visibility
@FUZZ
@given(data=st.data())
def test_grasp_region_and_surfel_visibility(data):
    EXAMPLES_RUN["test_grasp_region_and_surfel_visibility"] += 1
    names = ["points", "normals", "targets", "half_length", "radius", "threads"]
    plan = Plan(data, names)
    n = data.draw(st.integers(0, 20))
    m = data.draw(st.integers(0, 20))
    points, same, pts = cloud_arg(data, n, "points" in plan)
    targets, targets_same, tgt = cloud_arg(data, m, "targets" in plan)
    nrm = unit_rows(data, n)
    normals: Any = nrm
    normals_same = True
    if "normals" in plan:
        normals, normals_same = data.draw(
            st.one_of(
                maybe_array(nrm),
                st.tuples(st.just(nrm * 3.0), st.just(True)),  # normalised in the core
                st.tuples(st.just(np.zeros((n, 3))), st.just(not n)),
                st.tuples(st.just(np.zeros((n + 1, 3))), st.just(False)),
            )
        )
    kw = {
        "half_length": (
            data.draw(float_arg(st.floats(-0.1, 0.2))) if "half_length" in plan else 0.08
        ),
        "radius": data.draw(float_arg(st.floats(-0.01, 0.05))) if "radius" in plan else 0.015,
        "threads": data.draw(int_arg(0, 4096)) if "threads" in plan else None,
    }
    out = call("grasp_region", names, _core.grasp_region, points, normals, targets, **kw)
    if ok(out):
        assert same and normals_same
        del targets_same, tgt  # any (M, 3) targets are valid: compare with what was passed
        passed = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
        assert out.dtype == np.bool_ and out.shape == (len(passed),)
        kw["threads"] = 1
        np.testing.assert_array_equal(out, _core.grasp_region(pts, nrm, passed, **kw))
    else:
        assert plan.bad, "a valid call was refused"
    names = ["points", "normals", "eyes", "targets", "radius", "threads"]
    plan = Plan(data, names)
    v = data.draw(st.integers(0, 4))
    points, same, pts = cloud_arg(data, n, "points" in plan)
    eyes, eyes_same, eye = cloud_arg(data, v, "eyes" in plan)
    targets, targets_same, tgt = cloud_arg(data, m, "targets" in plan)
    normals, normals_same = data.draw(maybe_array(nrm, "normals" in plan))
    kw = {
        "radius": data.draw(float_arg(st.floats(-0.01, 0.05))) if "radius" in plan else 0.01,
        "threads": data.draw(int_arg(0, 4096)) if "threads" in plan else None,
    }
    out = call(
        "surfel_visibility", names, _core.surfel_visibility, points, normals, eyes, targets, **kw
    )
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    assert same and normals_same
    del eyes_same, targets_same, eye, tgt  # any (V, 3) eyes and (M, 3) targets are valid
    eyes_in = np.asarray(eyes, dtype=np.float64).reshape(-1, 3)
    targets_in = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    assert out.dtype == np.bool_ and out.shape == (len(eyes_in), len(targets_in))
    kw["threads"] = 1
    np.testing.assert_array_equal(out, _core.surfel_visibility(pts, nrm, eyes_in, targets_in, **kw))


# ------------------------------------------------------------------- voxel_downsample
def _reference_voxels(pts: np.ndarray, voxel: float) -> np.ndarray:
    """The NumPy down-sampling the core replaced: centroids per cell, keys sorted."""
    if len(pts) == 0:
        return np.zeros((0, 3))
    keys = np.floor(pts / voxel).astype(np.int64)
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    counts = np.bincount(inverse).astype(np.float64)
    sums = np.column_stack([np.bincount(inverse, weights=pts[:, k]) for k in range(3)])
    return sums / counts[:, None]


@FUZZ
@given(data=st.data())
def test_voxel_downsample(data):
    EXAMPLES_RUN["test_voxel_downsample"] += 1
    names = ["points", "voxel"]
    plan = Plan(data, names)
    n = data.draw(st.integers(0, 40))
    points, same, pts = cloud_arg(data, n, "points" in plan)
    voxel = data.draw(float_arg(st.floats(-0.01, 0.1))) if "voxel" in plan else 0.02
    out = call("voxel_downsample", names, _core.voxel_downsample, points, voxel)
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    del same, pts  # any (N, 3) cloud is valid: compare with what was passed
    passed = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    np.testing.assert_allclose(out, _reference_voxels(passed, float(voxel)), rtol=1e-12, atol=1e-15)


@FUZZ
@given(data=st.data())
def test_depth_voxels(data):
    from heapgrasp.geometry.camera import CameraSpec
    from heapgrasp.perception.clouds import backproject

    EXAMPLES_RUN["test_depth_voxels"] += 1
    names = ["depth", "camera", "cam2world", "min_range", "max_range", "voxel"]
    plan = Plan(data, names)
    cam, raw, depth, depth_same, camera, pose, pose_valid = _depth_view(data, plan)
    kw = {
        "min_range": data.draw(float_arg(st.floats(0.0, 0.5))) if "min_range" in plan else 0.1,
        "max_range": data.draw(float_arg(st.floats(0.0, 5.0))) if "max_range" in plan else 3.0,
        "voxel": data.draw(float_arg(st.floats(-0.01, 0.1))) if "voxel" in plan else 0.02,
    }
    out = call("depth_voxels", names, _core.depth_voxels, depth, camera, pose, **kw)
    if not ok(out):
        assert plan.bad, "a valid call was refused"
        return
    assert depth_same and pose_valid
    spec = CameraSpec(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
    cloud = backproject(
        raw,
        spec,
        canonical(pose, np.float64),
        min_range=float(kw["min_range"]),
        max_range=float(kw["max_range"]),
    )
    want = _reference_voxels(cloud, float(kw["voxel"]))
    assert out.shape == want.shape
    np.testing.assert_allclose(out, want, rtol=1e-9, atol=1e-12)


def test_every_entry_point_is_fuzzed():
    """The tests above cover every public name of the native module."""
    covered = {
        "HeapgraspError",
        "InvalidValueError",
        "MeshError",
        "NonFiniteError",
        "NotRigidError",
        "ShapeError",
        "UnknownMeshError",
        "PinholeCamera",
        "OccupancyGrid",
        "TSDFVolume",
        "MeshScene",
        "GraspLabeller",
        "score_views",
        "gaussian_filter3d",
        "maximum_filter3d",
        "nms3d",
        "antipodal_grasps",
        "hand_point_counts",
        "first_free_pose",
        "seen_empty",
        "grasp_region",
        "surfel_visibility",
        "voxel_downsample",
        "depth_voxels",
        "point_normals",
        "contact_patches",
        "antipodal_pairs",
        "keep_silhouettes",
        "kernel_level",
        "kernel_request_problem",
        "num_threads",
    }
    assert {n for n in dir(_core) if not n.startswith("_")} == covered
