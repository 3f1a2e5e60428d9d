"""A small 3-D convolutional grasp critic: the two crops of
:func:`~heapgrasp.planning.critic.candidate_features` read by two 3-D convolutions, then
with the scalar features by a hidden layer (the paper's answer to grasp quality is a 3-D
CNN on the occupancy grid, §IV-B; this one reads the grid only around a candidate).

Layers (the input standardised as the linear critic's is):

1. the crops as 2 channels of :data:`~heapgrasp.planning.critic.CROP_SHAPE` voxels;
2. 3³ convolution (padding 1) to ``c1`` channels, ReLU, 2³ max pooling;
3. 3³ convolution (padding 1) to ``c2`` channels, ReLU, adaptive average pooling to 2³;
4. with the :data:`~heapgrasp.planning.critic.N_SCALARS` scalars, a ``hidden``-unit
   layer, ReLU (dropout 0.3 in training), and one logit.

Training needs PyTorch (``pip install heapgrasp[nets]``); :meth:`ConvCritic.logits` is
plain numpy, so running a trained critic needs nothing beyond the base install.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numpy.lib.stride_tricks import sliding_window_view

from heapgrasp.planning.critic import CROP_SHAPE, N_SCALARS

__all__ = ["ARRAYS", "ConvCritic", "fit_conv"]

F64 = npt.NDArray[np.float64]

ARRAYS = ("conv1_w", "conv1_b", "conv2_w", "conv2_b", "fc1_w", "fc1_b", "fc2_w", "fc2_b")
"""The network's arrays, in the order of :class:`ConvCritic`'s fields."""

_N_CROP = 2 * int(np.prod(CROP_SHAPE))


def _conv3d(x: F64, w: F64, b: F64) -> F64:
    """3³ cross-correlation with padding 1 (as ``torch.nn.Conv3d(padding=1)``)."""
    xp = np.pad(x, ((0, 0), (0, 0), (1, 1), (1, 1), (1, 1)))
    win = sliding_window_view(xp, (3, 3, 3), axis=(2, 3, 4))
    out = np.einsum("ncdhwijk,ocijk->nodhw", win, w, optimize=True)
    return np.asarray(out + b[None, :, None, None, None], dtype=np.float64)


def _max_pool2(x: F64) -> F64:
    n, c, d, h, w = x.shape
    x = x[:, :, : d // 2 * 2, : h // 2 * 2, : w // 2 * 2]
    return np.asarray(x.reshape(n, c, d // 2, 2, h // 2, 2, w // 2, 2).max(axis=(3, 5, 7)))


def _adaptive_avg2(x: F64) -> F64:
    """Adaptive average pooling to 2³ with PyTorch's bins (``floor(i·L/2)`` to
    ``ceil((i+1)·L/2)``)."""

    def bins(length: int) -> list[slice]:
        return [slice((i * length) // 2, -(-((i + 1) * length) // 2)) for i in range(2)]

    n, c = x.shape[:2]
    out = np.empty((n, c, 2, 2, 2))
    for i, si in enumerate(bins(x.shape[2])):
        for j, sj in enumerate(bins(x.shape[3])):
            for k, sk in enumerate(bins(x.shape[4])):
                out[:, :, i, j, k] = x[:, :, si, sj, sk].mean(axis=(2, 3, 4))
    return out


@dataclass
class ConvCritic:
    """The network's weights (numpy, PyTorch's layouts); :meth:`logits` runs it."""

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
        expected = {
            "conv1_w": (c1, 2, 3, 3, 3),
            "conv2_w": (c2, c1, 3, 3, 3),
            "fc1_w": (hidden, 8 * c2 + N_SCALARS),
            "fc2_w": (1, hidden),
            "fc2_b": (1,),
        }
        for name, shape in expected.items():
            got = getattr(self, name).shape
            if got != shape:
                raise ValueError(f"critic network: {name} must have shape {shape}, got {got}")

    def logits(self, z: npt.ArrayLike) -> F64:
        """Logits of standardised feature rows ``z`` (``(n, crops + scalars)``)."""
        x = np.atleast_2d(np.asarray(z, dtype=np.float64))
        if x.shape[1] != _N_CROP + N_SCALARS:
            raise ValueError(f"features must have {_N_CROP + N_SCALARS} columns, got {x.shape[1]}")
        crops = x[:, :_N_CROP].reshape(-1, 2, *CROP_SHAPE)
        h = np.maximum(_conv3d(crops, self.conv1_w, self.conv1_b), 0.0)
        h = _max_pool2(h)
        h = np.maximum(_conv3d(h, self.conv2_w, self.conv2_b), 0.0)
        h = _adaptive_avg2(h).reshape(len(x), -1)
        h = np.hstack([h, x[:, _N_CROP:]])
        h = np.maximum(h @ self.fc1_w.T + self.fc1_b, 0.0)
        return np.asarray((h @ self.fc2_w.T + self.fc2_b)[:, 0])

    def arrays(self) -> dict[str, F64]:
        """The weights by name (:data:`ARRAYS`)."""
        return {name: getattr(self, name) for name in ARRAYS}


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
            "training the convolutional critic needs PyTorch: pip install 'heapgrasp[nets]'"
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
