"""CDR encoders compiled once per message type: the bytes `mcap-ros2-support` writes, ten times sooner.

`mcap_ros2`'s encoder interprets a message's definition for every message and writes arrays one element at a
time (a ``float64[36]`` covariance is 36 calls through its coercion, alignment and ``struct`` packing). At the
robot's rates (IMU and wheel odometry at 50 Hz, scans, poses and transforms at 10-20 Hz) that was a tenth of the
whole robot's CPU while it recorded. Here each type of `atemr.io.recording.ros2_types` is compiled once into
a list of field writers: a primitive array is one ``numpy`` conversion, a string or a number one ``struct``
call. The output is the same as `mcap_ros2`'s, byte for byte (``tests/io/recording/test_cdr.py`` compares
them on every type the recording uses), so every reader that decodes `mcap_ros2`'s files decodes these.

The rules followed are those of XCDR1 little-endian as ROS 2 uses it: a 4-byte encapsulation header
(``00 01 00 00``); every primitive aligned to its size counted from the end of the header; a string as a
``uint32`` length including its terminating NUL, then its UTF-8 bytes and the NUL; a sequence as a ``uint32``
count, then its elements; a fixed array as its elements alone. Missing fields (absent from the dict, or
None) take the definition's default or zero, as with `mcap_ros2`.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numpy as np

from atemr.io.recording.ros2_types import field_lines

Writer = Callable[[bytearray, Any], None]
HEADER = b"\x00\x01\x00\x00"

#: Primitive types: (struct code, size, numpy dtype, Python type for coercion).
_PRIMITIVES: dict[str, tuple[str, int, str, type]] = {
    "bool": ("?", 1, "?", bool), "byte": ("B", 1, "u1", int), "char": ("B", 1, "u1", int),
    "int8": ("b", 1, "i1", int), "uint8": ("B", 1, "u1", int), "int16": ("h", 2, "<i2", int),
    "uint16": ("H", 2, "<u2", int), "int32": ("i", 4, "<i4", int), "uint32": ("I", 4, "<u4", int),
    "int64": ("q", 8, "<i8", int), "uint64": ("Q", 8, "<u8", int), "float32": ("f", 4, "<f4", float),
    "float64": ("d", 8, "<f8", float),
}
#: Types every definition may use without spelling them out.
_BUILTIN: dict[str, list[str]] = {"builtin_interfaces/Time": ["int32 sec", "uint32 nanosec"],
                                  "builtin_interfaces/Duration": ["int32 sec", "uint32 nanosec"]}
_UINT32 = struct.Struct("<I")


def _align(buf: bytearray, size: int) -> None:
    """Pad ``buf`` so the next ``size``-byte value starts at a multiple of ``size`` after the header."""
    rest = (len(buf) - 4) % size
    if rest:
        buf += bytes(size - rest)


def _get(msg: Any, name: str) -> Any:
    if isinstance(msg, dict):
        return msg.get(name)
    return getattr(msg, name, None)


def _primitive(kind: str, default: str | None) -> Writer:
    code, size, _, cast = _PRIMITIVES[kind]
    packer = struct.Struct("<" + code)
    if default is None:
        fallback = cast(0)
    elif kind == "bool":
        fallback = default.strip().lower() == "true"
    else:
        fallback = cast(float(default)) if cast is float else cast(default)

    def write(buf: bytearray, value: Any) -> None:
        if size > 1:
            _align(buf, size)
        buf += packer.pack(fallback if value is None else cast(value))
    return write


def _string(default: str | None) -> Writer:
    fallback = "" if default is None else str(default)

    def write(buf: bytearray, value: Any) -> None:
        data = (fallback if value is None else str(value)).encode("utf-8")
        _align(buf, 4)
        buf += _UINT32.pack(len(data) + 1)
        buf += data
        buf += b"\x00"
    return write


def _primitive_array(kind: str, length: int | None) -> Writer:
    """``kind[length]`` (fixed) or ``kind[]`` (``length`` None: a sequence, its count first)."""
    code, size, dtype, cast = _PRIMITIVES[kind]
    raw = size == 1 and kind != "bool"
    fixed = struct.Struct(f"<{length}{code}") if length is not None else None

    def write(buf: bytearray, value: Any) -> None:
        if value is None:  # missing: empty, or zeros for a fixed array
            value = () if length is None else np.zeros(length, dtype=dtype)
        if raw and isinstance(value, (bytes, bytearray, memoryview)):
            data = bytes(value)
            count = len(data)
        elif isinstance(value, (list, tuple)) and len(value) < 64:  # a short list: one struct call beats numpy
            count = len(value)
            packer = fixed if fixed is not None and count == length else struct.Struct(f"<{count}{code}")
            data = packer.pack(*map(cast, value))
        else:
            array = np.asarray(value, dtype=dtype).reshape(-1)
            data, count = array.tobytes(), int(array.size)
        if length is None:
            _align(buf, 4)
            buf += _UINT32.pack(count)
        elif count != length:
            raise ValueError(f"{kind}[{length}] needs {length} values, got {count}")
        if count:
            if size > 1:
                _align(buf, size)
            buf += data
    return write


def _each(item: Writer, length: int | None, what: str) -> Writer:
    """An array of ``what`` written one ``item`` at a time: ``what[length]``, or a sequence (its count first)."""
    def write(buf: bytearray, value: Any) -> None:
        items = list(value or ())
        if length is None:
            _align(buf, 4)
            buf += _UINT32.pack(len(items))
        elif len(items) != length:
            raise ValueError(f"{what}[{length}] needs {length} values, got {len(items)}")
        for one in items:
            item(buf, one)
    return write


class _Compiler:
    """Writers for every type a definition reaches, each built once."""

    def __init__(self) -> None:
        self.types: dict[str, Writer] = {}

    def message(self, short: str) -> Writer:
        found = self.types.get(short)
        if found is not None:
            return found
        lines = _BUILTIN.get(short) or field_lines(short)
        # an empty definition is one uint8 in ROS 2's IDL (``structure_needs_at_least_one_member``)
        fields = [self._field(line, short) for line in lines] or [("structure_needs_at_least_one_member",
                                                                   _primitive("uint8", None))]
        names = [name for name, _ in fields]
        writers = [writer for _, writer in fields]

        def write(buf: bytearray, msg: Any) -> None:
            for name, writer in zip(names, writers, strict=True):
                writer(buf, None if msg is None else _get(msg, name))
        self.types[short] = write
        return write

    def _field(self, line: str, owner: str) -> tuple[str, Writer]:
        parts = line.split()
        if len(parts) < 2:
            raise ValueError(f"{owner}: cannot read the field {line!r}")
        spec, name = parts[0], parts[1]
        default = " ".join(parts[2:]) or None
        kind, length, is_array = spec, None, False
        if "[" in spec:
            kind, bound = spec[:-1].split("[", 1)
            is_array = True
            if bound.startswith("<="):
                raise ValueError(f"{owner}.{name}: bounded sequences are not supported")
            length = int(bound) if bound else None
        if kind in _PRIMITIVES:
            if is_array:
                return name, _primitive_array(kind, length)
            return name, _primitive(kind, default)
        if kind == "string":
            return name, (_each(_string(None), length, "string") if is_array else _string(default))
        if "/" not in kind:
            kind = f"{owner.split('/', maxsplit=1)[0]}/{kind}"
        nested = self.message(kind)
        return name, (_each(nested, length, kind) if is_array else nested)


def compile_encoder(short: str) -> Callable[[Any], bytes]:
    """The encoder of ``short`` (``package/Type`` of `atemr.io.recording.ros2_types`): a message (nested dicts,
    or objects with the fields as attributes) to its CDR bytes, header included."""
    write = _Compiler().message(short)

    def encode(message: Any) -> bytes:
        buf = bytearray(HEADER)
        write(buf, message)
        return bytes(buf)
    return encode


__all__ = ["compile_encoder"]
