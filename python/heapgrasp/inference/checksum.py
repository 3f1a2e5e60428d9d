"""The content checksum of a network file, computed on the ONNX protobuf's bytes by hand
(the ``onnx`` package is a training dependency, not a run-time one): the SHA-256 of
every top-level field but the metadata, appended by :func:`seal` and checked by
:class:`~heapgrasp.inference.network.OnnxNetwork`."""

from __future__ import annotations

import hashlib

from heapgrasp.inference.files import META_SHA256

__all__ = ["content_digest", "seal"]

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
