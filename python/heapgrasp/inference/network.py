"""The one way every shipped network runs: :class:`OnnxNetwork` (see
:mod:`heapgrasp.inference`), and the device it runs on (:func:`resolve_device`)."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from heapgrasp.inference.checksum import content_digest
from heapgrasp.inference.errors import WeightsError
from heapgrasp.inference.files import (
    FORMAT_VERSION,
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_SHA256,
    META_VERSION,
    Kind,
    check_kind,
)

if TYPE_CHECKING:
    import onnxruntime

__all__ = ["OnnxNetwork", "resolve_device"]

F32 = npt.NDArray[np.float32]

_DEVICE = re.compile(r"cpu|auto|cuda(?::(\d+))?")
_CUDA = "CUDAExecutionProvider"
_CPU = "CPUExecutionProvider"


def _ort() -> Any:
    try:
        import onnxruntime
    except ImportError as exc:  # pragma: no cover - a default dependency
        raise ImportError(
            "running heapgrasp's networks needs onnxruntime, a dependency of heapgrasp: "
            "reinstall heapgrasp, or `pip install onnxruntime` (onnxruntime-gpu for CUDA)"
        ) from exc
    return onnxruntime


def resolve_device(spec: str) -> str:
    """``cpu``, ``cuda``, ``cuda:N`` or ``auto`` (``cuda`` where onnxruntime has the CUDA
    execution provider, else ``cpu``) as the device to run on.

    Raises ``ValueError`` naming ``spec`` when it is none of these, or when it asks for
    CUDA and onnxruntime has no CUDA execution provider (``pip install onnxruntime-gpu``):
    a network asked to run on a GPU never runs on the CPU instead without saying so.
    """
    match = _DEVICE.fullmatch(spec) if isinstance(spec, str) else None
    if match is None:
        raise ValueError(f"device must be cpu, cuda, cuda:N or auto; got {spec!r}")
    if spec == "cpu":
        return spec
    available = list(_ort().get_available_providers())
    if spec == "auto":
        return "cuda" if _CUDA in available else "cpu"
    if _CUDA not in available:
        raise ValueError(
            f"{spec!r} asked for, but this onnxruntime has no {_CUDA} (it has "
            f"{', '.join(available)}): install onnxruntime-gpu in place of onnxruntime, "
            f"or run on the cpu"
        )
    return spec


def _check_threads(threads: int | None) -> int | None:
    if threads is None:
        return None
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"threads must be an integer >= 1 or None, got {threads!r}")
    return threads


def _providers(device: str) -> list[Any]:
    if device == "cpu":
        return [_CPU]
    index = int(device.partition(":")[2] or 0)
    return [(_CUDA, {"device_id": index}), _CPU]


@dataclass(frozen=True)
class _Io:
    """An input or output: its name and shape (None: a dynamic axis)."""

    name: str
    shape: tuple[int | None, ...]


def _as_int(value: object) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _positive(hp: Mapping[str, Any], key: str, p: Path) -> int:
    if key not in hp:
        raise WeightsError(p, f"metadata {META_HPARAMS} has no {key!r}")
    v = _as_int(hp[key])
    if v is None or v < 1:
        raise WeightsError(
            p, f"metadata {META_HPARAMS}: {key!r} is {hp[key]!r}, not an integer >= 1"
        )
    return v


def _expected_io(kind: str, hp: Mapping[str, Any], p: Path) -> tuple[_Io, list[_Io]]:
    """The input and outputs a ``kind`` file with hyper-parameters ``hp`` must have."""
    if kind == "grasp-critic":
        f = _positive(hp, "n_features", p)
        return _Io("features", (None, f)), [_Io("logits", (None,))]
    if kind == "viewsphere-policy":
        f = _positive(hp, "n_features", p)
        return _Io("state", (None, f)), [_Io("scores", (None, 8))]
    if kind == "segmentation-network":
        classes = hp.get("classes")
        if not isinstance(classes, list) or len(classes) < 2:
            raise WeightsError(
                p, f"metadata {META_HPARAMS}: 'classes' is {classes!r}, not a list of >= 2 names"
            )
        # Fully convolutional: the image axes are dynamic as the batch is.
        return _Io("image", (None, 3, None, None)), [
            _Io("logits", (None, len(classes), None, None))
        ]
    r = _positive(hp, "resolution", p)
    c = _positive(hp, "in_channels", p)
    grid = _Io("grid", (None, c, r, r, r))
    if kind == "grasp-network":
        return grid, [
            _Io("quality", (None, 1, r, r, r)),
            _Io("rotation", (None, 4, r, r, r)),
            _Io("width", (None, 1, r, r, r)),
        ]
    shape = hp.get("view_shape")
    if (
        not isinstance(shape, list)
        or len(shape) != 2
        or any(_as_int(s) is None or s < 1 for s in shape)
    ):
        raise WeightsError(
            p, f"metadata {META_HPARAMS}: 'view_shape' is {shape!r}, not a pair [U, V] >= 1"
        )
    return grid, [_Io("scores", (None, int(shape[0]), int(shape[1])))]


def _describe(shape: Sequence[object]) -> str:
    """``(B, 3, *, *)``: the batch axis, then the others (``*``: dynamic)."""
    names = ("B" if i == 0 else "*" if s is None else str(s) for i, s in enumerate(shape))
    return "(" + ", ".join(names) + ")"


def _detail(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    text = re.sub(r"^\[ONNXRuntimeError\] : \d+ : \w+ : ", "", text)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _json_object(meta: Mapping[str, str], key: str, p: Path) -> dict[str, Any]:
    if key not in meta:
        raise WeightsError(p, f"metadata {key!r} missing")
    try:
        value = json.loads(meta[key])
    except json.JSONDecodeError as exc:
        raise WeightsError(p, f"metadata {key!r} is not valid JSON ({exc})") from exc
    if not isinstance(value, dict):
        raise WeightsError(p, f"metadata {key!r} is a JSON {type(value).__name__}, not an object")
    return value


class OnnxNetwork:
    """A heapgrasp network file, checked whole (module docstring), ready to run.

    Parameters
    ----------
    path : path-like
        The ``.onnx`` file.
    kind : {"view-network", "grasp-network", "grasp-critic", "viewsphere-policy", \
            "segmentation-network"}
        What the file must hold.
    device : str
        ``cpu`` (default), ``cuda``, ``cuda:N`` or ``auto`` (:func:`resolve_device`).
    threads : int, optional
        CPU threads of one forward pass (onnxruntime's intra-op threads); default:
        ``HEAPGRASP_NUM_THREADS`` where set (the Rust core's threads too; the workers of
        a process pool set it to 1), else onnxruntime's, one per physical core.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    WeightsError
        Anything else wrong with the file (module docstring); the message starts with
        ``path``.
    ValueError
        ``device`` is not one, or asks for CUDA where onnxruntime cannot run it.

    Attributes
    ----------
    path, kind, format_version, hparams, provenance, device, model_bytes
        The file, what its metadata says, where it runs (``cpu`` or ``cuda[:N]``) and
        the file's bytes.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        kind: Kind,
        device: str = "cpu",
        threads: int | None = None,
    ) -> None:
        check_kind(kind)
        self._threads = _check_threads(threads)
        p = Path(path)
        if not p.exists():
            raise FileNotFoundError(f"{kind} file not found: {p}")
        if not p.is_file():
            raise WeightsError(p, f"not a file (expected an ONNX {kind} file)")
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise WeightsError(p, f"unreadable: {exc.strerror or _detail(exc)}") from exc
        self._open(p, data, kind, device)

    @classmethod
    def from_bytes(
        cls,
        data: bytes,
        *,
        kind: Kind,
        device: str = "cpu",
        threads: int | None = None,
        name: str = "<in memory>",
    ) -> OnnxNetwork:
        """A network from a serialised ONNX model (a critic just trained, ...), checked
        as a file is; errors name ``name``."""
        check_kind(kind)
        self = cls.__new__(cls)
        self._threads = _check_threads(threads)
        self._open(Path(name), bytes(data), kind, device)
        return self

    # ------------------------------------------------------------------ checks
    def _open(self, p: Path, data: bytes, kind: str, device: str) -> None:
        self.path = p
        self.kind = kind
        self.model_bytes = data
        self.device = resolve_device(device)
        if not data:
            raise WeightsError(p, "empty file (0 bytes), not an ONNX model")
        session = self._session(p, data)
        meta = dict(session.get_modelmeta().custom_metadata_map)
        stored = meta.get(META_KIND)
        if stored is None:
            raise WeightsError(
                p, f"an ONNX model but not a heapgrasp network: metadata {META_KIND!r} missing"
            )
        if stored != kind:
            raise WeightsError(p, f"holds a {stored!r} ({META_KIND}), expected a {kind!r}")
        version = meta.get(META_VERSION)
        if version is None:
            raise WeightsError(p, f"metadata {META_VERSION!r} missing")
        if not re.fullmatch(r"[0-9]+", version) or not 1 <= int(version) <= FORMAT_VERSION:
            raise WeightsError(
                p,
                f"unsupported {META_VERSION} {version!r} (this heapgrasp reads 1 to "
                f"{FORMAT_VERSION})",
            )
        self.format_version = int(version)
        stored_digest = meta.get(META_SHA256)
        if stored_digest is None:
            raise WeightsError(p, f"metadata {META_SHA256!r} missing")
        if content_digest(data) != stored_digest:
            raise WeightsError(
                p,
                f"garbled: the model's bytes do not match their SHA-256 ({META_SHA256}); "
                f"the file was changed after it was written",
            )
        self.hparams = _json_object(meta, META_HPARAMS, p)
        self.provenance = _json_object(meta, META_PROVENANCE, p)
        want_in, want_out = _expected_io(kind, self.hparams, p)
        self._check_io(p, session, want_in, want_out)
        self._session_ = session
        self.input = want_in
        self.outputs = want_out
        self._smoke_test(p)

    def _session(self, p: Path, data: bytes) -> onnxruntime.InferenceSession:
        ort = _ort()
        options = ort.SessionOptions()
        options.log_severity_level = 3  # errors only: no optimiser chatter on stderr
        threads = self._threads
        if threads is None:  # the Rust core's knob: a pool's workers set it to 1
            env = os.environ.get("HEAPGRASP_NUM_THREADS", "")
            threads = int(env) if env.isdigit() and int(env) >= 1 else None
        if threads is not None:
            options.intra_op_num_threads = threads
        providers = _providers(self.device)

        def open_with(prov: list[Any]) -> onnxruntime.InferenceSession:
            return ort.InferenceSession(data, sess_options=options, providers=prov)

        try:
            session = open_with(providers)
        except Exception as exc:  # onnxruntime raises its own classes for bad models
            if self.device != "cpu":
                try:
                    open_with([_CPU])
                except Exception:
                    pass
                else:  # the file is fine: the device is not
                    raise ValueError(f"{p}: cannot run on {self.device}: {_detail(exc)}") from exc
            raise WeightsError(p, self._not_onnx(data, exc)) from exc
        if self.device != "cpu" and session.get_providers()[0] != _CUDA:
            raise ValueError(
                f"{p}: {self.device} asked for, but onnxruntime could not start its "
                f"{_CUDA} (no usable CUDA device or libraries); run on the cpu"
            )
        return session

    @staticmethod
    def _not_onnx(data: bytes, exc: BaseException) -> str:
        if data[:4] == b"PK\x03\x04":
            return (
                "a zip archive (a PyTorch .pt or numpy .npz file?), not an ONNX model; "
                "networks ship as ONNX (heapgrasp.training.export_onnx)"
            )
        return f"not a valid ONNX model (corrupt, truncated or another format): {_detail(exc)}"

    @staticmethod
    def _check_io(
        p: Path, session: onnxruntime.InferenceSession, want_in: _Io, want_out: list[_Io]
    ) -> None:
        inputs = session.get_inputs()
        names = [i.name for i in inputs]
        if names != [want_in.name]:
            raise WeightsError(p, f"inputs are {names}, expected one named {want_in.name!r}")
        got_names = sorted(o.name for o in session.get_outputs())
        if got_names != sorted(o.name for o in want_out):
            raise WeightsError(
                p, f"outputs are {got_names}, expected {sorted(o.name for o in want_out)}"
            )
        outs = {o.name: o for o in session.get_outputs()}
        for arg, want, what in [
            (inputs[0], want_in, "input"),
            *((outs[w.name], w, "output") for w in want_out),
        ]:
            if arg.type != "tensor(float)":
                raise WeightsError(p, f"{what} {want.name!r} is {arg.type}, expected tensor(float)")
            shape = list(arg.shape)
            if len(shape) != len(want.shape):
                raise WeightsError(
                    p,
                    f"{what} {want.name!r} has shape {_describe(shape)}, expected "
                    f"{_describe(want.shape)} (metadata {META_HPARAMS})",
                )
            if _as_int(shape[0]) is not None:
                raise WeightsError(
                    p,
                    f"{what} {want.name!r} has a fixed batch axis of {shape[0]}, expected a "
                    f"dynamic one (export with a dynamic axis 0)",
                )
            for got, expected in zip(shape[1:], want.shape[1:], strict=True):
                if _as_int(got) is not None and got != expected:
                    raise WeightsError(
                        p,
                        f"{what} {want.name!r} has shape {_describe([None, *shape[1:]])}, "
                        f"expected {_describe(want.shape)} (metadata {META_HPARAMS})",
                    )

    def _smoke_test(self, p: Path) -> None:
        """One forward pass on zeros: the graph runs, its outputs have the declared shapes
        and are finite (NaN or infinite weights show here)."""
        probe = 2 * (_as_int(self.hparams.get("pad_multiple")) or 16)  # a dynamic image axis
        x = np.zeros((1, *(probe if s is None else s for s in self.input.shape[1:])), np.float32)
        try:
            outs = self._session_.run(None, {self.input.name: x})
        except Exception as exc:
            raise WeightsError(p, f"a forward pass fails: {_detail(exc)}") from exc
        for arg, out in zip(self._session_.get_outputs(), outs, strict=True):
            a = np.asarray(out)
            want = next(o for o in self.outputs if o.name == arg.name)
            expected = (1, *(probe if s is None else s for s in want.shape[1:]))
            if a.shape != expected:
                raise WeightsError(
                    p,
                    f"output {arg.name!r} of a batch of 1 has shape {a.shape}, expected {expected}",
                )
            if not np.isfinite(a).all():
                raise WeightsError(
                    p,
                    f"output {arg.name!r} holds NaN or infinity on an all-zero input (weights "
                    f"holding NaN or infinity?)",
                )

    # ------------------------------------------------------------------ use
    @property
    def providers(self) -> list[str]:
        """The execution providers of the session, in order of preference."""
        return list(self._session_.get_providers())

    @property
    def output_names(self) -> list[str]:
        """The outputs' names, in the order :meth:`run` returns them."""
        return [o.name for o in self.outputs]

    def run(self, x: npt.ArrayLike) -> list[F32]:
        """The outputs (in :attr:`output_names` order) for a batch ``x`` of the input's
        shape (float32, batch first)."""
        a = np.ascontiguousarray(x, dtype=np.float32)
        want = self.input.shape[1:]
        fits = all(w is None or w == g for w, g in zip(want, a.shape[1:], strict=False))
        if a.ndim != len(self.input.shape) or a.shape[0] < 1 or not fits:
            raise ValueError(
                f"{self.kind} {self.input.name!r} must have shape "
                f"{_describe(self.input.shape)} with B >= 1, got {a.shape}"
            )
        outs = self._session_.run(self.output_names, {self.input.name: a})
        return [np.asarray(o, dtype=np.float32) for o in outs]

    def __repr__(self) -> str:
        return f"OnnxNetwork({str(self.path)!r}, kind={self.kind!r}, device={self.device!r})"
