"""The grasp critic's models as ONNX graphs, and the small 3-D convolutional critic's
training: the two crops of :func:`~heapgrasp.planning.critic.candidate_features` read by
two 3-D convolutions, then with the scalar features by a hidden layer (the paper's
answer to grasp quality is a 3-D CNN on the occupancy grid, §IV-B; this one reads the
grid only around a candidate).

Layers of the ``cnn`` model (the input standardised as the linear critic's is):

1. the crops as 2 channels of :data:`~heapgrasp.planning.critic.CROP_SHAPE` voxels;
2. 3³ convolution (padding 1) to ``c1`` channels, ReLU, 2³ max pooling;
3. 3³ convolution (padding 1) to ``c2`` channels, ReLU, adaptive average pooling to 2³
   (on the 3 × 6 × 6 map: windows 2 × 3 × 3, strides 1 × 3 × 3, PyTorch's bins);
4. with the :data:`~heapgrasp.planning.critic.N_SCALARS` scalars, a ``hidden``-unit
   layer, ReLU (dropout 0.3 in training), and one logit.

Every critic file is an ONNX graph from the raw feature rows to the logits, the
standardisation included (:func:`critic_onnx`), run with onnxruntime like every shipped
network (:class:`heapgrasp.inference.OnnxNetwork`). Building one needs the ``onnx``
package and training the ``cnn`` model PyTorch (``pip install heapgrasp[train]``);
running one needs neither. :func:`convert_npz` turns a critic of the former ``.npz``
format into ONNX.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from heapgrasp.inference import (
    FORMAT_VERSION,
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_VERSION,
    require_onnx,
    seal,
    write_atomically,
)
from heapgrasp.planning.critic import (
    ARRAYS,
    CROP_SHAPE,
    N_SCALARS,
    cnn_shapes,
    read_critic_arrays,
)

if TYPE_CHECKING:
    import onnx

__all__ = [
    "OPSET",
    "ConvCritic",
    "convert_npz",
    "critic_onnx",
    "fit_conv",
    "with_metadata",
]

F64 = npt.NDArray[np.float64]

#: ONNX opset of critic files.
OPSET = 17

_N_CROP = 2 * int(np.prod(CROP_SHAPE))
_N_FEATURES = _N_CROP + N_SCALARS


@dataclass
class ConvCritic:
    """The ``cnn`` model's weights (numpy, PyTorch's layouts; fields in the order of
    :data:`~heapgrasp.planning.critic.ARRAYS`), checked to fit together;
    :func:`critic_onnx` makes them a graph that runs."""

    conv1_w: F64
    conv1_b: F64
    conv2_w: F64
    conv2_b: F64
    fc1_w: F64
    fc1_b: F64
    fc2_w: F64
    fc2_b: F64

    def __post_init__(self) -> None:
        c1, c2, hidden = len(self.conv1_b), len(self.conv2_b), len(self.fc1_b)
        for name, shape in cnn_shapes(c1, c2, hidden).items():
            got = getattr(self, name).shape
            if got != shape:
                raise ValueError(f"critic network: {name} must have shape {shape}, got {got}")

    def arrays(self) -> dict[str, F64]:
        """The weights by name (:data:`~heapgrasp.planning.critic.ARRAYS`)."""
        return {name: getattr(self, name) for name in ARRAYS}

    def hparams(self) -> dict[str, int]:
        """Channels of the two convolutions and width of the hidden layer."""
        return {"c1": len(self.conv1_b), "c2": len(self.conv2_b), "hidden": len(self.fc1_b)}


def critic_onnx(
    mean: npt.ArrayLike,
    scale: npt.ArrayLike,
    *,
    net: ConvCritic | None = None,
    components: npt.ArrayLike | None = None,
    weights: npt.ArrayLike | None = None,
    hparams: Mapping[str, Any],
    provenance: Mapping[str, Any],
) -> bytes:
    """A critic as a serialised ONNX model: ``features`` ``(B, F)`` float32 →
    standardise with ``mean`` and ``scale`` → the model → ``logits`` ``(B,)``.

    The model is ``net`` (``cnn``) or, without it, PCA ``components`` ``(k, crop
    features)`` and logistic ``weights`` (``k + N_SCALARS + 1``, bias last: ``linear``).
    ``hparams`` (``model``, ``threshold``, ``candidate_epsilon``, ...) and
    ``provenance`` are stored as the file's metadata with ``crop_shape`` and
    ``n_features`` added. Needs the ``onnx`` package."""
    onnx = require_onnx("building a grasp critic (training, conversion)")
    from onnx import TensorProto, helper, numpy_helper

    m = np.asarray(mean, dtype=np.float64)
    s = np.asarray(scale, dtype=np.float64)
    if m.shape != (_N_FEATURES,) or s.shape != (_N_FEATURES,):
        raise ValueError(
            f"mean and scale must have shape ({_N_FEATURES},), got {m.shape} and {s.shape}"
        )
    if not (np.isfinite(m).all() and np.isfinite(s).all() and (s > 0).all()):
        raise ValueError("mean and scale must be finite, and scale > 0")

    def const(name: str, value: npt.ArrayLike, dtype: type = np.float32) -> Any:
        return numpy_helper.from_array(np.ascontiguousarray(value, dtype=dtype), name)

    inits = [
        const("mean", m),
        const("scale", s),
        const("crop_start", [0], np.int64),
        const("crop_end", [_N_CROP], np.int64),
        const("scalar_end", [_N_FEATURES], np.int64),
        const("axis1", [1], np.int64),
    ]
    nodes = [
        helper.make_node("Sub", ["features", "mean"], ["centred"]),
        helper.make_node("Div", ["centred", "scale"], ["z"]),
        helper.make_node("Slice", ["z", "crop_start", "crop_end", "axis1"], ["z_crops"]),
        helper.make_node("Slice", ["z", "crop_end", "scalar_end", "axis1"], ["z_scalars"]),
    ]
    hp = dict(hparams)
    if net is not None:
        model = "cnn"
        inits += [const(k, v) for k, v in net.arrays().items()]
        inits.append(const("crop_shape", [-1, 2, *CROP_SHAPE], np.int64))
        pool = _avg_pool_to_2([n // 2 for n in CROP_SHAPE])
        nodes += [
            helper.make_node("Reshape", ["z_crops", "crop_shape"], ["crops"]),
            helper.make_node(
                "Conv",
                ["crops", "conv1_w", "conv1_b"],
                ["h1"],
                kernel_shape=[3, 3, 3],
                pads=[1] * 6,
            ),
            helper.make_node("Relu", ["h1"], ["r1"]),
            helper.make_node("MaxPool", ["r1"], ["p1"], kernel_shape=[2, 2, 2], strides=[2, 2, 2]),
            helper.make_node(
                "Conv", ["p1", "conv2_w", "conv2_b"], ["h2"], kernel_shape=[3, 3, 3], pads=[1] * 6
            ),
            helper.make_node("Relu", ["h2"], ["r2"]),
            helper.make_node(
                "AveragePool",
                ["r2"],
                ["p2"],
                kernel_shape=pool["kernel_shape"],
                strides=pool["strides"],
            ),
            helper.make_node("Flatten", ["p2"], ["f2"], axis=1),
            helper.make_node("Concat", ["f2", "z_scalars"], ["hidden_in"], axis=1),
            helper.make_node("Gemm", ["hidden_in", "fc1_w", "fc1_b"], ["g1"], transB=1),
            helper.make_node("Relu", ["g1"], ["hidden"]),
            helper.make_node("Gemm", ["hidden", "fc2_w", "fc2_b"], ["g2"], transB=1),
            helper.make_node("Squeeze", ["g2", "axis1"], ["logits"]),
        ]
        hp.update(net.hparams())
    else:
        if components is None or weights is None:
            raise ValueError("a linear critic needs components and weights (or pass net)")
        c = np.asarray(components, dtype=np.float64)
        w = np.asarray(weights, dtype=np.float64)
        k = c.shape[0] if c.ndim == 2 else -1
        if c.shape != (k, _N_CROP) or w.shape != (k + N_SCALARS + 1,) or k < 1:
            raise ValueError(
                f"critic arrays do not fit together: components {c.shape}, weights {w.shape} "
                f"(expected (k >= 1, {_N_CROP}) and (k + {N_SCALARS + 1},))"
            )
        model = "linear"
        inits += [const("components_t", c.T), const("w", w[:-1]), const("b", w[-1:])]
        nodes += [
            helper.make_node("MatMul", ["z_crops", "components_t"], ["projected"]),
            helper.make_node("Concat", ["projected", "z_scalars"], ["design"], axis=1),
            helper.make_node("MatMul", ["design", "w"], ["wx"]),
            helper.make_node("Add", ["wx", "b"], ["logits"]),
        ]
        hp["components"] = k
    hp.update(model=model, crop_shape=list(CROP_SHAPE), n_features=_N_FEATURES)
    graph = helper.make_graph(
        nodes,
        f"heapgrasp-grasp-critic-{model}",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, ["batch", _N_FEATURES])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch"])],
        inits,
    )
    proto = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="heapgrasp"
    )
    _set_metadata(proto, hp, provenance)
    onnx.checker.check_model(proto, full_check=True)
    return seal(proto.SerializeToString())


def _avg_pool_to_2(sizes: list[int]) -> dict[str, list[int]]:
    """``AveragePool`` attributes giving PyTorch's adaptive average pooling to 2 per axis
    (bins ``floor(i·L/2)`` to ``ceil((i+1)·L/2)``): equal windows, so ``L`` must be even
    or 3."""
    kernels, strides = [], []
    for n in sizes:
        if n % 2 == 0:
            kernels.append(n // 2)
            strides.append(n // 2)
        elif n == 3:  # bins [0, 2) and [1, 3)
            kernels.append(2)
            strides.append(1)
        else:  # pragma: no cover - CROP_SHAPE fixes the sizes
            raise ValueError(f"adaptive pooling of {n} to 2 has unequal bins")
    return {"kernel_shape": kernels, "strides": strides}


def _set_metadata(
    proto: onnx.ModelProto, hparams: Mapping[str, Any], provenance: Mapping[str, Any]
) -> None:
    meta = {
        META_KIND: "grasp-critic",
        META_VERSION: str(FORMAT_VERSION),
        META_HPARAMS: json.dumps(dict(hparams), sort_keys=True, allow_nan=False),
        META_PROVENANCE: json.dumps(dict(provenance), sort_keys=True, allow_nan=False),
    }
    del proto.metadata_props[:]
    for key, value in meta.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value


def with_metadata(
    model_bytes: bytes, hparams: Mapping[str, Any], provenance: Mapping[str, Any]
) -> bytes:
    """The serialised critic ``model_bytes`` with its metadata replaced."""
    onnx = require_onnx("building a grasp critic (training, conversion)")
    proto = onnx.load_model_from_string(model_bytes)
    _set_metadata(proto, hparams, provenance)
    return seal(proto.SerializeToString())


def convert_npz(
    src: str | os.PathLike[str], dst: str | os.PathLike[str], *, command: str = ""
) -> Path:
    """Converts a critic of the former ``.npz`` format (read and checked whole by
    :func:`~heapgrasp.planning.critic.read_critic_arrays`) to an ONNX critic file at
    ``dst``: the same model, standardisation, threshold and ε, its metadata kept as the
    provenance with the conversion noted."""
    arrays, meta = read_critic_arrays(src)
    hparams = {
        "threshold": float(arrays["threshold"]),
        "candidate_epsilon": float(arrays["candidate_epsilon"]),
    }
    provenance = {
        **meta,
        "converted": {
            "from": Path(src).name,
            "command": command,
            "created": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        },
    }
    net = None
    if int(arrays["version"]) == 2:
        net = ConvCritic(*(arrays[f"net_{k}"].astype(np.float64) for k in ARRAYS))
    data = critic_onnx(
        arrays["mean"],
        arrays["scale"],
        net=net,
        components=None if net is not None else arrays["components"],
        weights=None if net is not None else arrays["weights"],
        hparams=hparams,
        provenance=provenance,
    )
    return write_atomically(data, dst)


def _torch_module(c1: int, c2: int, hidden: int):  # type: ignore[no-untyped-def]
    import torch

    class Net(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.conv1 = torch.nn.Conv3d(2, c1, 3, padding=1)
            self.conv2 = torch.nn.Conv3d(c1, c2, 3, padding=1)
            self.fc1 = torch.nn.Linear(8 * c2 + N_SCALARS, hidden)
            self.fc2 = torch.nn.Linear(hidden, 1)
            self.drop = torch.nn.Dropout(0.3)

        def forward(self, z: torch.Tensor) -> torch.Tensor:
            crops = z[:, :_N_CROP].reshape(-1, 2, *CROP_SHAPE)
            h = torch.max_pool3d(torch.relu(self.conv1(crops)), 2)
            h = torch.nn.functional.adaptive_avg_pool3d(torch.relu(self.conv2(h)), 2)
            h = torch.cat([h.flatten(1), z[:, _N_CROP:]], 1)
            logits: torch.Tensor = self.fc2(self.drop(torch.relu(self.fc1(h))))[:, 0]
            return logits

    return Net()


def fit_conv(
    z: npt.ArrayLike,
    labels: npt.ArrayLike,
    *,
    epochs: int = 30,
    weight_decay: float = 1e-2,
    channels: tuple[int, int] = (8, 16),
    hidden: int = 64,
    seed: int = 0,
) -> ConvCritic:
    """Trains the network on standardised rows ``z`` and 0/1 ``labels`` (AdamW, learning
    rate 1e-3, batches of 128, binary cross-entropy) on the CPU; deterministic for a
    ``seed``. Needs PyTorch."""
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            "training the convolutional critic needs PyTorch: pip install 'heapgrasp[train]'"
        ) from exc
    x = np.asarray(z, dtype=np.float32)
    y = np.asarray(labels, dtype=np.float32)
    if x.ndim != 2 or x.shape[1] != _N_CROP + N_SCALARS or len(x) != len(y) or len(y) == 0:
        raise ValueError(
            f"z must be (n, {_N_CROP + N_SCALARS}) with n = len(labels) > 0, "
            f"got {x.shape} and {y.shape}"
        )
    if epochs < 1:
        raise ValueError(f"epochs must be >= 1, got {epochs}")
    gen = torch.Generator().manual_seed(seed)
    torch.manual_seed(seed)
    net = _torch_module(channels[0], channels[1], hidden)
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3, weight_decay=weight_decay)
    xt, yt = torch.from_numpy(x), torch.from_numpy(y)
    net.train()
    for _ in range(epochs):
        perm = torch.randperm(len(xt), generator=gen)
        for i in range(0, len(xt), 128):
            batch = perm[i : i + 128]
            loss = torch.nn.functional.binary_cross_entropy_with_logits(net(xt[batch]), yt[batch])
            opt.zero_grad()
            loss.backward()  # type: ignore[no-untyped-call]
            opt.step()
    net.eval()
    params = {
        "conv1_w": net.conv1.weight,
        "conv1_b": net.conv1.bias,
        "conv2_w": net.conv2.weight,
        "conv2_b": net.conv2.bias,
        "fc1_w": net.fc1.weight,
        "fc1_b": net.fc1.bias,
        "fc2_w": net.fc2.weight,
        "fc2_b": net.fc2.bias,
    }
    return ConvCritic(**{k: v.detach().numpy().astype(np.float64) for k, v in params.items()})
