"""The pipe protocol between the evaluator and a sandboxed policy: frames of named numpy arrays, never pickle.

A sandboxed policy is someone else's code, so what it sends is read as untrusted bytes
(unpickling would run its code in the evaluator). A frame is a ``WFB1`` header (kind, count,
body bytes) and named arrays of a fixed dtype whitelist (:data:`DTYPES`); :class:`Decoder` checks
each field against :class:`WireLimits` as soon as it has its bytes and raises a one-line
:class:`WireError` on anything else. The kinds are STARTED, HELLO, READY, ACTION and ERROR from
the child, RESET, ACT and BYE from the parent; nothing the child sends touches the parent's
clocks. The layout: ``docs/leaderboard.md``, "The sandbox's process and its pipes".
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

MAGIC = b"WFB1"
_HEADER = struct.Struct("<4sBHQ")  # magic, kind, count, body bytes
_U16 = struct.Struct("<H")
_U64 = struct.Struct("<Q")

# code -> dtype, all little-endian; the only types a frame may carry
DTYPES: dict[int, np.dtype] = {
    1: np.dtype("?"), 2: np.dtype("<i1"), 3: np.dtype("<u1"), 4: np.dtype("<i2"),
    5: np.dtype("<i4"), 6: np.dtype("<i8"), 7: np.dtype("<f4"), 8: np.dtype("<f8"),
}
_CODES = {dt: code for code, dt in DTYPES.items()}
ALLOWED = ", ".join(dt.name for dt in DTYPES.values())


class Kind(IntEnum):
    """What a frame is; the module docstring says who sends which."""

    HELLO = 1
    RESET = 2
    READY = 3
    ACT = 4
    ACTION = 5
    ERROR = 6
    BYE = 7
    STARTED = 10


class WireError(ValueError):
    """A frame broke the protocol or its limits; ``str()`` is one line saying what."""


@dataclass(frozen=True)
class WireLimits:
    """What a reader accepts in one message."""

    max_arrays: int = 64
    max_bytes: int = 256 << 20  # the body; an observation of a large batch is tens of MB
    max_ndim: int = 8
    max_name: int = 64


@dataclass
class Message:
    kind: Kind
    arrays: dict[str, np.ndarray] = field(default_factory=dict)


def text_array(text: str) -> np.ndarray:
    """``text`` as the uint8 array of its UTF-8 bytes."""
    return np.frombuffer(text.encode("utf-8", "replace"), dtype=np.uint8)


def array_text(a: np.ndarray | None) -> str:
    """The text of a :func:`text_array` (undecodable bytes replaced); ``""`` for None."""
    if a is None:
        return ""
    return np.ascontiguousarray(a, dtype=np.uint8).tobytes().decode("utf-8", "replace")


def wire_dtype(a: np.ndarray) -> np.dtype:
    """The little-endian whitelisted dtype of ``a``, or WireError naming it and what is allowed."""
    dt = a.dtype.newbyteorder("<")
    if dt not in _CODES:
        raise WireError(f"dtype {a.dtype} cannot be sent; allowed: {ALLOWED}")
    return dt


def encode(kind: Kind, arrays: dict[str, np.ndarray] | None = None, limits: WireLimits = WireLimits()) -> bytes:
    """One frame of ``kind`` carrying ``arrays``; WireError if they break ``limits`` or the whitelist."""
    arrays = arrays or {}
    if len(arrays) > limits.max_arrays:
        raise WireError(f"{len(arrays)} arrays in one message; allowed: at most {limits.max_arrays}")
    parts = []
    for name, value in arrays.items():
        _check_name(name, limits)
        a = np.asarray(value)
        if a.ndim > limits.max_ndim:
            raise WireError(f"array {name!r} has {a.ndim} dimensions; allowed: at most {limits.max_ndim}")
        dt = wire_dtype(a)
        data = np.ascontiguousarray(a, dtype=dt).tobytes()
        raw = name.encode("ascii")
        parts += [_U16.pack(len(raw)), raw, bytes((_CODES[dt], a.ndim)), *(_U64.pack(n) for n in a.shape),
                  _U64.pack(len(data)), data]
    body = b"".join(parts)
    if len(body) > limits.max_bytes:
        raise WireError(f"a message of {len(body)} bytes; allowed: at most {limits.max_bytes}")
    return _HEADER.pack(MAGIC, int(kind), len(arrays), len(body)) + body


class Decoder:
    """Turns a byte stream into :class:`Message` s, checking each against ``limits``.

    :meth:`feed` takes whatever a read returned and gives back the messages it completed;
    a violation raises WireError and leaves the decoder unusable (the stream has no
    way to resynchronize, and a peer that broke the protocol once is not trusted again).
    """

    def __init__(self, limits: WireLimits = WireLimits()):
        self.limits = limits
        self._buf = bytearray()
        self._header: tuple[Kind, int, int] | None = None  # kind, count, body bytes of the frame being read

    @property
    def pending(self) -> int:
        """Bytes received that do not yet make a whole message."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[Message]:
        self._buf += data
        out = []
        while True:
            if self._header is None:
                if len(self._buf) < _HEADER.size:
                    return out
                self._header = self._read_header(bytes(self._buf[:_HEADER.size]))
                del self._buf[:_HEADER.size]
            kind, count, size = self._header
            if len(self._buf) < size:
                return out
            body = bytes(self._buf[:size])
            del self._buf[:size]
            self._header = None
            out.append(Message(kind, self._read_body(body, count)))

    def _read_header(self, raw: bytes) -> tuple[Kind, int, int]:
        magic, kind, count, size = _HEADER.unpack(raw)
        if magic != MAGIC:
            raise WireError(f"a frame starts with {magic!r}; expected {MAGIC!r}")
        if kind not in Kind._value2member_map_:
            raise WireError(f"unknown message kind {kind}; allowed: {', '.join(f'{k.value} ({k.name})' for k in Kind)}")
        if count > self.limits.max_arrays:
            raise WireError(f"a message announces {count} arrays; allowed: at most {self.limits.max_arrays}")
        if size > self.limits.max_bytes:
            raise WireError(f"a message announces {size} bytes; allowed: at most {self.limits.max_bytes}")
        return Kind(kind), count, size

    def _read_body(self, body: bytes, count: int) -> dict[str, np.ndarray]:
        view = memoryview(body)
        pos = 0

        def take(n: int, what: str) -> memoryview:
            nonlocal pos
            if n > len(view) - pos:
                raise WireError(f"a message ends inside {what} (its body is {len(view)} bytes)")
            pos += n
            return view[pos - n:pos]

        arrays: dict[str, np.ndarray] = {}
        for _ in range(count):
            (n,) = _U16.unpack(take(2, "an array name's length"))
            if n > self.limits.max_name:
                raise WireError(f"an array name of {n} bytes; allowed: at most {self.limits.max_name}")
            name = bytes(take(n, "an array name")).decode("ascii", "replace")
            _check_name(name, self.limits)
            if name in arrays:
                raise WireError(f"array {name!r} appears twice in one message")
            code, ndim = take(2, f"the type of array {name!r}")
            if code not in DTYPES:
                raise WireError(f"array {name!r} has dtype code {code}; allowed: "
                                + ", ".join(f"{c} ({dt})" for c, dt in DTYPES.items()))
            if ndim > self.limits.max_ndim:
                raise WireError(f"array {name!r} has {ndim} dimensions; allowed: at most {self.limits.max_ndim}")
            shape = tuple(_U64.unpack(take(8, f"the shape of array {name!r}"))[0] for _ in range(ndim))
            (nbytes,) = _U64.unpack(take(8, f"the size of array {name!r}"))
            dt = DTYPES[code]
            size = 1
            for d in shape:  # Python integers: a product that overflows 64 bits is still compared exactly
                size *= d
            if size * dt.itemsize != nbytes:
                raise WireError(f"array {name!r} of shape {shape} and dtype {dt} needs {size * dt.itemsize} bytes "
                                f"but says {nbytes}")
            data = take(nbytes, f"the data of array {name!r}")
            arrays[name] = np.frombuffer(data, dtype=dt).astype(dt.newbyteorder("="), copy=True).reshape(shape)
        if pos != len(view):
            raise WireError(f"{len(view) - pos} bytes left over after the {count} arrays of a message")
        return arrays


def _check_name(name: str, limits: WireLimits) -> None:
    if not (isinstance(name, str) and name.isascii() and name.isidentifier() and len(name) <= limits.max_name):
        raise WireError(f"array name {name!r} is not allowed; allowed: an ASCII identifier of at most "
                        f"{limits.max_name} characters")
