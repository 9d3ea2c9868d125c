"""What identifies a local entry: the fingerprint of what a policy spec runs.

:func:`policy_fingerprint` covers a registry name's code and shipped file, a tuned file's or
checkpoint's bytes, or an entry point's loaded modules and ``params()``;
:func:`fingerprint_change` says in a few words what differs. ``docs/leaderboard.md``, "What
identifies an entry".
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import sys
from pathlib import Path
from typing import Any

from wfbench.leaderboard.rows import SubmitError
from wfbench.policies import registry as _registry

from wfbench import __version__
from wfbench.core.paths import package_dir
from wfbench.harness.guard import NOT_USER


def _sha(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@functools.lru_cache(maxsize=1)
def policy_code_digest() -> str:
    """sha256 over wfbench's policy code (every ``.py`` of ``policies`` and ``solvers``) and its version."""
    h = hashlib.sha256(__version__.encode())
    for pkg in ("wfbench.policies", "wfbench.solvers"):
        root = package_dir(pkg)
        for f in sorted(root.rglob("*.py")):
            # the folder's name (policies/, solvers/): the digest names files as it did before they were installed
            # under wfbench., so moving a name changes no fingerprint
            h.update(f"{root.name}/{f.relative_to(root).as_posix()}".encode())
            h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()


def _file_digest(spec: str, path: str | Path) -> str:
    try:
        return _sha(path)
    except OSError as exc:
        raise SubmitError(f"cannot read {str(path)!r} of policy {spec!r}: {exc.strerror or exc}") from None


def is_entry_point(spec: str) -> bool:
    """True for a ``module:attr`` entry point (the user's code), False for names, files and checkpoints."""
    return _registry.parse_spec(spec).kind == "entry-point"


def policy_fingerprint(spec: str, policy: Any = None) -> tuple[str, dict[str, Any]]:
    """The fingerprint of what ``spec`` runs (16 hex digits) and what it covers.

    - a registry name (composite, ``D+W+P``, shipped tuned file or network): the name,
      :func:`policy_code_digest`, and the bytes of the shipped file it loads;
    - a tuned-policy file (``.json``/``.toml``/``tuned:``): its bytes and the policy code
      digest (it parameterizes a built-in);
    - a checkpoint ``ALGO:PATH[@MODE]``: its bytes, the algorithm and the mode (not the path);
    - a ``module:attr`` entry point: the entry point, every loaded module of its top-level
      package, every other loaded module whose file is the user's (not in the Python
      installation, installed packages or wfbench), each by module name and file bytes,
      and ``policy.params()`` where the loaded ``policy`` declares it. Computed after the
      policy is loaded, in the process that loaded it.

    Raises:
        SubmitError: a file the policy names cannot be read.
    """
    detail: dict[str, Any]
    p = _registry.parse_spec(spec)  # the registry's one reading of the spec
    if p.kind == "checkpoint":
        detail = {"kind": "checkpoint", "algo": p.algo, "mode": "sample" if p.mode is None else p.mode,
                  "file": _file_digest(spec, p.path)}
    elif p.kind == "tuned-file":
        detail = {"kind": "tuned-file", "file": _file_digest(spec, p.path), "code": policy_code_digest()}
    elif p.kind != "entry-point":
        detail = {"kind": "builtin", "spec": spec, "code": policy_code_digest()}
        if p.kind in ("tuned", "learned", "member"):  # the shipped or trained file it loads
            detail["file"] = _file_digest(spec, p.file)
        elif p.kind == "oracle":  # it plays its candidates: their shipped files decide its numbers too
            detail["candidates"] = {
                c: _file_digest(spec, _registry.tuned_file(c)) if _registry.entry(c).kind == "tuned"
                else _file_digest(spec, _registry.checkpoint_file(c)) if _registry.entry(c).kind == "learned"
                else c
                for c in _registry.oracle_candidates()
            }
    else:
        top = p.name.split(".")[0]
        files = {}
        for mod_name, mod in sorted(sys.modules.items()):
            f = getattr(mod, "__file__", None)
            if not isinstance(f, str) or not os.path.isfile(f):
                continue
            mine = mod_name == top or mod_name.startswith(top + ".")
            if mine or not str(Path(f).resolve()).startswith(NOT_USER):
                files[mod_name] = _file_digest(spec, f)
        detail = {"kind": "entry-point", "entry": spec, "files": files}
        params = getattr(policy, "params", None)
        if callable(params):
            values = params()
            if isinstance(values, dict):
                detail["params"] = {str(k): repr(v) for k, v in sorted(values.items(), key=lambda kv: str(kv[0]))}
    text = json.dumps(detail, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16], detail


def fingerprint_change(old: str, new: dict[str, Any]) -> str:
    """What differs between a stored fingerprint's detail (JSON) and a new one, in a few words."""
    try:
        before = json.loads(old) if old else {}
    except json.JSONDecodeError:
        before = {}
    if not before:
        return "the stored entry has no fingerprint details"
    if before.get("kind") != new.get("kind"):
        return f"a {new.get('kind')} instead of a {before.get('kind')}"
    out = []
    for key, what in (("spec", "another registry name"), ("entry", "another entry point"),
                      ("algo", "another algorithm"), ("mode", "another mode"), ("file", "the file's bytes differ"),
                      ("code", "wfbench's policy code changed")):
        if before.get(key) != new.get(key):
            out.append(what)
    old_files, new_files = before.get("files", {}), new.get("files", {})
    for label, mods in (("changed", [m for m in new_files if m in old_files and new_files[m] != old_files[m]]),
                        ("new", [m for m in new_files if m not in old_files]),
                        ("gone", [m for m in old_files if m not in new_files])):
        if mods:
            out.append(f"{label}: {', '.join(mods[:5])}{', ...' if len(mods) > 5 else ''}")
    if before.get("params") != new.get("params"):
        out.append("its params() differ")
    return "; ".join(out) or "the fingerprint differs"
