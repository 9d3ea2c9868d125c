"""numba's on-disk cache for wfbench, keyed by every source file the compiled code depends on.

numba's cache checks only the cached function's own file, so an edit of an inlined module
(``dynamics.py`` in ``policies/episode.py``) kept the old code running. Importing this module
registers :class:`DigestLocator`, whose source stamp for a cached function of ``wfbench`` or
``policies`` is a digest of its file, every in-project file it imports at module level,
transitively (:func:`dependencies`), and the numba, numpy and Python versions. It must be imported
before any module with cached functions (``wfbench/__init__`` imports it first). The first compile
in a process prints one line with an estimate scaled by :func:`load_factor`. The design, the
cache's place and the pinned numba internals: ``docs/performance.md``, "A cache that cannot lie".
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import re
import sys
import threading
import time
from pathlib import Path

import numba
import numpy as np
from numba.core import caching, event

from wfbench.core.paths import package_dir

# In-project imports are followed into these packages. wfbench.policies and wfbench.solvers are the checkout's
# top-level folders policies/ and solvers/ (pyproject.toml maps them); an installed wheel has them under wfbench/.
# The import system says which (wfbench.core.paths), not arithmetic on this file's path.
PACKAGES = {name: package_dir(name) for name in ("wfbench", "wfbench.policies", "wfbench.solvers")}
ROOT = PACKAGES["wfbench"].parent  # the folder that holds wfbench/ (and, in a checkout, policies/, solvers/)
CACHED_PACKAGES = ("wfbench", "policies")  # the folders (under ROOT) whose functions DigestLocator locates
ENV_CACHE_DIR = "WFBENCH_CACHE_DIR"

# Cold compile time (wall, seconds) after the first entry point a process compiles,
# measured on the development VM (docs/performance.md, "Cold start"); used until this
# machine has recorded its own. reset_batch: a Simulator (reset, step, observe);
# play_range: the compiled episode runner that ``wfbench evaluate`` runs, one per combination of rule codes
# (``policies/episode.py``; docs/performance.md, "Cold compile").
ESTIMATE_S = {
    "wfbench.core.dynamics.reset_batch": 45,
    "wfbench.policies.episode.play_range": 35,
}
DEFAULT_ESTIMATE_S = 60
# what a process's first compilation builds, by the module of the function numba compiles first (the longest
# prefix wins; the episode and the lookaheads inline the simulator's step, so they compile it too): the cold-start
# line names it, so a user who sees the line again for another family learns what is compiled this time
WHAT = {
    "wfbench.core": "the simulator core",
    "wfbench.policies": "the built-in policies' compiled code and the simulator's step it inlines",
    "wfbench.policies.episode": "the compiled episode of these built-in rules (each combination of rules once) and "
                                "the simulator's step it inlines",
    "wfbench.policies.kernels.act": "the kernels of this policy's built-in rules (each combination of rules once)",
    "wfbench.policies.lookahead": "the lookaheads' kernels (rollouts on sampled futures, the MPC's model)",
    "wfbench.policies.oracle": "the hindsight oracle's planner and roll-forward",
    "wfbench.policies.kernels.forward": "the roll-forward of the lookaheads (for their base's rules) and the oracle",
    "wfbench.solvers": "the solvers' compiled kernels",
}
TIMES_FILE = "wfbench-compile-times.json"


# -- the digest ----------------------------------------------------------------------------------
# Plain strings and os.path, memoized: the digests are computed at every start-up.
_FILES: dict[str, str | None] = {}
_SOURCES: dict[str, bytes] = {}
_IMPORTS: dict[str, frozenset[str]] = {}
_DIGESTS: dict[str, str] = {}
_LISTINGS: dict[str, frozenset[str]] = {}
_OURS: dict[str, bool] = {}
_LOCK = threading.Lock()
_ROOT = str(ROOT)
_PREFIX = _ROOT + os.sep


def _listing(directory: str) -> frozenset[str]:
    names = _LISTINGS.get(directory)
    if names is None:
        try:
            names = frozenset(os.listdir(directory))
        except OSError:
            names = frozenset()
        _LISTINGS[directory] = names
    return names


def _module_file(module: str) -> str | None:
    """The source file of an in-project module name, or None (not ours, or no such file)."""
    path = _FILES.get(module, "")
    if path != "":
        return path
    path = None
    package = max((p for p in PACKAGES if module == p or module.startswith(p + ".")), key=len, default=None)
    if package is not None:
        parts = [package, *module[len(package) + 1:].split(".")] if module != package else [package]
        directory = os.fspath(PACKAGES[package])
        if len(parts) == 1:
            path = os.path.join(directory, "__init__.py") if "__init__.py" in _listing(directory) else None
        else:
            for part in parts[1:-1]:  # list only directories that exist
                if part not in _listing(directory):
                    break
                directory = os.path.join(directory, part)
            else:
                names = _listing(directory)
                if parts[-1] + ".py" in names:
                    path = os.path.join(directory, parts[-1] + ".py")
                elif parts[-1] in names and "__init__.py" in _listing(os.path.join(directory, parts[-1])):
                    path = os.path.join(directory, parts[-1], "__init__.py")
    _FILES[module] = path
    return path


def _relative(path: str) -> str:
    """``path`` (under ROOT, real) relative to ROOT, with ``/`` separators."""
    return path[len(_PREFIX):].replace(os.sep, "/")


def _read(path: str) -> bytes:
    data = _SOURCES.get(path)
    if data is None:
        with open(path, "rb") as f:
            data = _SOURCES[path] = f.read()
    return data


# a module-level ``from MODULE import NAMES`` (NAMES parenthesized over lines, or continued
# with backslashes) or ``import NAMES``
_IMPORT = re.compile(
    r"^(?:from[ \t]+([.\w]+)[ \t]+import[ \t]*(\([^)]*\)|(?:[^\n]*\\\n)*[^\n]*)|import[ \t]+((?:[^\n]*\\\n)*[^\n]*))",
    re.M)
_COMMENT = re.compile(r"#[^\n]*")


def _names(text: str) -> list[str]:
    """The imported names in ``a as b, c`` (comments, parentheses and continuations removed): ``[a, c]``."""
    text = _COMMENT.sub("", text).replace("(", " ").replace(")", " ").replace("\\", " ")
    return [n.split()[0] for n in text.split(",") if n.strip()]


def imported_modules(path: str | os.PathLike) -> frozenset[str]:
    """Dotted names of what the file ``path`` imports at module level (outside functions and classes).

    ``from pkg import name`` gives ``pkg`` and ``pkg.name`` (the name may be a module).
    Relative imports are resolved against the package of ``path``, which must lie under
    :data:`ROOT`.
    """
    path = os.fspath(path)
    found = _IMPORTS.get(path)
    if found is not None:
        return found
    package = _relative(path).split("/")[:-1]  # the package of a module, and of a package's __init__ itself
    names = set()
    for m in _IMPORT.finditer(_read(path).decode("utf-8")):
        module, imported, plain = m.groups()
        if plain is not None:
            names.update(_names(plain))
            continue
        level = len(module) - len(module.lstrip("."))
        if level:
            stem = module[level:]
            module = ".".join(package[: len(package) - level + 1] + ([stem] if stem else []))
        names.add(module)
        names.update(f"{module}.{n}" for n in _names(imported))
    found = _IMPORTS[path] = frozenset(names)
    return found


def dependencies(path: str | os.PathLike) -> tuple[str, ...]:
    """``path`` and every in-project source file it imports at module level, transitively, sorted."""
    start = os.path.realpath(path)
    seen = {start}
    todo = [start]
    while todo:
        for module in imported_modules(todo.pop()):
            dep = _module_file(module)
            if dep is not None and dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return tuple(sorted(seen))


def source_digest(path: str | os.PathLike) -> str:
    """The cache stamp of the functions in ``path``: a sha256 of its dependencies' contents and the versions."""
    path = os.path.realpath(path)
    with _LOCK:
        digest = _DIGESTS.get(path)
        if digest is None:
            h = hashlib.sha256()
            h.update(f"numba {numba.__version__} numpy {np.__version__} python {platform.python_version()}".encode())
            for dep in dependencies(path):
                h.update(b"\0" + _relative(dep).encode() + b"\0")
                h.update(_read(dep))
            digest = _DIGESTS[path] = h.hexdigest()
    return digest


def is_ours(py_file: str | os.PathLike) -> bool:
    """``py_file`` is a source file of a package whose cache :class:`DigestLocator` keys."""
    py_file = os.fspath(py_file)
    ours = _OURS.get(py_file)
    if ours is None:
        real = os.path.realpath(py_file)
        rel = _relative(real).split("/") if real.startswith(_PREFIX) else []
        ours = _OURS[py_file] = len(rel) > 1 and rel[0] in CACHED_PACKAGES and rel[-1].endswith(".py")
    return ours


# -- the locator -----------------------------------------------------------------------------------
class _EnvDirLocator(caching.UserProvidedCacheLocator):
    """numba's locator for ``NUMBA_CACHE_DIR``, pointed at ``WFBENCH_CACHE_DIR`` instead."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(os.environ[ENV_CACHE_DIR], self.get_suitable_cache_subpath(py_file))

    @classmethod
    def from_function(cls, py_func, py_file):
        if not os.environ.get(ENV_CACHE_DIR):
            return None
        self = cls(py_func, py_file)
        try:
            self.ensure_cache_path()
        except OSError:
            return None
        return self


_INNER = (_EnvDirLocator, caching.UserProvidedCacheLocator, caching.InTreeCacheLocator,
          caching.UserWideCacheLocator)


class DigestLocator(caching._CacheLocator):
    """numba's usual cache directory, with the digest of the file's dependencies as the source stamp."""

    def __init__(self, inner: caching._CacheLocator, py_file: str, module: str = ""):
        self._inner = inner
        self._py_file = py_file
        # the module's dotted name is part of the file name: an index pickled under another name (before
        # policies/ was installed as wfbench.policies) names classes that no longer import, and numba unpickles
        # an index before it compares stamps
        self._module_tag = hashlib.sha256(module.encode()).hexdigest()[:8]

    def ensure_cache_path(self):
        self._inner.ensure_cache_path()

    def get_cache_path(self):
        return self._inner.get_cache_path()

    def get_source_stamp(self):
        return source_digest(self._py_file)

    def get_disambiguator(self):
        return f"{self._inner.get_disambiguator()}-{self._module_tag}"

    @classmethod
    def from_function(cls, py_func, py_file):
        if not is_ours(py_file):
            return None
        for locator_class in _INNER:
            inner = locator_class.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner, py_file, getattr(py_func, "__module__", "") or "")
        return None


# -- the line on a cold start ----------------------------------------------------------------------
class _ColdCompileNotice(event.Listener):
    """Prints one line before the first compilation of one of our functions; records how long it took.

    A subclass says something else in that line through :meth:`first_line`, and records
    nothing when ``records_times`` is False (the sandbox's child, whose cache dies with it).
    """

    records_times = True  # keep this machine's compile time beside the cache (TIMES_FILE)

    def __init__(self):
        self.first: str | None = None  # qualified name of the first function of ours compiled
        self.times_path: Path | None = None
        self.started = 0.0
        self.depth = 0  # nesting of our compilations (callees compile inside their callers)
        self.total = 0.0  # idle-equivalent seconds: wall time divided by the load factor
        self.factor = 1.0  # load_factor() when the compilation started

    @staticmethod
    def _ours(ev) -> tuple[str, str] | None:
        func = getattr(ev.data.get("dispatcher"), "py_func", None)
        code = getattr(func, "__code__", None)
        if code is None or not is_ours(code.co_filename):
            return None
        return f"{func.__module__}.{func.__qualname__}", code.co_filename

    def on_start(self, ev):
        ours = self._ours(ev)
        if ours is None:
            return
        self.depth += 1
        if self.depth > 1:
            return
        self.started = time.perf_counter()
        if self.first is None:
            self.first = ours[0]
            cache = getattr(ev.data["dispatcher"], "_cache", None)
            path = getattr(cache, "cache_path", None)
            self.times_path = Path(path) / TIMES_FILE if path and self.records_times else None
            self.factor = load_factor()
            print(self.first_line(path), file=sys.stderr, flush=True)

    def first_line(self, path: str | None) -> str:
        """The line printed before the first compilation (``path``: numba's cache folder of it, if any)."""
        where = f" ({path})" if path else ""
        return f"wfbench: compiling {self.what()} once, {self._estimate()}; cached afterwards{where}"

    def what(self) -> str:
        """What the first compilation builds (:data:`WHAT`), else the module of its first function."""
        module = (self.first or "").rpartition(".")[0]
        known = [k for k in WHAT if module == k or module.startswith(k + ".")]
        return WHAT[max(known, key=len)] if known else f"{module or 'wfbench'}'s compiled code"

    def _estimate(self) -> str:
        """``~N s (how N was found)``: the idle time here (else on the development VM) times the load factor."""
        recorded = self._recorded().get(self.first)
        idle = recorded or ESTIMATE_S.get(self.first, DEFAULT_ESTIMATE_S)
        source = "on this machine idle, from its last compile" if recorded else "on an idle 2-core VM"
        if self.factor < 1.1:
            return f"~{idle:.0f} s ({source})"
        return f"~{idle * self.factor:.0f} s ({idle:.0f} s {source}, x{self.factor:.1f} for the current load)"

    def on_end(self, ev):
        if self._ours(ev) is None:
            return
        self.depth -= 1
        if self.depth == 0:
            self.total += (time.perf_counter() - self.started) / self.factor  # the load before it began
            self._record()

    def _recorded(self) -> dict:
        try:
            return json.loads(self.times_path.read_text())
        except (AttributeError, OSError, ValueError):
            return {}

    def _record(self) -> None:
        """Store the compile time of this process so far under its first entry point (atomic replace)."""
        if self.times_path is None:
            return
        times = self._recorded()
        times[self.first] = round(self.total, 1)
        tmp = self.times_path.with_name(f"{TIMES_FILE}.{os.getpid()}.tmp")
        try:
            tmp.write_text(json.dumps(times, indent=1, sort_keys=True))
            os.replace(tmp, self.times_path)
        except OSError:
            pass


def load_factor() -> float:
    """How much slower a single-threaded compile runs now than on an idle machine: at least 1.

    The one-minute load average plus the compile itself, shared over the cores (a busy
    2-core machine at load 3 gives 2.0); 1 where the load average is not available.
    """
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        return 1.0
    return max(1.0, (load + 1.0) / (os.cpu_count() or 1))


NOTICE = _ColdCompileNotice()


def install() -> None:
    """Register :class:`DigestLocator` first among numba's cache locators, and the cold-start notice."""
    classes = caching.CacheImpl._locator_classes
    if DigestLocator not in classes:
        classes.insert(0, DigestLocator)
        event.register("numba:compile", NOTICE)


install()
