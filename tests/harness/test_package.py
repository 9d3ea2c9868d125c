"""Policy packages (wfbench.harness.isolation.package): deterministic packing, and every archive a stranger could upload
to break out of its folder or fill a disk is refused in one line, before or while unpacking (issue #34)."""

from __future__ import annotations

import io
import json
import os
import stat
import zipfile
from pathlib import Path

import pytest

from wfbench.harness.isolation.package import (
    MANIFEST,
    Manifest,
    PackageError,
    content_hash,
    inspect,
    pack,
    pack_folder,
    unpack,
)

MANIFEST_OK = json.dumps({"entry": "mypol:Policy", "format": 1})


def _project(root: Path) -> Path:
    (root / "mypol" / "nets").mkdir(parents=True)
    (root / "mypol" / "__init__.py").write_text("class Policy: ...\n")
    (root / "mypol" / "nets" / "weights.bin").write_bytes(bytes(range(256)) * 4)
    (root / "mypol" / "__pycache__").mkdir()
    (root / "mypol" / "__pycache__" / "x.cpython-311.pyc").write_bytes(b"stale")
    (root / "unrelated.txt").write_text("not part of the package")
    return root


def _zip(members: dict[str, bytes | str], modes: dict[str, int] | None = None) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            info = zipfile.ZipInfo(name)
            info.compress_type = zipfile.ZIP_DEFLATED
            if modes and name in modes:
                info.create_system = 3
                info.external_attr = modes[name] << 16
            zf.writestr(info, data)
    return buf.getvalue()


def _refused(data: bytes, **limits) -> str:
    with pytest.raises(PackageError) as info:
        inspect(data, **limits)
    assert "\n" not in str(info.value)
    return str(info.value)


def test_pack_is_deterministic_and_holds_only_the_entry_package(tmp_path):
    root = _project(tmp_path)
    first = pack("mypol:Policy", root)
    os.utime(root / "mypol" / "__init__.py", (1e9, 1e9))  # a touched file: same code, same bytes
    assert pack("mypol:Policy", root) == first
    assert content_hash(first).startswith("sha256:") and len(content_hash(first)) == 7 + 64
    names = zipfile.ZipFile(io.BytesIO(first)).namelist()
    assert names == sorted(names) == ["mypol/__init__.py", "mypol/nets/weights.bin", MANIFEST]
    assert inspect(first) == Manifest("mypol:Policy", 1, 3, len(MANIFEST_OK) + len("class Policy: ...\n") + 1024)
    (root / "mypol" / "__init__.py").write_text("class Policy: pass\n")
    assert content_hash(pack("mypol:Policy", root)) != content_hash(first)


def test_unpack_writes_what_was_packed_readable_by_the_sandbox_user(tmp_path):
    data = pack("mypol.sub:make", _project(tmp_path / "src"))
    dest = tmp_path / "dest"
    assert unpack(data, dest).entry == "mypol.sub:make"
    assert (dest / "mypol" / "nets" / "weights.bin").read_bytes() == bytes(range(256)) * 4
    assert stat.S_IMODE(dest.stat().st_mode) == 0o755
    assert stat.S_IMODE((dest / "mypol" / "nets").stat().st_mode) == 0o755
    assert stat.S_IMODE((dest / "mypol" / "__init__.py").stat().st_mode) == 0o644
    assert pack_folder(dest) == data  # the unpacked folder packs to the same bytes
    with pytest.raises(PackageError, match="is not empty"):
        unpack(data, dest)


def test_a_single_module_file_is_a_package(tmp_path):
    (tmp_path / "rule.py").write_text("def make(): ...\n")
    names = zipfile.ZipFile(io.BytesIO(pack("rule:make", tmp_path))).namelist()
    assert names == ["rule.py", MANIFEST]


@pytest.mark.parametrize(("entry", "expected"), [
    ("nocolon", "entry point 'nocolon' is not allowed; allowed: module:attr"),
    ("a b:c", "entry point 'a b:c' is not allowed"),
    ("json:Policy", "a package named 'json' would hide the Python module of that name; rename it"),
    ("wfbench:Policy", "a package named 'wfbench' would hide wfbench; rename it"),
    ("missing:Policy", "neither"),
])
def test_pack_refuses_what_cannot_be_a_package(tmp_path, entry, expected):
    with pytest.raises(PackageError, match=expected):
        pack(entry, tmp_path)


def test_pack_refuses_a_symlink(tmp_path):
    root = _project(tmp_path)
    (root / "mypol" / "secret").symlink_to("/etc/hostname")
    with pytest.raises(PackageError, match="secret is a symlink; a package holds plain files only"):
        pack("mypol:Policy", root)


@pytest.mark.parametrize(("members", "modes", "expected"), [
    ({MANIFEST: MANIFEST_OK, "mypol.py": "", "../evil.py": "x"}, None,
     "zip-slip: member '../evil.py' would land outside the package; allowed: paths without '..'"),
    ({MANIFEST: MANIFEST_OK, "mypol.py": "", "mypol/../../x": "x"}, None, "zip-slip: member 'mypol/../../x'"),
    ({MANIFEST: MANIFEST_OK, "mypol.py": "", "/etc/cron.d/x": "x"}, None,
     "absolute path: member '/etc/cron.d/x' would land outside the package"),
    ({MANIFEST: MANIFEST_OK, "mypol.py": "", "C:/x": "x"}, None, "absolute path: member 'C:/x'"),
    ({MANIFEST: MANIFEST_OK, "mypol.py": "", "link": "/etc/passwd"}, {"link": stat.S_IFLNK | 0o777},
     "member 'link' is a symlink; allowed: plain files and folders"),
    ({MANIFEST: MANIFEST_OK, "mypol.py": "", "dev": ""}, {"dev": stat.S_IFCHR | 0o666},
     "member 'dev' is a device, pipe or socket"),
    ({"mypol.py": ""}, None, f"the package has no {MANIFEST} at its top"),
    ({MANIFEST: "{not json", "mypol.py": ""}, None, f"{MANIFEST} is not valid JSON"),
    ({MANIFEST: '{"entry": "mypol:P", "format": 1, "run": "rm -rf /"}', "mypol.py": ""}, None,
     "allowed: exactly the keys entry and format"),
    ({MANIFEST: '{"entry": "mypol:P", "format": 2}', "mypol.py": ""}, None, "has format 2; allowed: 1"),
    ({MANIFEST: '{"entry": "os:system", "format": 1}', "os.py": ""}, None, "a package named 'os' would hide"),
    ({MANIFEST: MANIFEST_OK, "other.py": ""}, None,
     "the entry point's module 'mypol' is not in the package (neither mypol/ nor mypol.py; it holds other.py, "
     "wfbench-policy.json)"),
])
def test_inspect_refuses_hostile_or_broken_archives(members, modes, expected):
    assert expected in _refused(_zip(members, modes))


def test_inspect_refuses_a_non_zip_and_the_size_limits():
    assert _refused(b"\x80\x04pickle").startswith("the package is not a zip archive")
    data = _zip({MANIFEST: MANIFEST_OK, "mypol.py": "x" * 1000})
    assert _refused(data, max_bytes=100) == f"the package is {len(data)} bytes; allowed: at most 100 bytes"
    assert _refused(data, max_members=1) == "the package has 2 members; allowed: at most 1"
    assert _refused(data, max_unpacked=500) == ("zip bomb: the members declare "
                                                f"{1000 + len(MANIFEST_OK)} bytes unpacked; allowed: at most 500")


def test_inspect_refuses_a_compression_ratio_of_a_bomb():
    data = _zip({MANIFEST: MANIFEST_OK, "mypol.py": b"\0" * (8 << 20)})  # 8 MiB of zeros pack into a few KiB
    assert "zip bomb: " in _refused(data) and "allowed: a ratio of at most 200" in _refused(data)


def _lie_about_sizes(data: bytes, name: bytes, size: int) -> bytes:
    """``data`` with the member ``name``'s uncompressed size set to ``size`` in its local and central headers."""
    out = bytearray(data)
    local = out.find(b"PK\x03\x04")
    while local >= 0:
        name_len = int.from_bytes(out[local + 26:local + 28], "little")
        if out[local + 30:local + 30 + name_len] == name:
            out[local + 22:local + 26] = size.to_bytes(4, "little")
        local = out.find(b"PK\x03\x04", local + 4)
    central = out.find(b"PK\x01\x02")
    while central >= 0:
        name_len = int.from_bytes(out[central + 28:central + 30], "little")
        if out[central + 46:central + 46 + name_len] == name:
            out[central + 24:central + 28] = size.to_bytes(4, "little")
        central = out.find(b"PK\x01\x02", central + 4)
    return bytes(out)


def test_headers_that_lie_about_sizes_get_no_further_than_their_claim(tmp_path):
    payload = os.urandom(1 << 20)  # incompressible: the ratio check does not see it
    data = _lie_about_sizes(_zip({MANIFEST: MANIFEST_OK, "mypol.py": payload}), b"mypol.py", 1000)
    assert inspect(data).unpacked_bytes == 1000 + len(MANIFEST_OK)  # the headers' claim passes the checks
    dest = tmp_path / "dest"
    with pytest.raises(PackageError, match="member 'mypol.py' is damaged .*the package must unpack to what its "
                                           "headers declare"):
        unpack(data, dest)
    assert list(dest.iterdir()) == []  # what was written is removed again


def test_unpack_counts_the_bytes_it_writes(tmp_path, monkeypatch):
    """The second line of defence: were the header checks fooled, the bytes written still stop at the limit."""
    import wfbench.harness.isolation.package as package

    data = _zip({MANIFEST: MANIFEST_OK, "mypol.py": os.urandom(4000), "more.bin": os.urandom(4000)})
    monkeypatch.setattr(package, "inspect", lambda *args: Manifest("mypol:Policy"))
    with pytest.raises(PackageError, match="zip bomb: the members unpack to more than 5000 bytes"):
        unpack(data, tmp_path / "a", max_unpacked=5000)
    assert list((tmp_path / "a").iterdir()) == []


def test_unpack_refuses_a_file_where_a_folder_goes(tmp_path):
    data = _zip({MANIFEST: MANIFEST_OK, "mypol.py": "", "x": "file", "x/y": "under a file"})
    with pytest.raises(PackageError, match="member folder 'x' collides with a file of the package"):
        unpack(data, tmp_path / "d")
