"""The sandbox's pipe protocol (wfbench.harness.isolation.wire): arrays round-trip exactly, and every malformed or
oversized frame is refused with one line saying what is wrong (issue #34)."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from wfbench.harness.isolation.wire import (
    DTYPES,
    Decoder,
    Kind,
    WireError,
    WireLimits,
    array_text,
    encode,
    text_array,
)


def _array(name: bytes, code: int, shape: tuple[int, ...], nbytes: int, data: bytes = b"") -> bytes:
    dims = b"".join(struct.pack("<Q", d) for d in shape)
    return struct.pack("<H", len(name)) + name + bytes((code, len(shape))) + dims + struct.pack("<Q", nbytes) + data


def _frame(body: bytes, count: int = 1, kind: int = Kind.ACT, magic: bytes = b"WFB1") -> bytes:
    return struct.pack("<4sBHQ", magic, kind, count, len(body)) + body


def _refused(frame: bytes, limits: WireLimits | None = None) -> str:
    with pytest.raises(WireError) as info:
        Decoder(limits or WireLimits()).feed(frame)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_every_allowed_dtype_round_trips_bit_for_bit__fed_one_byte_at_a_time():
    rng = np.random.default_rng(0)
    arrays = {f"a{code}": (rng.normal(size=(2, 3)) * 100).astype(dt) for code, dt in DTYPES.items()}
    arrays["scalar"] = np.float64(np.nan)
    arrays["empty"] = np.zeros((0, 5), dtype=np.int8)
    arrays["big_endian"] = np.arange(4, dtype=">i8")
    frame = encode(Kind.ACTION, arrays)
    decoder = Decoder()
    got = []
    for i in range(len(frame)):
        got += decoder.feed(frame[i:i + 1])
    assert len(got) == 1 and got[0].kind == Kind.ACTION and decoder.pending == 0
    for name, a in arrays.items():
        b = got[0].arrays[name]
        assert b.shape == np.shape(a) and b.dtype == np.asarray(a).dtype.newbyteorder("=")
        assert np.asarray(a).tobytes() == b.astype(np.asarray(a).dtype).tobytes()
        assert b.flags.writeable  # the policy may work in place on its observation, as outside the sandbox


def test_two_frames_in_one_read_and_text():
    frame = encode(Kind.ERROR, {"reason": text_array("naïve: ☃")}) + encode(Kind.BYE)
    first, second = Decoder().feed(frame)
    assert array_text(first.arrays["reason"]) == "naïve: ☃" and second.kind == Kind.BYE and second.arrays == {}


@pytest.mark.parametrize("value", [np.array(["text"]), np.array([object()]), np.array([1], dtype=np.uint64),
                                   np.array([1j]), np.zeros(1, dtype=[("a", "i4")])])
def test_only_whitelisted_dtypes_are_sent(value):
    with pytest.raises(WireError, match="cannot be sent; allowed: bool, int8, uint8, int16, int32, int64, float32, "
                                        "float64"):
        encode(Kind.ACTION, {"x": value})


def test_sender_refuses_bad_names_and_too_many_arrays():
    with pytest.raises(WireError, match="array name 'not ok' is not allowed; allowed: an ASCII identifier"):
        encode(Kind.ACTION, {"not ok": np.zeros(1)})
    with pytest.raises(WireError, match="65 arrays in one message; allowed: at most 64"):
        encode(Kind.ACTION, {f"a{i}": np.zeros(1) for i in range(65)})


def test_header_checks_come_before_the_body_is_read():
    assert _refused(_frame(b"", magic=b"PKL\x80")) == "a frame starts with b'PKL\\x80'; expected b'WFB1'"
    assert _refused(_frame(b"", kind=99)).startswith("unknown message kind 99; allowed: 1 (HELLO), 2 (RESET)")
    assert _refused(_frame(b"", count=65)) == "a message announces 65 arrays; allowed: at most 64"
    # a header that announces a huge body is refused from its 15 bytes: nothing is buffered waiting for it
    header = struct.pack("<4sBHQ", b"WFB1", Kind.ACT, 1, 10**12)
    assert _refused(header) == f"a message announces {10**12} bytes; allowed: at most {256 << 20}"


@pytest.mark.parametrize(("body", "count", "expected"), [
    (_array(b"x", 6, (2,), 8, b"\0" * 8), 1, "array 'x' of shape (2,) and dtype int64 needs 16 bytes but says 8"),
    (_array(b"x", 6, (2**40, 2**40), 0), 1, "array 'x' of shape (1099511627776, 1099511627776) and dtype int64 "
                                            "needs 9671406556917033397649408 bytes but says 0"),
    (_array(b"x", 17, (1,), 8, b"\0" * 8), 1, "array 'x' has dtype code 17; allowed: 1 (bool), 2 (int8)"),
    (_array(b"x", 6, (1,) * 9, 8, b"\0" * 8), 1, "array 'x' has 9 dimensions; allowed: at most 8"),
    (_array(b"1x", 6, (), 8, b"\0" * 8), 1, "array name '1x' is not allowed"),
    (_array("ä".encode(), 6, (), 8, b"\0" * 8), 1, "is not allowed; allowed: an ASCII identifier"),
    (_array(b"x", 3, (1,), 1, b"\1") * 2, 2, "array 'x' appears twice in one message"),
    (_array(b"x", 3, (1,), 1, b"\1") + b"junk", 1, "4 bytes left over after the 1 arrays of a message"),
    (_array(b"x", 3, (4,), 4, b"\1"), 1, "a message ends inside the data of array 'x' (its body is"),
    (_array(b"x", 3, (1,), 1, b"\1"), 2, "a message ends inside an array name's length"),
])
def test_malformed_bodies_are_refused_in_one_line(body, count, expected):
    assert expected in _refused(_frame(body, count=count))


def test_a_smaller_limit_is_enforced():
    frame = encode(Kind.ACT, {"x": np.zeros(100)})
    assert _refused(frame, WireLimits(max_bytes=100)).endswith("bytes; allowed: at most 100")
