"""Policy packages: a zip of a policy's code and checkpoint files with a manifest, checked before it is opened.

A package is a zip (a wheel is one) holding the policy's package folder or module and, at the
top, ``wfbench-policy.json`` (``{"entry": "module:attr", "format": 1}``). :func:`pack` makes one
deterministically, so the same code gives the same bytes and :func:`content_hash`.
:func:`inspect` checks an archive without extracting it (size, members, names: no zip-slip,
types: no links or devices, declared sizes and ratio: no zip bomb, the manifest); :func:`unpack`
checks again and counts the bytes it writes, so lying headers get no further. Every refusal is a
one-line :class:`PackageError`. ``docs/leaderboard.md``, "Phases, seeds and keys".
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import shutil
import stat
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

MANIFEST = "wfbench-policy.json"
FORMAT = 1
MAX_PACKAGE_BYTES = 64 << 20  # the archive
MAX_UNPACKED_BYTES = 256 << 20  # its members, unpacked
MAX_MEMBERS = 10_000
MAX_RATIO = 200  # unpacked / packed, over the archive, once it unpacks to more than RATIO_FLOOR
RATIO_FLOOR = 1 << 20
MAX_NAME = 1024
_DATE = (1980, 1, 1, 0, 0, 0)  # the earliest date a zip can hold: every member gets it
_IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
ENTRY_RE = re.compile(rf"{_IDENT}(\.{_IDENT})*:{_IDENT}(\.{_IDENT})*")
_SKIP = ("__pycache__",)  # never packed: Python rebuilds them


class PackageError(ValueError):
    """A package was refused; ``str()`` is one line saying what is wrong and what is allowed."""


@dataclass(frozen=True)
class Manifest:
    """What a checked package declares."""

    entry: str
    format: int = FORMAT
    members: int = 0  # files and folders in the archive
    unpacked_bytes: int = 0  # what the headers declare

    @property
    def module(self) -> str:
        """The top-level module or package the entry point is imported from."""
        return self.entry.split(":", 1)[0].split(".", 1)[0]


def content_hash(data: bytes) -> str:
    """``sha256:<hex>`` of the package's bytes: its identity on a board."""
    return "sha256:" + hashlib.sha256(data).hexdigest()


def check_entry(entry: str) -> str:
    """``entry`` if it is a ``module:attr`` entry point whose module may be shipped, else PackageError."""
    if not isinstance(entry, str) or not entry.isascii() or not ENTRY_RE.fullmatch(entry):
        raise PackageError(f"entry point {entry!r} is not allowed; allowed: module:attr (dotted Python names, for "
                           "example mypolicy:Policy)")
    top = entry.split(":", 1)[0].split(".", 1)[0]
    if top == "wfbench" or top in sys.stdlib_module_names:
        raise PackageError(f"entry point {entry!r}: a package named {top!r} would hide "
                           f"{'wfbench' if top == 'wfbench' else 'the Python module of that name'}; rename it")
    return entry


# -- making a package ------------------------------------------------------------------------------------------------


def pack(entry: str, root: str | Path = ".") -> bytes:
    """The package of ``entry``: its top-level package folder (or module file) under ``root``, and the manifest.

    Files in ``__pycache__`` are left out; a symlink is refused (a package holds plain files).
    """
    check_entry(entry)
    root = Path(root)
    top = entry.split(":", 1)[0].split(".", 1)[0]
    folder, module = root / top, root / f"{top}.py"
    if folder.is_dir():
        files = _files(folder, root)
    elif module.is_file():
        files = _files(module, root)
    else:
        raise PackageError(f"entry point {entry!r}: neither {folder}/ nor {module} exists (the module must be a "
                           f"folder or file directly under {root})")
    manifest = json.dumps({"entry": entry, "format": FORMAT}, sort_keys=True).encode()
    return archive([(MANIFEST, manifest), *((name, path.read_bytes()) for name, path in files)])


def pack_folder(folder: str | Path) -> bytes:
    """The package of a folder that holds a manifest (``wfbench-policy.json``) and the code it names."""
    folder = Path(folder)
    if not (folder / MANIFEST).is_file():
        raise PackageError(f"{folder} holds no {MANIFEST}; a package folder needs one: "
                           '{"entry": "module:attr", "format": 1}')
    return archive([(name, path.read_bytes()) for name, path in _files(folder, folder)])


def _files(path: Path, root: Path) -> list[tuple[str, Path]]:
    """(archive name, file) of ``path`` (a file, or every file below a folder), sorted, relative to ``root``."""
    out = []
    for p in [path] if path.is_file() else sorted(path.rglob("*")):
        rel = p.relative_to(root)
        if any(part in _SKIP for part in rel.parts) or p.suffix == ".pyc":
            continue
        if p.is_symlink():
            raise PackageError(f"{p} is a symlink; a package holds plain files only (copy what it points to)")
        if p.is_file():
            out.append((rel.as_posix(), p))
    return sorted(out)


def archive(members: list[tuple[str, bytes]]) -> bytes:
    """The deterministic zip of ``(name, bytes)`` members (sorted, fixed times, plain files 0644): what pack makes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in sorted(members):
            info = zipfile.ZipInfo(name, date_time=_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.create_system = 3  # unix, so that the mode below is read as one
            info.external_attr = (stat.S_IFREG | 0o644) << 16
            zf.writestr(info, data, compresslevel=9)
    return buf.getvalue()


# -- checking and opening one ----------------------------------------------------------------------------------------


def inspect(data: bytes, max_bytes: int = MAX_PACKAGE_BYTES, max_unpacked: int = MAX_UNPACKED_BYTES,
            max_members: int = MAX_MEMBERS) -> Manifest:
    """Check a package without extracting it; its manifest, or PackageError saying what is wrong."""
    if len(data) > max_bytes:
        raise PackageError(f"the package is {len(data)} bytes; allowed: at most {max_bytes} bytes")
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, ValueError, EOFError) as exc:
        raise PackageError(f"the package is not a zip archive ({exc}); allowed: a .zip or a wheel") from None
    with zf:
        infos = zf.infolist()
        if len(infos) > max_members:
            raise PackageError(f"the package has {len(infos)} members; allowed: at most {max_members}")
        seen: set[str] = set()
        for info in infos:
            _check_member(info, seen)
        declared = sum(i.file_size for i in infos)
        if declared > max_unpacked:
            raise PackageError(f"zip bomb: the members declare {declared} bytes unpacked; allowed: at most "
                               f"{max_unpacked}")
        if declared > RATIO_FLOOR and declared > MAX_RATIO * len(data):
            raise PackageError(f"zip bomb: {len(data)} bytes declare {declared} bytes unpacked (ratio "
                               f"{declared / len(data):.0f}); allowed: a ratio of at most {MAX_RATIO}")
        manifest = _read_manifest(zf)
        tops = {PurePosixPath(n).parts[0] for n in seen}
        top = manifest.module
        if top not in tops and f"{top}.py" not in tops:
            raise PackageError(f"the entry point's module {top!r} is not in the package (neither {top}/ nor {top}.py; "
                               f"it holds {', '.join(sorted(tops))})")
        return Manifest(manifest.entry, manifest.format, len(infos), declared)


def _check_member(info: zipfile.ZipInfo, seen: set[str]) -> None:
    name = info.filename
    shown = name if len(name) <= 80 else name[:77] + "..."
    if not name or len(name) > MAX_NAME or "\x00" in name or "\\" in name:
        raise PackageError(f"member {shown!r} has a name that is not allowed; allowed: relative paths with '/' of at "
                           f"most {MAX_NAME} characters")
    path = PurePosixPath(name)
    if name.startswith("/") or re.match(r"[A-Za-z]:", name):
        raise PackageError(f"absolute path: member {shown!r} would land outside the package; allowed: relative paths")
    if ".." in path.parts:
        raise PackageError(f"zip-slip: member {shown!r} would land outside the package; allowed: paths without '..'")
    mode = info.external_attr >> 16  # many tools write permission bits only: no type is a plain file
    if info.create_system == 3 and stat.S_IFMT(mode) not in (0, stat.S_IFREG, stat.S_IFDIR):
        kind = "a symlink" if stat.S_ISLNK(mode) else "a device, pipe or socket"
        raise PackageError(f"member {shown!r} is {kind}; allowed: plain files and folders")
    if info.flag_bits & 0x1:
        raise PackageError(f"member {shown!r} is encrypted; allowed: unencrypted members")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise PackageError(f"member {shown!r} uses compression method {info.compress_type}; allowed: stored or "
                           "deflated")
    key = path.as_posix()
    if key in seen:
        raise PackageError(f"member {shown!r} appears twice; allowed: each name once")
    seen.add(key)


def _read_manifest(zf: zipfile.ZipFile) -> Manifest:
    try:
        info = zf.getinfo(MANIFEST)
    except KeyError:
        raise PackageError(f"the package has no {MANIFEST} at its top; it needs one: "
                           '{"entry": "module:attr", "format": 1} (harness.isolation.package.pack writes it)') from None
    if info.file_size > 64 << 10:
        raise PackageError(f"{MANIFEST} is {info.file_size} bytes; allowed: at most 64 KiB")
    try:
        doc = json.loads(zf.read(info))
    except (ValueError, zipfile.BadZipFile, OSError) as exc:
        raise PackageError(f"{MANIFEST} is not valid JSON ({str(exc).splitlines()[0]}); allowed: "
                           '{"entry": "module:attr", "format": 1}') from None
    if not isinstance(doc, dict) or set(doc) != {"entry", "format"}:
        raise PackageError(f"{MANIFEST} holds {json.dumps(doc)[:100]}; allowed: exactly the keys entry and format, "
                           '{"entry": "module:attr", "format": 1}')
    if doc["format"] != FORMAT or isinstance(doc["format"], bool):
        raise PackageError(f"{MANIFEST} has format {doc['format']!r}; allowed: {FORMAT}")
    return Manifest(check_entry(doc["entry"]), FORMAT)


def unpack(data: bytes, dest: str | Path, max_bytes: int = MAX_PACKAGE_BYTES, max_unpacked: int = MAX_UNPACKED_BYTES,
           max_members: int = MAX_MEMBERS) -> Manifest:
    """Check the package, then extract it into ``dest`` (created, or empty), readable by all; its manifest.

    The bytes written are counted as they stream out and extraction stops at
    ``max_unpacked``, whatever the headers declared; on any failure ``dest`` is emptied
    again. Files are 0644 and folders 0755 (``dest`` too): the sandbox's user reads them.
    """
    manifest = inspect(data, max_bytes, max_unpacked, max_members)
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    if any(dest.iterdir()):
        raise PackageError(f"cannot unpack into {dest}: it is not empty")
    os.chmod(dest, 0o755)
    try:
        _extract(data, dest, max_unpacked)
    except BaseException:
        for child in dest.iterdir():
            shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
        raise
    return manifest


def _extract(data: bytes, dest: Path, max_unpacked: int) -> None:
    written = 0
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        for info in zf.infolist():
            target = dest.joinpath(*PurePosixPath(info.filename).parts)
            if info.is_dir():
                _mkdirs(dest, target)
                continue
            _mkdirs(dest, target.parent)
            try:
                fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
            except OSError as exc:
                raise PackageError(f"member {info.filename!r} cannot be written ({exc.strerror}); allowed: each "
                                   "path once, files and folders not overlapping") from None
            try:
                with os.fdopen(fd, "wb") as out, zf.open(info) as src:
                    while chunk := src.read(1 << 20):
                        written += len(chunk)
                        if written > max_unpacked:
                            raise PackageError(f"zip bomb: the members unpack to more than {max_unpacked} bytes "
                                               f"(their headers declared {sum(i.file_size for i in zf.infolist())})")
                        out.write(chunk)
            except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
                if isinstance(exc, PackageError):
                    raise
                raise PackageError(f"member {info.filename!r} is damaged ({str(exc).splitlines()[0]}); the package "
                                   "must unpack to what its headers declare") from None
            os.chmod(target, 0o644)


def _mkdirs(dest: Path, folder: Path) -> None:
    """Create ``folder`` (inside ``dest``) and its parents, 0755, refusing to pass through anything but folders."""
    rel = folder.relative_to(dest)
    cur = dest
    for part in rel.parts:
        cur = cur / part
        if cur.is_symlink() or (cur.exists() and not cur.is_dir()):
            raise PackageError(f"member folder {rel.as_posix()!r} collides with a file of the package; allowed: files "
                               "and folders not overlapping")
        if not cur.exists():
            cur.mkdir()
            os.chmod(cur, 0o755)
