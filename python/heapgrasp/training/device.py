"""Where the networks run: a device name, checked against the devices PyTorch sees."""

from __future__ import annotations

import re

import torch

__all__ = ["resolve_device"]

_SPEC = re.compile(r"cpu|auto|cuda(?::(\d+))?")


def resolve_device(spec: str) -> str:
    """``cpu``, ``cuda``, ``cuda:N``, or ``auto`` (``cuda`` where PyTorch sees a CUDA
    device, else ``cpu``) as the device name to run on.

    Raises ``ValueError`` naming ``spec`` when it is none of these, or when it asks for a
    CUDA device PyTorch does not see: a network asked to run on a GPU never runs on the
    CPU instead without saying so.
    """
    match = _SPEC.fullmatch(spec) if isinstance(spec, str) else None
    if match is None:
        raise ValueError(f"device must be cpu, cuda, cuda:N or auto; got {spec!r}")
    if spec == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if spec.startswith("cuda"):
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        index = int(match.group(1) or 0)
        if index >= count:
            raise ValueError(f"{spec!r} asked for, but PyTorch sees {count} CUDA device(s)")
    return spec
