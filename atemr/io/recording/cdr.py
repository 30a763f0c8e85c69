"""CDR encoders generated once per message type: the bytes `mcap-ros2-support` writes, many times sooner.

`mcap_ros2`'s encoder interprets a message's definition for every message and writes one value at a time (a
``float64[36]`` covariance is 36 calls through its coercion, alignment and ``struct`` packing). At the robot's
rates (IMU and wheel odometry at 50 Hz, scans, poses and transforms at 10-20 Hz) that was a tenth of the whole
robot's CPU while it recorded, and a field-by-field interpreter of our own still cost several per cent. So each
type of `atemr.io.recording.ros2_types` becomes the source of one Python function, compiled once, as ROS 1's
``genpy`` does: nested messages are inlined, every run of fixed-size values between two variable-length ones
(strings, sequences) is packed by one precompiled ``struct.Struct`` with the alignment padding computed while
generating, and a primitive array is one ``numpy`` or ``struct`` call. Padding is computed at run time only after
a variable-length field, where the offset is not known in advance. The output is the same as `mcap_ros2`'s, byte
for byte (``tests/io/test_recording_cdr.py`` compares them on every type the recording uses and on random
definitions), so every reader that decodes `mcap_ros2`'s files decodes these.

The rules followed are those of XCDR1 little-endian as ROS 2 uses it: a 4-byte encapsulation header
(``00 01 00 00``); every primitive aligned to its size counted from the end of the header; a string as a
``uint32`` length including its terminating NUL, then its UTF-8 bytes and the NUL; a sequence as a ``uint32``
count, then its elements; a fixed array as its elements alone. Missing fields (absent from the dict, or
None) take the definition's default or zero, as with `mcap_ros2`. A message is nested dicts or objects with the
fields as attributes.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numpy as np

from atemr.io.recording.ros2_types import field_lines

Encoder = Callable[[Any], bytes]
HEADER = b"\x00\x01\x00\x00"

#: Primitive types: (struct code, size, numpy dtype, Python type for coercion).
_PRIMITIVES: dict[str, tuple[str, int, str, type]] = {
    "bool": ("?", 1, "?", bool), "byte": ("B", 1, "u1", int), "char": ("b", 1, "i1", int),
    "int8": ("b", 1, "i1", int), "uint8": ("B", 1, "u1", int), "int16": ("h", 2, "<i2", int),
    "uint16": ("H", 2, "<u2", int), "int32": ("i", 4, "<i4", int), "uint32": ("I", 4, "<u4", int),
    "int64": ("q", 8, "<i8", int), "uint64": ("Q", 8, "<u8", int), "float32": ("f", 4, "<f4", float),
    "float64": ("d", 8, "<f8", float),
}
#: Types every definition may use without spelling them out.
_BUILTIN: dict[str, list[str]] = {"builtin_interfaces/Time": ["int32 sec", "uint32 nanosec"],
                                  "builtin_interfaces/Duration": ["int32 sec", "uint32 nanosec"]}
#: A fixed primitive array this long or shorter joins its neighbours' ``struct`` call; a longer one is one
#: ``numpy`` conversion of its own.
_PACK_MAX = 64
_UINT32 = struct.Struct("<I")
_ZEROS = tuple(bytes(n) for n in range(8))


def _no_field(name: str) -> None:
    return None


def _getter(msg: Any) -> Callable[[str], Any]:
    """How to read ``msg``'s fields by name: a dict's ``get``, an object's attributes, nothing for None."""
    if msg.__class__ is dict:
        return msg.get
    if msg is None:
        return _no_field
    return lambda name: getattr(msg, name, None)


def _array_data(kind: str, length: int | None) -> Callable[[Any], tuple[int, bytes]]:
    """``kind[length]`` (fixed) or ``kind[]`` (``length`` None) as (count, little-endian bytes); missing: empty,
    or zeros for a fixed array. A fixed array of another length is a `ValueError` naming the type."""
    code, _, dtype, cast = _PRIMITIVES[kind]
    raw = dtype == "u1"

    def data(value: Any) -> tuple[int, bytes]:
        if value is None:
            value = () if length is None else np.zeros(length, dtype=dtype)
        if raw and isinstance(value, (bytes, bytearray, memoryview)):
            out, count = bytes(value), len(value)
        elif isinstance(value, (list, tuple)) and len(value) < _PACK_MAX:  # one struct call beats numpy
            count = len(value)
            out = struct.pack(f"<{count}{code}", *map(cast, value))
        else:
            array = np.asarray(value, dtype=dtype).reshape(-1)
            out, count = array.tobytes(), int(array.size)
        if length is not None and count != length:
            raise ValueError(f"{kind}[{length}] needs {length} values, got {count}")
        return count, out
    return data


def _fixed_values(kind: str, length: int) -> Callable[[Any], Any]:
    """``kind[length]``'s values cast for a ``struct`` call (missing: zeros)."""
    cast = _PRIMITIVES[kind][3]
    zeros = (cast(0),) * length

    def values(value: Any) -> Any:
        if value is None:
            return zeros
        out = tuple(map(cast, value))
        if len(out) != length:
            raise ValueError(f"{kind}[{length}] needs {length} values, got {len(out)}")
        return out
    return values


def _items(length: int | None, what: str) -> Callable[[Any], list[Any]]:
    """An array of ``what`` (strings or messages) as a list (missing: empty, or ``length`` defaults); a fixed one
    of another length is a `ValueError`."""
    def items(value: Any) -> list[Any]:
        if value is None:
            return [None] * (length or 0)
        out = list(value)
        if length is not None and len(out) != length:
            raise ValueError(f"{what}[{length}] needs {length} values, got {len(out)}")
        return out
    return items


def _write_string(buf: bytearray, value: Any) -> None:
    """One element of a string array: aligned length, UTF-8 bytes, NUL."""
    data = ("" if value is None else str(value)).encode("utf-8")
    buf += _ZEROS[(4 - len(buf)) % 4]
    buf += _UINT32.pack(len(data) + 1)
    buf += data
    buf += b"\x00"


def _parse_field(line: str, owner: str) -> tuple[str, str, bool, int | None, str | None]:
    """A definition's line as (name, type, whether an array, its fixed length or None, default text or None)."""
    parts = line.split()
    if len(parts) < 2:
        raise ValueError(f"{owner}: cannot read the field {line!r}")
    spec, name = parts[0], parts[1]
    default = " ".join(parts[2:]) or None
    if "[" not in spec:
        return name, spec, False, None, default
    kind, bound = spec[:-1].split("[", 1)
    if bound.startswith("<="):
        raise ValueError(f"{owner}.{name}: bounded sequences are not supported")
    return name, kind, True, int(bound) if bound else None, default


def _parse_default(kind: str, default: str | None) -> Any:
    cast = _PRIMITIVES[kind][3]
    if default is None:
        return cast(0)
    if kind == "bool":
        return default.strip().lower() == "true"
    return cast(float(default)) if cast is float else cast(default)


class _Function:
    """The source of one generated function ``name(buf, m)`` that appends a message's CDR bytes to ``buf``.

    The offset from the end of the header is tracked as ``offset % modulus == rest`` (``modulus`` 8 when it is
    known exactly, 1 right after a variable-length field): padding is static while the modulus covers the
    alignment, and computed from ``len(buf)`` otherwise. Fixed-size values wait in a group (a ``struct`` format
    and its arguments) that is packed at once when something variable-length comes.
    """

    def __init__(self, generator: _Generator, name: str, short: str, *, known: bool) -> None:
        self.generator = generator
        self.name = name
        self.lines: list[str] = []
        self.modulus, self.rest = (8, 0) if known else (1, 0)
        self.fmt: list[str] = []
        self.args: list[str] = []
        self._vars = 0
        self.message(short, "m")

    def var(self, prefix: str) -> str:
        self._vars += 1
        return f"{prefix}{self._vars}"

    def emit(self, line: str) -> None:
        self.lines.append(line)

    def flush(self) -> None:
        if self.fmt:
            packer = self.generator.constant("_S", struct.Struct("<" + "".join(self.fmt)))
            self.emit(f"buf += {packer}.pack({', '.join(self.args)})")
            self.fmt, self.args = [], []

    def align(self, size: int) -> None:
        if size == 1:
            return
        if self.modulus >= size:
            pad = -self.rest % size
            if pad:
                self.fmt.append(f"{pad}x")
                self.rest = (self.rest + pad) % self.modulus
            return
        self.flush()
        self.emit(f"buf += _ZEROS[(4 - len(buf)) % {size}]")
        self.modulus, self.rest = size, 0

    def advance(self, size: int) -> None:
        self.rest = (self.rest + size) % self.modulus

    def unknown(self, modulus: int = 1) -> None:
        """After a variable-length field: only alignment to ``modulus`` is known."""
        self.modulus, self.rest = modulus, 0

    # -- fields ---------------------------------------------------------------------------------------------
    def message(self, short: str, value: str) -> None:
        lines = _BUILTIN.get(short) or field_lines(short)
        get = self.var("g")
        self.emit(f"{get} = _getter({value})")
        if not lines:  # an empty definition is one uint8 in ROS 2's IDL (``structure_needs_at_least_one_member``)
            self.fmt.append("B")
            self.args.append("0")
            self.advance(1)
        for line in lines:
            self.field(line, short, get)

    def field(self, line: str, owner: str, get: str) -> None:
        name, kind, is_array, length, default = _parse_field(line, owner)
        value = self.var("v")
        self.emit(f"{value} = {get}({name!r})")
        if kind in _PRIMITIVES:
            if is_array:
                self.primitive_array(kind, length, value)
            else:
                self.primitive(kind, default, value)
        elif kind == "string":
            if is_array:
                self.each("_write_string", length, "string", value)
            else:
                self.string(default, value)
        else:
            if "/" not in kind:
                kind = f"{owner.split('/', maxsplit=1)[0]}/{kind}"
            if is_array:
                self.each(self.generator.element_writer(kind), length, kind, value)
            else:
                self.message(kind, value)

    def primitive(self, kind: str, default: str | None, value: str) -> None:
        code, size, _, cast = _PRIMITIVES[kind]
        fallback = self.generator.constant("_D", _parse_default(kind, default))
        self.align(size)
        self.fmt.append(code)
        self.args.append(f"{fallback} if {value} is None else {cast.__name__}({value})")
        self.advance(size)

    def string(self, default: str | None, value: str) -> None:
        fallback = self.generator.constant("_D", "" if default is None else str(default))
        data = self.var("s")
        self.emit(f"{data} = ({fallback} if {value} is None else str({value})).encode('utf-8')")
        self.align(4)
        self.fmt.append("I")
        self.args.append(f"len({data}) + 1")
        self.flush()
        self.emit(f"buf += {data}")
        self.emit("buf += b'\\x00'")
        self.unknown()

    def primitive_array(self, kind: str, length: int | None, value: str) -> None:
        code, size, dtype, _ = _PRIMITIVES[kind]
        if length is not None and length <= _PACK_MAX and dtype != "u1":
            values = self.generator.constant("_F", _fixed_values(kind, length))
            self.align(size)
            self.fmt.append(f"{length}{code}")
            self.args.append(f"*{values}({value})")
            self.advance(size * length)
            return
        data = self.generator.constant("_A", _array_data(kind, length))
        count, out = self.var("n"), self.var("b")
        self.emit(f"{count}, {out} = {data}({value})")
        if length is not None:  # fixed: its size is known, so is the offset after it
            self.align(size)
            self.flush()
            self.emit(f"buf += {out}")
            self.advance(size * length)
            return
        self.align(4)
        self.fmt.append("I")
        self.args.append(count)
        self.advance(4)
        self.flush()
        if size > self.modulus:  # the elements' alignment after the count, when there are any
            self.emit(f"if {count}: buf += _ZEROS[(4 - len(buf)) % {size}]")
        elif -self.rest % size:
            self.emit(f"if {count}: buf += _ZEROS[{-self.rest % size}]")
        self.emit(f"buf += {out}")
        self.unknown(min(size, 4))  # 4 after an empty sequence's count, the element size after its elements

    def each(self, writer: str, length: int | None, what: str, value: str) -> None:
        items = self.var("i")
        self.emit(f"{items} = {self.generator.constant('_I', _items(length, what))}({value})")
        if length is None:
            self.align(4)
            self.fmt.append("I")
            self.args.append(f"len({items})")
        self.flush()
        self.emit(f"for item in {items}: {writer}(buf, item)")
        self.unknown()

    def source(self) -> str:
        self.flush()
        body = "\n    ".join(self.lines) or "pass"
        return f"def {self.name}(buf, m):\n    {body}\n"


class _Generator:
    """The generated functions of one type and of the element types its arrays reach, in one namespace."""

    def __init__(self) -> None:
        self.namespace: dict[str, Any] = {"_getter": _getter, "_ZEROS": _ZEROS, "_write_string": _write_string}
        self.elements: dict[str, str] = {}
        self._constants = 0

    def constant(self, prefix: str, value: Any) -> str:
        self._constants += 1
        name = f"{prefix}{self._constants}"
        self.namespace[name] = value
        return name

    def element_writer(self, short: str) -> str:
        """The name of the function writing one ``short`` at an unknown offset (an array's element)."""
        found = self.elements.get(short)
        if found is None:
            found = self.elements[short] = f"_write_{len(self.elements)}"
            self.define(_Function(self, found, short, known=False))
        return found

    def define(self, function: _Function) -> Callable[[bytearray, Any], None]:
        exec(compile(function.source(), f"<cdr {function.name}>", "exec"), self.namespace)
        return self.namespace[function.name]


def compile_encoder(short: str) -> Encoder:
    """The encoder of ``short`` (``package/Type`` of `atemr.io.recording.ros2_types`): a message (nested dicts,
    or objects with the fields as attributes) to its CDR bytes, header included."""
    generator = _Generator()
    write = generator.define(_Function(generator, "_write", short, known=True))

    def encode(message: Any) -> bytes:
        buf = bytearray(HEADER)
        write(buf, message)
        return bytes(buf)
    return encode


__all__ = ["compile_encoder"]
