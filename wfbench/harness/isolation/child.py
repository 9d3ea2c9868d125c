"""The process inside the sandbox: loads a policy package and answers the evaluator over two pipes.

Run as ``python -I -B -u -m wfbench.harness.isolation.child CONFIG`` by
:mod:`wfbench.harness.isolation.sandbox` inside bubblewrap. Before any of the package's code runs
it closes every other descriptor, sets its rlimits and sends STARTED (``-I`` keeps the package
off the import path until then, so it cannot shadow the child's modules); then it loads the entry
point and serves RESET, ACT and BYE (:mod:`wfbench.harness.isolation.wire`), answering a policy's
failure with a one-line ERROR. It sends nothing about time. :class:`CacheCopies` copies entries
of the evaluator's read-only numba cache into the sandbox's own. ``docs/leaderboard.md``, "The
sandbox's process and its pipes" and "numba's cache in the sandbox".
"""

from __future__ import annotations

import importlib
import json
import os
import resource
import stat
import sys
import traceback
from collections import deque
from typing import Any

import numpy as np
from numba.core import caching
from numba.core import event as numba_event

from wfbench.core import jit
from wfbench.harness.isolation.wire import Decoder, Kind, Message, WireError, array_text, encode, text_array, wire_dtype

PACKAGE_ROOT = "/policy/"  # where the sandbox mounts the package; frames under it are the user's
PROBE_OK = "wfbench-sandbox-probe-ok"  # what a probe prints once its Python has imported wfbench in the sandbox


class Channel:
    """The child's end of the protocol: blocking reads and writes of whole messages."""

    def __init__(self, fd_in: int, fd_out: int):
        self.fd_in, self.fd_out = fd_in, fd_out
        self.decoder = Decoder()
        self.inbox: deque[Message] = deque()

    def send(self, kind: Kind, arrays: dict[str, np.ndarray] | None = None) -> None:
        view = memoryview(encode(kind, arrays))
        while view:
            view = view[os.write(self.fd_out, view):]

    def receive(self) -> Message | None:
        """The next message, or None when the evaluator closed its end."""
        while not self.inbox:
            data = os.read(self.fd_in, 1 << 20)
            if not data:
                return None
            self.inbox.extend(self.decoder.feed(data))
        return self.inbox.popleft()

    def error(self, reason: str, trace: str = "") -> None:
        self.send(Kind.ERROR, {"reason": text_array(reason), "trace": text_array(trace)})


class SandboxCompileNotice(jit._ColdCompileNotice):
    """wfbench's line before a cold compile, true in the sandbox: the compiled code is thrown away with it.

    Outside a sandbox wfbench says its kernels compile once and are cached; here the cache
    is the sandbox's tmpfs, which dies with it, so the next sandbox compiles again unless the
    evaluator's own cache (which it copies from) holds the kernel.
    """

    records_times = False  # nothing to record: the sandbox's files die with it

    def first_line(self, path: str | None) -> str:
        return (f"wfbench: compiling {self.first} inside the sandbox, {self._estimate()}; the compiled code is thrown "
                "away with the sandbox (its cache lives in the sandbox's /tmp), so every sandbox of this policy "
                "compiles it again unless the evaluator's own cache holds it")


def install_notice() -> None:
    """Put :class:`SandboxCompileNotice` in place of wfbench's own line about compiling."""
    numba_event.unregister("numba:compile", jit.NOTICE)
    numba_event.register("numba:compile", SandboxCompileNotice())


def _probe() -> None:
    """A stand-in function: numba's cache locators are asked about a source file through a function in it."""


def cache_folder(py_file: str) -> str | None:
    """The folder this process's numba caches the compiled functions of ``py_file`` in (None: not cached).

    The first of numba's locator classes that takes the file, as numba's own choice
    (``numba.core.caching._CacheImpl``); wfbench's :class:`~wfbench.core.jit.DigestLocator`
    comes first among them. The folder depends only on where the file is, so any
    function stands in for the file's.
    """
    for locator_class in caching.CacheImpl._locator_classes:
        locator = locator_class.from_function(_probe, py_file)
        if locator is not None:
            return os.path.normpath(locator.get_cache_path())
    return None


class CacheCopies:
    """The evaluator's compiled kernels, copied into this process's own numba cache as numba first reads each.

    numba refuses a cache folder it cannot write, so the evaluator's (trusted) cache is
    mounted read-only and each entry (an index, ``*.nbi``, and its data files, ``*.nbc``)
    is copied into the folder where this process's numba looks (:func:`cache_folder`:
    ``/tmp/numba/...``) just before numba reads the index. Only what the policy calls is
    copied, at most ``budget`` bytes in all (past it numba compiles, as on a cold cache);
    a file larger than the file size limit is left out rather than killing the process
    (SIGXFSZ). A failed copy costs a compilation, never the policy's run.

    Args:
        sources: source file -> the read-only folder holding the evaluator's cache of its folder.
        budget: bytes it may copy.
        max_file: the largest file it may write (RLIMIT_FSIZE).
    """

    def __init__(self, sources: dict[str, str], budget: int, max_file: int):
        self.folders: dict[str, str] = {}  # this process's cache folder -> the evaluator's, read-only
        for py_file, mounted in sources.items():
            mine = cache_folder(py_file)
            if mine is not None:
                self.folders[mine] = mounted
        self.left, self.max_file = int(budget), int(max_file)
        self.copied: list[str] = []
        self._seen: set[tuple[str, str]] = set()
        self._listings: dict[str, list[str]] = {}

    def install(self) -> None:
        """Copy each entry just before numba first loads its index (``IndexDataCacheFile._load_index``)."""
        load_index = caching.IndexDataCacheFile._load_index
        copies = self

        def _load_index(cache_file: caching.IndexDataCacheFile) -> dict:
            copies.fetch(cache_file._cache_path, cache_file._index_name)
            return load_index(cache_file)

        caching.IndexDataCacheFile._load_index = _load_index

    def fetch(self, cache_path: str, index_name: str) -> None:
        """Copy the evaluator's ``index_name`` and its data files into ``cache_path``, once."""
        target = os.path.normpath(cache_path)
        source = self.folders.get(target)
        if source is None or not index_name.endswith(".nbi") or (target, index_name) in self._seen:
            return
        self._seen.add((target, index_name))
        if index_name not in self._listing(source):
            return
        stem = index_name[: -len(".nbi")] + "."
        names = [n for n in self._listing(source) if n.startswith(stem) and n.endswith(".nbc")]
        for name in [*sorted(names), index_name]:  # the index last: without it numba reads none of the data
            if not self._copy(os.path.join(source, name), os.path.join(target, name)):
                return

    def _listing(self, folder: str) -> list[str]:
        if folder not in self._listings:
            try:
                self._listings[folder] = os.listdir(folder)
            except OSError:
                self._listings[folder] = []
        return self._listings[folder]

    def _copy(self, src: str, dest: str) -> bool:
        """One regular file within the budget, written beside ``dest`` and renamed over it (whatever ``dest`` was)."""
        tmp = f"{dest}.copy.{os.getpid()}"
        try:
            st = os.lstat(src)
            if not stat.S_ISREG(st.st_mode) or st.st_size > min(self.left, self.max_file):
                return False
            with open(src, "rb") as f:
                data = f.read(st.st_size + 1)
            if len(data) != st.st_size:  # rewritten while we read it (the evaluator compiling): leave it
                return False
            with open(tmp, "wb") as f:
                f.write(data)
            os.replace(tmp, dest)
        except OSError:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            return False
        self.left -= st.st_size
        self.copied.append(dest)
        return True


def set_limits(rlimits: dict[str, int]) -> None:
    """Soft and hard limits both, so the policy cannot raise them again (CPU: hard one second later, SIGKILL)."""
    for name, value in rlimits.items():
        which = getattr(resource, f"RLIMIT_{name}")
        resource.setrlimit(which, (value, value + 1 if name == "CPU" else value))


def load(entry: str) -> Any:
    """The policy of ``module:attr``: an object, or a class or factory called with no arguments.

    The rules of :func:`wfbench.policies.registry.get` for an entry point, without the
    registry (whose other spellings, ``ppo:PATH`` and the like, mean files outside the package).
    """
    module_name, _, attr = entry.partition(":")
    obj: Any = importlib.import_module(module_name)
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise AttributeError(f"module {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if isinstance(obj, type) or (not (hasattr(obj, "act") and hasattr(obj, "reset")) and callable(obj)):
        obj = obj()
    if not (hasattr(obj, "act") and hasattr(obj, "reset")):
        raise TypeError(f"entry point {entry!r} is not a policy: it needs reset(seeds) and act(obs)")
    return obj


def where_syntax(exc: SyntaxError) -> str | None:
    """`` (pkg/file.py, line N)``-style text of a SyntaxError in one of the package's files, else None."""
    filename = exc.filename or ""
    if not filename.startswith(PACKAGE_ROOT):
        return None
    message = exc.msg or "invalid syntax"
    return f"{type(exc).__name__}: {message} ({filename[len(PACKAGE_ROOT):]}, line {exc.lineno})"


def where(tb: Any) -> str:
    """`` at pkg/file.py:LINE``: the innermost frame inside the package (else the innermost frame)."""
    frames = traceback.extract_tb(tb)
    for fr in reversed(frames):
        if fr.filename.startswith(PACKAGE_ROOT):
            return f" at {fr.filename[len(PACKAGE_ROOT):]}:{fr.lineno}"
    return f" at {frames[-1].filename}:{frames[-1].lineno}" if frames else ""


def what(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__


def failure(exc: BaseException, call: str, memory_mb: int) -> str:
    """The one-line reason for an exception the policy raised in ``call``."""
    if isinstance(exc, MemoryError):
        return f"{what(exc)} in {call}{where(exc.__traceback__)} (memory limit {memory_mb} MB)"
    if isinstance(exc, SyntaxError) and where_syntax(exc):
        return f"the policy could not be loaded: {where_syntax(exc)}" if call == "loading" else \
            f"the policy raised {where_syntax(exc)} in {call}"
    if call == "loading":
        return f"the policy could not be loaded: {what(exc)}{where(exc.__traceback__)}"
    return f"the policy raised {what(exc)} in {call}{where(exc.__traceback__)}"


def action_arrays(action: Any) -> dict[str, np.ndarray]:
    """The policy's action as arrays the wire carries; integers widen to int64, other floats to float64."""
    if not isinstance(action, dict):
        raise TypeError(f"act returned {type(action).__name__}; allowed: a dict of arrays")
    out = {}
    for name, value in action.items():
        a = np.asarray(value)
        try:
            wire_dtype(a)
        except WireError:
            if a.dtype.kind in "iu":
                a = a.astype(np.int64)
            elif a.dtype.kind == "f":
                a = a.astype(np.float64)
            else:
                raise TypeError(f"act returned {name!r} of dtype {a.dtype}; allowed: numbers") from None
        out[str(name)] = a
    return out


def world_config(text: str) -> Any:
    """The :class:`~wfbench.core.config.ScenarioConfig` of a RESET's ``world`` (its JSON), imported when first sent."""
    from wfbench.core.config import ScenarioConfig

    return ScenarioConfig.from_json(text)


def serve(channel: Channel, policy: Any, memory_mb: int) -> int:
    """Answer RESET and ACT until BYE (0) or a failure (1)."""
    while True:
        msg = channel.receive()
        if msg is None or msg.kind == Kind.BYE:
            return 0
        if msg.kind not in (Kind.RESET, Kind.ACT):
            channel.error(f"the sandbox got a {msg.kind.name} message; allowed: RESET, ACT, BYE")
            return 1
        call = "reset" if msg.kind == Kind.RESET else "act"
        try:
            if msg.kind == Kind.RESET:
                if "world" in msg.arrays and hasattr(policy, "set_world"):  # runner.public_world's config
                    call = "set_world"
                    policy.set_world(world_config(array_text(msg.arrays["world"])))
                    call = "reset"
                policy.reset(msg.arrays["keys"].astype(np.int64))
                reply: tuple[Kind, dict[str, np.ndarray]] = (Kind.READY, {})
            else:
                reply = (Kind.ACTION, action_arrays(policy.act(msg.arrays)))
            channel.send(*reply)
        except Exception as exc:  # noqa: BLE001 - anything the policy raises is its failure, reported in one line
            channel.error(failure(exc, call, memory_mb), "".join(traceback.format_exception(exc)))
            return 1


def close_other_fds(keep: set[int]) -> None:
    """Close every descriptor but ``keep``: the policy inherits nothing from bubblewrap or the evaluator."""
    try:
        fds = [int(fd) for fd in os.listdir("/proc/self/fd")]
    except OSError:
        fds = list(range(3, 1024))
    for fd in fds:
        if fd not in keep:
            try:
                os.close(fd)
            except OSError:
                pass


def main(argv: list[str]) -> int:
    config = json.loads(argv[0])
    if config.get("probe"):  # check_sandbox: this Python started in the sandbox and imported wfbench
        set_limits(config["rlimits"])
        print(PROBE_OK, flush=True)
        return 0
    close_other_fds({0, 1, 2, config["in"], config["out"]})
    set_limits(config["rlimits"])
    channel = Channel(config["in"], config["out"])
    memory_mb = int(config["memory_mb"])
    install_notice()
    if config.get("numba_cache"):
        CacheCopies(dict(config["numba_cache"]), config["numba_cache_bytes"], config["rlimits"]["FSIZE"]).install()
    channel.send(Kind.STARTED)  # nothing of the package has run yet: what fails from here on is the policy's
    sys.path.insert(0, PACKAGE_ROOT.rstrip("/"))
    try:
        policy = load(config["entry"])
    except Exception as exc:  # noqa: BLE001 - the package's import or constructor failed
        channel.error(failure(exc, "loading", memory_mb), "".join(traceback.format_exception(exc)))
        return 1
    if getattr(policy, "reads_trace", False):
        channel.error("the policy declares reads_trace (it reads the scenario's future, like a hindsight oracle); "
                      "a sandboxed policy sees observations only")
        return 1
    decisions = getattr(policy, "decisions", ())
    name = getattr(policy, "name", None) or type(policy).__qualname__
    channel.send(Kind.HELLO, {"decisions": text_array(",".join(map(str, decisions))),
                              "name": text_array(str(name))})
    return serve(channel, policy, memory_mb)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
