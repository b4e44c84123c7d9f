"""The build journal's file format: checksummed frames of self-contained, pickle-free point records.

File format (version 1, all integers little-endian)::

    file    := MAGIC frame(header) frame(record)*
    MAGIC   := b"LUTGEN-JOURNAL\\x00\\x01"                       (16 bytes)
    frame   := length:u64  digest:32 bytes  payload[length]
               digest = SHA-256(length:u64 || payload)
    payload := json_length:u32  json[json_length]  blob          (see encode_record)

The header frame's payload is an encoded ``dict[str, str]`` (config hash etc.); a journal reopened with
a different header raises :class:`~lut.table.schema.TableError`. Frames are read in order up to the first
incomplete or corrupt one; everything from there on is ignored (and truncated away when the journal
is opened for appending) — those points are simply solved again.

Record payload: ``json`` is UTF-8 JSON ``{"format": 1, "fields": [...]}`` with one entry per key, in
the record's key order. A ``str`` value is stored in the JSON itself (``{"key", "type": "str",
"value"}``); every number and array is stored as raw little-endian bytes in ``blob``
(``{"key", "type", "dtype", "shape", "offset", "nbytes"}``, ``dtype`` a numpy type string such as
``"<f8"``, ``offset`` relative to the start of ``blob``), so floats come back bit-identical. ``type``
restores the Python type: ``"float"``/``"int"``/``"bool"`` (Python scalars, stored as ``<f8``/``<i8``/
``|b1``), ``"npscalar"`` (a numpy scalar), ``"array"`` (an ``np.ndarray`` of bool, integer, float or
complex dtype). Nothing else is accepted — no pickles.
"""

from __future__ import annotations

import hashlib
import json
import struct
from typing import Any

import numpy as np

from lut.table.schema import TableError

MAGIC = b"LUTGEN-JOURNAL\x00\x01"
RECORD_FORMAT = 1
_LEN = struct.Struct("<Q")
_JSON_LEN = struct.Struct("<I")
_DIGEST_SIZE = 32
_FRAME_HEAD = _LEN.size + _DIGEST_SIZE
_NUMERIC_KINDS = "biufc"


def encode_record(record: dict[str, Any]) -> bytes:
    """The payload bytes of ``record`` (``str`` keys → ``str``, numbers, numpy scalars or numeric arrays)."""
    fields: list[dict[str, Any]] = []
    blobs: list[bytes] = []
    offset = 0
    for key, value in record.items():
        if not isinstance(key, str):
            raise TableError(f"journal record: key {key!r} is not a string")
        if isinstance(value, str):
            fields.append({"key": key, "type": "str", "value": str(value)})
            continue
        if isinstance(value, bool):
            kind, arr = "bool", np.asarray(value, dtype=np.bool_)
        elif isinstance(value, int):
            if not -(2**63) <= value < 2**63:
                raise TableError(f"journal record: {key}: integer {value} does not fit in 64 bits")
            kind, arr = "int", np.asarray(value, dtype="<i8")
        elif isinstance(value, float):
            kind, arr = "float", np.asarray(value, dtype="<f8")
        elif isinstance(value, np.generic) and value.dtype.kind in _NUMERIC_KINDS:
            kind, arr = "npscalar", np.asarray(value)
        elif isinstance(value, np.ndarray) and value.dtype.kind in _NUMERIC_KINDS:
            kind, arr = "array", value
        else:
            raise TableError(f"journal record: {key}: cannot store a value of type {type(value).__name__}"
                               + (f" (dtype {value.dtype})" if isinstance(value, np.ndarray | np.generic) else ""))
        arr = np.asarray(arr, dtype=arr.dtype.newbyteorder("<"))  # (ascontiguousarray would make 0-d 1-d)
        data = arr.tobytes(order="C")
        fields.append({"key": key, "type": kind, "dtype": arr.dtype.str, "shape": list(arr.shape),
                       "offset": offset, "nbytes": len(data)})
        blobs.append(data)
        offset += len(data)
    head = json.dumps({"format": RECORD_FORMAT, "fields": fields}, separators=(",", ":")).encode("utf-8")
    return _JSON_LEN.pack(len(head)) + head + b"".join(blobs)


def decode_record(payload: bytes) -> dict[str, Any]:
    """The record of an :func:`encode_record` payload (arrays are fresh, writable copies)."""
    try:
        (n,) = _JSON_LEN.unpack_from(payload, 0)
        head = json.loads(payload[_JSON_LEN.size:_JSON_LEN.size + n].decode("utf-8"))
        if head.get("format") != RECORD_FORMAT:
            raise ValueError(f"record format {head.get('format')!r}, this lutgen reads {RECORD_FORMAT}")
        blob = memoryview(payload)[_JSON_LEN.size + n:]
        out: dict[str, Any] = {}
        for f in head["fields"]:
            if f["type"] == "str":
                out[f["key"]] = f["value"]
                continue
            raw = blob[f["offset"]:f["offset"] + f["nbytes"]]
            if len(raw) != f["nbytes"]:
                raise ValueError(f"field {f['key']}: {len(raw)} of {f['nbytes']} bytes")
            arr = np.frombuffer(raw, dtype=np.dtype(f["dtype"])).reshape(f["shape"]).copy()
            kind = f["type"]
            if kind == "array":
                out[f["key"]] = arr
            elif kind == "npscalar":
                out[f["key"]] = arr[()]
            elif kind in ("float", "int", "bool"):
                out[f["key"]] = arr.item()
            else:
                raise ValueError(f"field {f['key']}: unknown type {kind!r}")
        return out
    except (ValueError, KeyError, TypeError, struct.error, UnicodeDecodeError) as exc:
        raise TableError(f"journal record cannot be decoded: {exc}") from None


def encode_frame(payload: bytes) -> bytes:
    """``length || SHA-256(length || payload) || payload``."""
    length = _LEN.pack(len(payload))
    return length + hashlib.sha256(length + payload).digest() + payload


def read_frames(data: bytes, start: int) -> tuple[list[bytes], int]:
    """The payloads of the intact frames of ``data`` from ``start``, and the offset where they end.

    Reading stops at the first frame that is incomplete (torn write) or fails its checksum.
    """
    payloads: list[bytes] = []
    pos = start
    while pos + _FRAME_HEAD <= len(data):
        length_bytes = data[pos:pos + _LEN.size]
        (length,) = _LEN.unpack(length_bytes)
        end = pos + _FRAME_HEAD + length
        if end > len(data):
            break
        payload = data[pos + _FRAME_HEAD:end]
        if hashlib.sha256(length_bytes + payload).digest() != data[pos + _LEN.size:pos + _FRAME_HEAD]:
            break
        payloads.append(payload)
        pos = end
    return payloads, pos
