"""The two networks of HEAPGrasp §IV-B: the grasp network (eq. 11) and the view network
(eq. 13).

Both read a ``(B, 1, R, R, R)`` grid indexed ``[x, y, z]`` (the package convention, z up;
the view network optionally a second channel, ``in_channels = 2``) and share the
architecture of their 3-D encoder, :class:`Encoder3d` (VGN's, Breyer et al. 2020): three
stride-2 3-D convolutions, ``R → R/2 → R/4 → R/8``, so ``R`` must be a multiple of 8 (40
in the paper, Table I).

* :class:`GraspNet` — the encoder-decoder 3-D CNN of the grasp planning module: a VGN
  decoder (three ``conv3d → ReLU → trilinear ×2`` blocks) back to ``R³`` and three
  per-voxel heads giving ``S_grasp`` (sigmoid, in [0, 1]), ``R_grasp`` (unit quaternion
  ``x, y, z, w`` in the grid's axes) and ``W_grasp`` (opening width, metres) of eq. 11.
* :class:`ViewNet` — the view planning network: the same encoder, then the 3-D feature map
  is compressed along z (height) to a 2-D ``(x, y)`` map, followed by several
  ``conv2d → ReLU → upsample`` blocks and a final ``conv2d → sigmoid`` giving the
  ``U × V`` view scores ``S_cam`` of eq. 13 (40 × 20 in the paper).

**z-compression (ViewNet).** The paper only says the encoder's 3-D map is "compressed along
the z-axis". We fold height into channels — ``(B, C, X, Y, Z) → (B, C·Z, X, Y)`` — and mix
them with a learned 1 × 1 2-D convolution + ReLU (``C·Z → compress_channels``). Unlike a
max/mean over z this keeps *at which height* a feature lies, which matters for occlusion
(what a camera at polar angle θ can see over); it costs ``C·Z·compress_channels`` weights
(20 k at R = 40) and ties the network to one resolution ``R``.

**Up-sampling to U × V (ViewNet).** The 2-D map starts at ``(R/8, R/8)`` (5 × 5 at R = 40).
Each of ``len(up_channels)`` blocks applies ``conv2d 3×3 → ReLU`` and then a bilinear
resize that doubles each side, capped at the target (U, V); the last block resizes to
exactly ``(U, V)``. For R = 40, U × V = 40 × 20 the sizes are 5×5 → 10×10 → 20×20 → 40×20.
Row ``u`` of the output is the azimuth ``φ = 2π u / U``, column ``v`` the polar angle
``θ = θ_max v / V`` (0-based), eq. 12-13.

Both networks are deterministic in eval mode on the CPU (no dropout, no batch norm).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
import torch.nn.functional as F
from torch import Tensor, nn

__all__ = [
    "DEFAULT_RESOLUTION",
    "DEFAULT_VIEW_SHAPE",
    "Encoder3d",
    "GraspNet",
    "ViewNet",
]

#: Voxel grid resolution ``N_x = N_y = N_z`` of Table I.
DEFAULT_RESOLUTION = 40
#: Azimuth and polar divisions ``(U, V)`` of Table I.
DEFAULT_VIEW_SHAPE = (40, 20)

_ENCODER_CHANNELS = (16, 32, 64)
_ENCODER_KERNELS = (5, 3, 3)
_GRASP_DECODER_CHANNELS = (64, 32, 16)
_GRASP_DECODER_KERNELS = (3, 3, 5)
_HEAD_KERNEL = 5
_VIEW_UP_CHANNELS = (64, 32, 16)


def _ints(name: str, values: Sequence[int], length: int | None = None) -> tuple[int, ...]:
    out = tuple(int(v) for v in values)
    if length is not None and len(out) != length:
        raise ValueError(f"{name} must have {length} entries, got {len(out)}")
    if not out or any(v < 1 for v in out):
        raise ValueError(f"{name} must be a non-empty list of positive integers, got {out}")
    return out


def _odd_kernels(name: str, values: Sequence[int], length: int) -> tuple[int, ...]:
    out = _ints(name, values, length)
    if any(k % 2 == 0 for k in out):
        raise ValueError(f"{name} must be odd (same padding), got {out}")
    return out


def _check_resolution(resolution: int, levels: int) -> int:
    r = int(resolution)
    factor = 2**levels
    if r < factor or r % factor != 0:
        raise ValueError(
            f"grid resolution R = {r} does not fit the {levels}-level stride-2 encoder: "
            f"R must be a positive multiple of {factor} (40 in the paper)"
        )
    return r


def _check_grid(x: Tensor, resolution: int, who: str, channels: int = 1) -> None:
    r, c = resolution, channels
    if x.dim() != 5 or x.shape[1] != c or tuple(x.shape[2:]) != (r, r, r):
        raise ValueError(f"{who} expects a (B, {c}, {r}, {r}, {r}) grid, got {tuple(x.shape)}")


class Encoder3d(nn.Module):
    """VGN's 3-D encoder: ``len(channels)`` blocks of ``conv3d (stride 2, same padding)
    → ReLU``; ``(B, 1, R, R, R) → (B, channels[-1], R/2^n, R/2^n, R/2^n)``.

    Parameters
    ----------
    channels : sequence of int
        Output channels of each block (VGN: 16, 32, 64).
    kernels : sequence of int
        Odd kernel size of each block (VGN: 5, 3, 3).
    in_channels : int
        Channels of the input grid (1: occupancy ``Ŝ≥λ`` / ``Ŝ_{0-1}`` of eq. 9-10, or a TSDF).
    """

    def __init__(
        self,
        channels: Sequence[int] = _ENCODER_CHANNELS,
        kernels: Sequence[int] = _ENCODER_KERNELS,
        in_channels: int = 1,
    ) -> None:
        super().__init__()
        self.channels = _ints("encoder channels", channels)
        self.kernels = _odd_kernels("encoder kernels", kernels, len(self.channels))
        self.in_channels = int(in_channels)
        layers: list[nn.Module] = []
        prev = self.in_channels
        for c, k in zip(self.channels, self.kernels, strict=True):
            layers.append(nn.Conv3d(prev, c, k, stride=2, padding=k // 2))
            prev = c
        self.convs = nn.ModuleList(layers)

    @property
    def levels(self) -> int:
        """Number of stride-2 blocks (the input side must be a multiple of ``2**levels``)."""
        return len(self.channels)

    @property
    def out_channels(self) -> int:
        """Channels of the feature map."""
        return self.channels[-1]

    def forward(self, x: Tensor) -> Tensor:
        """``(B, C_in, R, R, R) → (B, C_out, R/2^n, R/2^n, R/2^n)``."""
        for conv in self.convs:
            x = F.relu(conv(x))
        return x


class GraspNet(nn.Module):
    """Encoder-decoder 3-D CNN of the grasp planning module (HEAPGrasp eq. 11, VGN).

    ``forward(x)`` with ``x`` of shape ``(B, 1, R, R, R)`` returns

    * ``quality`` ``(B, 1, R, R, R)``: ``S_grasp ∈ [0, 1]`` (sigmoid);
    * ``rotation`` ``(B, 4, R, R, R)``: ``R_grasp``, unit quaternions ``x, y, z, w`` of the
      TCP (z = approach, fingers along y) in the grid's axes (world-aligned);
    * ``width`` ``(B, 1, R, R, R)``: ``W_grasp``, gripper opening in metres (no activation,
      as VGN; consumers clip it).

    Parameters
    ----------
    resolution : int
        Grid side ``R`` (a multiple of ``2**len(encoder_channels)``). The network is fully
        convolutional, but its weights are learnt for one voxel size, so the input side is
        checked against it.
    encoder_channels, encoder_kernels : sequence of int
        :class:`Encoder3d` (VGN: 16, 32, 64 and 5, 3, 3).
    decoder_channels, decoder_kernels : sequence of int
        ``conv3d → ReLU → trilinear ×2`` blocks (VGN: 64, 32, 16 and 3, 3, 5); as many as
        encoder blocks, so the output is back at ``R³``.
    head_kernel : int
        Kernel of the three output convolutions (VGN: 5).
    """

    def __init__(
        self,
        resolution: int = DEFAULT_RESOLUTION,
        *,
        encoder_channels: Sequence[int] = _ENCODER_CHANNELS,
        encoder_kernels: Sequence[int] = _ENCODER_KERNELS,
        decoder_channels: Sequence[int] = _GRASP_DECODER_CHANNELS,
        decoder_kernels: Sequence[int] = _GRASP_DECODER_KERNELS,
        head_kernel: int = _HEAD_KERNEL,
    ) -> None:
        super().__init__()
        self.encoder = Encoder3d(encoder_channels, encoder_kernels)
        self.resolution = _check_resolution(resolution, self.encoder.levels)
        dec = _ints("decoder channels", decoder_channels, self.encoder.levels)
        self.decoder_channels = dec
        self.decoder_kernels = _odd_kernels("decoder kernels", decoder_kernels, len(dec))
        (self.head_kernel,) = _odd_kernels("head kernel", (head_kernel,), 1)
        layers: list[nn.Module] = []
        prev = self.encoder.out_channels
        for c, k in zip(dec, self.decoder_kernels, strict=True):
            layers.append(nn.Conv3d(prev, c, k, padding=k // 2))
            prev = c
        self.decoder = nn.ModuleList(layers)
        hk = self.head_kernel
        self.quality_head = nn.Conv3d(prev, 1, hk, padding=hk // 2)
        self.rotation_head = nn.Conv3d(prev, 4, hk, padding=hk // 2)
        self.width_head = nn.Conv3d(prev, 1, hk, padding=hk // 2)

    def hparams(self) -> dict[str, Any]:
        """Constructor arguments as plain types (stored with the weights)."""
        return {
            "resolution": self.resolution,
            "encoder_channels": list(self.encoder.channels),
            "encoder_kernels": list(self.encoder.kernels),
            "decoder_channels": list(self.decoder_channels),
            "decoder_kernels": list(self.decoder_kernels),
            "head_kernel": self.head_kernel,
        }

    def forward(self, x: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """``(B, 1, R, R, R) → (quality, rotation, width)`` (see the class docstring)."""
        _check_grid(x, self.resolution, "GraspNet")
        h = self.encoder(x)
        for conv in self.decoder:
            h = F.interpolate(F.relu(conv(h)), scale_factor=2.0, mode="trilinear")
        quality = torch.sigmoid(self.quality_head(h))
        rotation = _unit_quaternions(self.rotation_head(h))
        width = self.width_head(h)
        return quality, rotation, width


def _unit_quaternions(raw: Tensor, eps: float = 1e-12) -> Tensor:
    """L2-normalise along dim 1; a (numerically) zero vector becomes the identity
    ``(0, 0, 0, 1)`` so every output is a unit quaternion."""
    norm = torch.linalg.vector_norm(raw, dim=1, keepdim=True)
    identity = torch.zeros_like(raw)
    identity[:, 3] = 1.0
    return torch.where(norm > eps, raw / norm.clamp_min(eps), identity)


class ViewNet(nn.Module):
    """View planning network (HEAPGrasp eq. 13): ``Ŝ_{0-1}`` grid → ``U × V`` view scores.

    ``forward(x)`` with ``x`` of shape ``(B, in_channels, R, R, R)`` returns ``(B, U, V)`` scores in
    [0, 1]; ``[b, u, v]`` scores the candidate at azimuth ``φ = 2π u / U`` and polar angle
    ``θ = θ_max v / V`` (eq. 12, 0-based indices), the network's estimate of eq. 14.

    Parameters
    ----------
    resolution : int
        Grid side ``R``, a multiple of ``2**len(encoder_channels)`` (the z-compression layer
        depends on it).
    view_shape : tuple of int
        ``(U, V)``, azimuth and polar divisions (40, 20 in Table I).
    encoder_channels, encoder_kernels : sequence of int
        :class:`Encoder3d`, as the grasp network's.
    compress_channels : int
        Channels after the z-compression (fold ``C·Z`` into channels, 1×1 conv, ReLU).
    up_channels : sequence of int
        Channels of the ``conv2d 3×3 → ReLU → upsample`` blocks.
    head_kernel : int
        Kernel of the final ``conv2d → sigmoid``.
    in_channels : int
        Channels of the input grid: 1 is the paper's ``Ŝ_{0-1}`` alone; 2 adds the x–y
        column mask eq. 14 is counted on (broadcast along z, 0/1), for scores restricted to
        a region (``OracleViewScorer(target_radius > 0)``).
    """

    def __init__(
        self,
        resolution: int = DEFAULT_RESOLUTION,
        view_shape: Sequence[int] = DEFAULT_VIEW_SHAPE,
        *,
        encoder_channels: Sequence[int] = _ENCODER_CHANNELS,
        encoder_kernels: Sequence[int] = _ENCODER_KERNELS,
        compress_channels: int = 64,
        up_channels: Sequence[int] = _VIEW_UP_CHANNELS,
        head_kernel: int = 3,
        in_channels: int = 1,
    ) -> None:
        super().__init__()
        (channels,) = _ints("in_channels", (in_channels,), 1)
        self.encoder = Encoder3d(encoder_channels, encoder_kernels, in_channels=channels)
        self.resolution = _check_resolution(resolution, self.encoder.levels)
        u, v = _ints("view_shape (U, V)", view_shape, 2)
        self.view_shape = (u, v)
        (self.compress_channels,) = _ints("compress_channels", (compress_channels,), 1)
        self.up_channels = _ints("up_channels", up_channels)
        (self.head_kernel,) = _odd_kernels("head kernel", (head_kernel,), 1)
        latent = self.resolution >> self.encoder.levels
        self.latent_side = latent
        self.compress = nn.Conv2d(self.encoder.out_channels * latent, self.compress_channels, 1)
        layers: list[nn.Module] = []
        prev = self.compress_channels
        for c in self.up_channels:
            layers.append(nn.Conv2d(prev, c, 3, padding=1))
            prev = c
        self.ups = nn.ModuleList(layers)
        self.head = nn.Conv2d(prev, 1, self.head_kernel, padding=self.head_kernel // 2)
        self.sizes = self._upsample_sizes()

    def _upsample_sizes(self) -> tuple[tuple[int, int], ...]:
        """Map size after each block: ×2 per side, capped at (U, V); the last is (U, V)."""
        sizes = []
        cur = (self.latent_side, self.latent_side)
        n = len(self.up_channels)
        for i in range(n):
            if i == n - 1:
                cur = self.view_shape
            else:
                cur = (min(2 * cur[0], self.view_shape[0]), min(2 * cur[1], self.view_shape[1]))
            sizes.append(cur)
        return tuple(sizes)

    def hparams(self) -> dict[str, Any]:
        """Constructor arguments as plain types (stored with the weights)."""
        return {
            "resolution": self.resolution,
            "view_shape": list(self.view_shape),
            "encoder_channels": list(self.encoder.channels),
            "encoder_kernels": list(self.encoder.kernels),
            "compress_channels": self.compress_channels,
            "up_channels": list(self.up_channels),
            "head_kernel": self.head_kernel,
            "in_channels": self.in_channels,
        }

    @property
    def in_channels(self) -> int:
        """Channels of the input grid (1: ``Ŝ_{0-1}``; 2: plus the region mask)."""
        return self.encoder.in_channels

    def compress_z(self, features: Tensor) -> Tensor:
        """z-compression: ``(B, C, X, Y, Z) → (B, C·Z, X, Y)`` (height folded into
        channels) → 1×1 conv → ReLU ``(B, compress_channels, X, Y)``."""
        b, c, x, y, z = features.shape
        folded = features.permute(0, 1, 4, 2, 3).reshape(b, c * z, x, y)
        return F.relu(self.compress(folded))

    def forward(self, x: Tensor) -> Tensor:
        """``(B, in_channels, R, R, R) → (B, U, V)`` view scores in [0, 1] (eq. 13)."""
        _check_grid(x, self.resolution, "ViewNet", self.in_channels)
        h = self.compress_z(self.encoder(x))
        for conv, size in zip(self.ups, self.sizes, strict=True):
            h = F.relu(conv(h))
            if tuple(h.shape[2:]) != size:
                h = F.interpolate(h, size=size, mode="bilinear")
        return torch.sigmoid(self.head(h))[:, 0]
