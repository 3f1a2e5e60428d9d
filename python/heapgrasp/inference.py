"""The one way every shipped network runs: an ONNX file, checked whole, run with
onnxruntime (no PyTorch at run time).

The view network (eq. 13), the grasp network (eq. 11) and the grasp critic are trained
with PyTorch (``pip install heapgrasp[train]``) and shipped as ONNX files
(:func:`heapgrasp.nets.export_onnx`, :mod:`heapgrasp.planning.critic_net`).
:class:`OnnxNetwork` opens one, checks it before any use and runs it on the CPU, or on a
CUDA device where onnxruntime has the CUDA execution provider (``onnxruntime-gpu``).

**The file.** An ONNX model (opset ≥ 17) with one float32 input whose first axis (the
batch) is dynamic, and these ``metadata_props``:

=============================  ==========================================================
``heapgrasp.kind``             ``"view-network"``, ``"grasp-network"``, ``"grasp-critic"``,
                               ``"viewsphere-policy"`` or ``"segmentation-network"``
``heapgrasp.format_version``   ``"1"`` (:data:`FORMAT_VERSION`)
``heapgrasp.hparams``          JSON object: the architecture and what the input must be
                               (``resolution``, ``in_channels``, ``view_shape``, ...)
``heapgrasp.provenance``       JSON object: ``command``, ``created``, ``machine``,
                               ``data``, ``metrics`` (the model card's facts)
``heapgrasp.sha256``           SHA-256 of the model without its metadata
                               (:func:`content_digest`; :func:`seal` appends it)
=============================  ==========================================================

Inputs and outputs by kind (``B`` the batch, ``R`` = ``hparams["resolution"]``,
``C`` = ``hparams["in_channels"]``):

* ``view-network``: ``grid`` ``(B, C, R, R, R)`` → ``scores`` ``(B, U, V)``,
  ``(U, V)`` = ``hparams["view_shape"]``;
* ``grasp-network``: ``grid`` ``(B, C, R, R, R)`` → ``quality`` ``(B, 1, R, R, R)``,
  ``rotation`` ``(B, 4, R, R, R)``, ``width`` ``(B, 1, R, R, R)``;
* ``grasp-critic``: ``features`` ``(B, F)`` → ``logits`` ``(B,)``,
  ``F`` = ``hparams["n_features"]``;
* ``viewsphere-policy``: ``state`` ``(B, F)`` → ``scores`` ``(B, 8)`` (one per direction
  of seed 001's viewsphere), ``F`` = ``hparams["n_features"]``;
* ``segmentation-network``: ``image`` ``(B, 3, H, W)`` → ``logits`` ``(B, K, H, W)``,
  ``H``, ``W`` dynamic (fully convolutional), ``K`` = ``len(hparams["classes"])``
  (:class:`heapgrasp.perception.segnet.NetworkSegmenter` checks the rest).

**Errors.** A missing file raises :class:`FileNotFoundError` naming it. Any other bad
file raises :class:`~heapgrasp.geometry.errors.WeightsError` whose message starts with
the file's path and says what is wrong: not a file, unreadable, empty, not an ONNX model
(truncated, garbage, a PyTorch or numpy archive), an ONNX model that is not a heapgrasp
network (metadata missing or malformed), garbled bytes (the SHA-256 differs: onnxruntime
would run altered weights without a word), another kind of network, inputs or outputs of
other names, types or shapes than its ``hparams`` say, a fixed batch axis, or a forward
pass on an all-zero input that fails or gives NaN or infinity (weights holding NaN).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, Literal

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.errors import WeightsError

if TYPE_CHECKING:
    import onnxruntime

__all__ = [
    "FORMAT_VERSION",
    "KINDS",
    "META_HPARAMS",
    "META_KIND",
    "META_PROVENANCE",
    "META_SHA256",
    "META_VERSION",
    "SHIPPED_FILES",
    "SHIPPED_VIEWSPHERE_POLICIES",
    "Kind",
    "OnnxNetwork",
    "content_digest",
    "require_onnx",
    "resolve_device",
    "seal",
    "shipped_weights",
    "weights_dir",
    "write_atomically",
]

F32 = npt.NDArray[np.float32]

Kind = Literal[
    "view-network", "grasp-network", "grasp-critic", "viewsphere-policy", "segmentation-network"
]
#: Every kind of network file.
KINDS: Final = (
    "view-network",
    "grasp-network",
    "grasp-critic",
    "viewsphere-policy",
    "segmentation-network",
)
#: ``heapgrasp.format_version`` written by this version (files of versions 1 … this load).
FORMAT_VERSION: Final = 1
META_KIND: Final = "heapgrasp.kind"
META_VERSION: Final = "heapgrasp.format_version"
META_HPARAMS: Final = "heapgrasp.hparams"
META_PROVENANCE: Final = "heapgrasp.provenance"
META_SHA256: Final = "heapgrasp.sha256"
#: The shipped file of each kind, under :func:`weights_dir`.
SHIPPED_FILES: Final[Mapping[str, str]] = {
    "view-network": "view_network.onnx",
    "grasp-network": "grasp_network.onnx",
    "grasp-critic": "critic.onnx",
}

#: The shipped viewsphere policies (seed 001's learned policies), by model.
SHIPPED_VIEWSPHERE_POLICIES: Final[Mapping[str, str]] = {
    "pca-lr": "viewsphere_pca_lr.onnx",
    "pca-lda": "viewsphere_pca_lda.onnx",
    "dqn": "viewsphere_dqn.onnx",
}

#: The shipped grasp network of each input kind (``hparams["input_kind"]``): the
#: silhouette methods' ``Ŝ≥λ`` and the VGN baseline's TSDF.
SHIPPED_GRASP_NETWORKS: Final[Mapping[str, str]] = {
    "occupancy": "grasp_network.onnx",
    "tsdf": "grasp_network_tsdf.onnx",
}

_DEVICE = re.compile(r"cpu|auto|cuda(?::(\d+))?")
_CUDA = "CUDAExecutionProvider"
_CPU = "CPUExecutionProvider"


def weights_dir() -> Path:
    """Where shipped weights live: ``<heapgrasp package>/weights``."""
    return Path(__file__).resolve().parent / "weights"


def write_atomically(data: bytes, path: str | os.PathLike[str]) -> Path:
    """Writes a weights file's bytes to ``path`` through a temporary file and a rename, so
    the file is whole or absent (the exporters and the critic's writers use it)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out


def require_onnx(purpose: str) -> Any:
    """The ``onnx`` package (building network files), or an ImportError saying
    ``purpose`` needs it and how to install it."""
    try:
        import onnx
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            f"{purpose} needs the onnx package: pip install 'heapgrasp[train]'"
        ) from exc
    return onnx


def shipped_weights(kind: Kind) -> Path | None:
    """The shipped file of ``kind`` (:data:`SHIPPED_FILES`), or None when none ships
    (viewsphere policies: :data:`SHIPPED_VIEWSPHERE_POLICIES`)."""
    _check_kind(kind)
    if kind not in SHIPPED_FILES:
        return None
    p = weights_dir() / SHIPPED_FILES[kind]
    return p if p.is_file() else None


def shipped_grasp_network(input_kind: str) -> Path | None:
    """The shipped grasp network that reads ``input_kind`` grids
    (:data:`SHIPPED_GRASP_NETWORKS`), or None when none ships."""
    if input_kind not in SHIPPED_GRASP_NETWORKS:
        raise ValueError(
            f"input_kind must be one of {', '.join(SHIPPED_GRASP_NETWORKS)}; got {input_kind!r}"
        )
    p = weights_dir() / SHIPPED_GRASP_NETWORKS[input_kind]
    return p if p.is_file() else None


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}; got {kind!r}")


# ----------------------------------------------------------------------------- checksum
# An ONNX file is a protobuf ModelProto; field 14 holds metadata_props. The checksum covers
# every other top-level field, so adding it (a field 14 entry) does not change it.
_METADATA_FIELD = 14


def _varint(data: bytes, i: int) -> tuple[int, int]:
    value, shift = 0, 0
    while True:
        if i >= len(data) or shift > 63:
            raise ValueError("truncated or malformed protobuf varint")
        b = data[i]
        value |= (b & 0x7F) << shift
        i += 1
        shift += 7
        if not b & 0x80:
            return value, i


def _encode_varint(value: int) -> bytes:
    out = bytearray()
    while True:
        b = value & 0x7F
        value >>= 7
        out.append(b | (0x80 if value else 0))
        if not value:
            return bytes(out)


def content_digest(data: bytes) -> str:
    """SHA-256 (hex) of a serialised ONNX model's top-level fields other than its
    metadata (``metadata_props``), in file order. Raises ``ValueError`` on bytes that are
    not a protobuf message."""
    h = hashlib.sha256()
    i, n = 0, len(data)
    while i < n:
        start = i
        key, i = _varint(data, i)
        field, wire = key >> 3, key & 7
        if wire == 0:
            _, i = _varint(data, i)
        elif wire == 1:
            i += 8
        elif wire == 5:
            i += 4
        elif wire == 2:
            length, i = _varint(data, i)
            i += length
        else:
            raise ValueError(f"unsupported protobuf wire type {wire}")
        if i > n:
            raise ValueError("truncated protobuf field")
        if field != _METADATA_FIELD:
            h.update(data[start:i])
    return h.hexdigest()


def seal(data: bytes) -> bytes:
    """``data`` (a serialised ONNX model holding no ``heapgrasp.sha256`` yet) with its
    :func:`content_digest` appended as the metadata entry ``heapgrasp.sha256``."""

    def field(number: int, payload: bytes) -> bytes:
        return _encode_varint(number << 3 | 2) + _encode_varint(len(payload)) + payload

    digest = content_digest(data).encode()
    entry = field(1, META_SHA256.encode()) + field(2, digest)
    return bytes(data) + field(_METADATA_FIELD, entry)


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
        _check_kind(kind)
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
        _check_kind(kind)
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
                "networks ship as ONNX (heapgrasp.nets.export_onnx)"
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
