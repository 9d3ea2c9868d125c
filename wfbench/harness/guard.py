"""Loading a policy once, and running a user's policy contained.

:func:`load_policy` turns a registry name, a ``module:attr`` entry point or a policy object into a
:class:`LoadedPolicy` once per evaluation. Built-in registry policies run as they are; every other
policy runs through a :class:`Guard`: its exceptions and refused actions become a one-line
:class:`PolicyError` naming its file and line (the whole trace in ``PolicyError.trace``), and each
``reset`` and ``act`` call has a time limit (``act_timeout_s``, a ``SIGALRM`` timer in the main
thread; the clock stops while numba holds its compiler lock). What each failure says and the
timer's limits: ``docs/leaderboard.md``, "When a policy fails"; ``docs/policies.md`` for authors.
"""

from __future__ import annotations

import inspect
import math
import os
import signal
import sysconfig
import threading
import traceback
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

from numba.core import event as numba_event

from wfbench.core.actions import ActionError
from wfbench.core.paths import package_dir
from wfbench.core.simulator import Simulator
from wfbench.policies import get

DEFAULT_ACT_TIMEOUT_S = 10.0
# the file name that cloudpickle (3.1.3, which joblib 1.6 uses) gives the code it sends by value (__main__'s)
DYNAMIC_CODE = "<dynamic-code>"

# files in these folders are not the user's (the Python installation, installed packages, wfbench's own folders):
# the innermost frame outside them is "where", and the leaderboard's fingerprint leaves them out
NOT_USER = tuple(  # folder prefixes with their separator: /repo/wfbench_runs/ is the user's
    {str(Path(sysconfig.get_paths()[k]).resolve()) + os.sep for k in ("stdlib", "platstdlib", "purelib", "platlib")}
    | {str(package_dir(f"wfbench{pkg}")) + os.sep for pkg in ("", ".policies", ".solvers", ".leaderboard")}
)


class PolicyError(RuntimeError):
    """A user's policy failed: ``str()`` is one line naming the policy, its file and line, and what was wrong.

    Attributes:
        message: that line.
        trace: the whole traceback, formatted in the process where the policy ran.
    """

    def __init__(self, message: str, trace: str = ""):
        super().__init__(message, trace)  # both in args: the error pickles from a worker whole
        self.message = message
        self.trace = trace

    def __str__(self) -> str:
        return self.message


class PolicyLoadError(ValueError):
    """The policy spec names nothing loadable (unknown name, missing module or attribute): a usage error."""


class ActTimeout(BaseException):
    """Raised inside a policy call that ran past its limit.

    A ``BaseException``, like ``KeyboardInterrupt``: a policy's own ``except Exception``
    does not swallow it.
    """


@dataclass(frozen=True)
class LoadedPolicy:
    """A policy resolved once: the object, the name reports use, and its guard (``None`` for built-ins)."""

    policy: Any
    name: str
    guard: Guard | None


def check_act_timeout(act_timeout_s: float | None) -> float | None:
    """``act_timeout_s`` if it is allowed (seconds > 0, or ``None``/0 for no limit), else ValueError."""
    if act_timeout_s is None or act_timeout_s == 0:
        return None
    if isinstance(act_timeout_s, bool) or not isinstance(act_timeout_s, (int, float)) \
            or not math.isfinite(act_timeout_s) or act_timeout_s < 0:
        raise ValueError(f"act_timeout_s = {act_timeout_s!r} is not allowed; allowed: seconds > 0, or 0/None for "
                         "no limit")
    return float(act_timeout_s)


def load_policy(policy: Any, act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S) -> LoadedPolicy:
    """Resolve ``policy`` once; every policy that is not a built-in registry name gets a guard.

    Args:
        policy: a registry name, a ``module:attr`` entry point, a policy object or a
            :class:`LoadedPolicy` (returned as it is).
        act_timeout_s: the time limit of each ``reset`` and ``act`` call of a user's
            policy in seconds; ``None`` or 0 for no limit.

    Returns:
        The loaded policy.

    Raises:
        PolicyLoadError: the spec names no policy (unknown name, module or attribute).
        PolicyError: the user's code raised while being imported or constructed.
    """
    if isinstance(policy, LoadedPolicy):
        return policy
    timeout = check_act_timeout(act_timeout_s)
    builtin = isinstance(policy, str) and ":" not in policy
    try:
        obj = get(policy)
    except ValueError as exc:
        raise PolicyLoadError(str(exc)) from None
    except Exception as exc:  # the user's module or constructor raised: name their line
        name = policy if isinstance(policy, str) else type(policy).__qualname__
        raise PolicyError(f"policy {name!r} could not be loaded: {one_line(exc)}{_at(exc.__traceback__)}",
                          _format(exc)) from exc
    name = policy if isinstance(policy, str) else str(getattr(obj, "name", None) or type(obj).__qualname__)
    return LoadedPolicy(obj, name, None if builtin else Guard(name, timeout, _source_file(obj)))


@dataclass(frozen=True)
class Guard:
    """Calls into a user's policy with a time limit, turning its failures into one-line PolicyErrors."""

    name: str
    act_timeout_s: float | None
    source: str | None = None  # the file of the policy's class, for its frames in a worker (see _at)

    def call(self, what: str, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)`` (the policy's ``reset`` or ``act``) under the time limit."""
        try:
            with _time_limit(self.act_timeout_s):
                return fn(*args)
        except ActTimeout as exc:
            stopped = _at(exc.__traceback__, " (stopped at ", self.source)
            raise PolicyError(
                f"policy {self.name!r} did not return from {what} within the act timeout of {self.act_timeout_s:g} s"
                f"{stopped + ')' if stopped else ''}; if it is only slow, raise the limit with --act-timeout "
                "(act_timeout_s= in Python)", _format(exc)) from None
        except MemoryError as exc:
            where = _at(exc.__traceback__, source=self.source)
            raise PolicyError(f"policy {self.name!r} ran out of memory in {what}{where} ({one_line(exc)})",
                              _format(exc)) from exc
        except Exception as exc:  # noqa: BLE001 - anything the user's code raises is its failure
            where = _at(exc.__traceback__, source=self.source)
            raise PolicyError(f"policy {self.name!r} failed in {what}{where}: {one_line(exc)}",
                              _format(exc)) from exc

    def step(self, sim: Simulator, actions: Any, act: Callable[..., Any]) -> None:
        """``sim.step(actions)``; an action the simulator refuses names the policy and its ``act``."""
        try:
            sim.step(actions)
        except (ActionError, TypeError, ValueError) as exc:  # np.asarray of garbage raises the latter two
            where = _defined_at(act)
            raise PolicyError(f"policy {self.name!r} returned a malformed action at step {sim.t}"
                              f"{f' (its act is at {where})' if where else ''}: {one_line(exc)}", _format(exc)) from exc


def one_line(exc: BaseException) -> str:
    """``Type: first line of the message``: how a board and the guard name an exception in one line."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _format(exc: BaseException) -> str:
    return "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))


def _at(tb: TracebackType | None, prefix: str = " at ", source: str | None = None) -> str:
    """`` at file:line`` of the innermost frame in the user's code (else the innermost frame).

    In a worker process a policy defined in a script or notebook (``__main__``) runs
    from code that cloudpickle sent by value, whose file name it replaces with
    ``<dynamic-code>`` (the line numbers stay); ``source``, the file of the policy's
    class in the parent, names it again.
    """
    frames = traceback.extract_tb(tb)
    if not frames:
        return ""
    for fr in reversed(frames):
        filename = source if source and fr.filename == DYNAMIC_CODE else fr.filename
        if _is_user_file(filename):
            return f"{prefix}{filename}:{fr.lineno}"
    return f"{prefix}{frames[-1].filename}:{frames[-1].lineno}"


def _source_file(obj: Any) -> str | None:
    """The file that defines ``obj``'s class, or None (built in, or defined where no file is)."""
    try:
        return inspect.getsourcefile(type(obj))
    except (TypeError, OSError):
        return None


def _is_user_file(filename: str) -> bool:
    if filename.startswith("<") and not filename.startswith("<ipython-input"):
        return False  # <frozen ...>, <string>: nothing a user can open
    try:
        path = str(Path(filename).resolve())
    except OSError:
        return True
    return not path.startswith(NOT_USER)


def _defined_at(fn: Callable[..., Any]) -> str:
    """``file:line`` where ``fn`` (a bound method or function) is defined, or ``""``."""
    try:
        target = inspect.unwrap(getattr(fn, "__func__", fn))
        return f"{inspect.getsourcefile(target)}:{target.__code__.co_firstlineno}"
    except (TypeError, AttributeError, OSError):
        return ""


_warned_no_limit = False
_REPEAT_S = 1.0  # the alarm fires again every second: a policy that swallows the first interrupt gets another


def _on_alarm(signum: int, frame: Any) -> None:
    raise ActTimeout()


class _PauseWhileCompiling(numba_event.Listener):
    """Stops the act clock while numba holds its compiler lock (loading from its cache or compiling).

    The lock is re-entrant and its events nest; the clock stops at the outermost start and
    runs on with the time that was left at the outermost end.
    """

    def __init__(self) -> None:
        self.armed = False  # a guarded call is running on the main thread
        self.depth = 0
        self.left = 0.0

    def on_start(self, event: numba_event.Event) -> None:
        if self.armed and self.depth == 0 and threading.current_thread() is threading.main_thread():
            self.left = signal.setitimer(signal.ITIMER_REAL, 0)[0]
        self.depth += 1

    def on_end(self, event: numba_event.Event) -> None:
        self.depth -= 1
        if self.armed and self.depth == 0 and self.left > 0:
            signal.setitimer(signal.ITIMER_REAL, self.left, _REPEAT_S)
            self.left = 0.0


_pause = _PauseWhileCompiling()
numba_event.register("numba:compiler_lock", _pause)


@contextmanager
def _time_limit(seconds: float | None) -> Iterator[None]:
    global _warned_no_limit
    if seconds is None:
        yield
        return
    if not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        if not _warned_no_limit:
            _warned_no_limit = True
            warnings.warn("the act timeout is not enforced here: it needs the main thread of a POSIX process",
                          RuntimeWarning, stacklevel=4)
        yield
        return
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds, _REPEAT_S)
    _pause.armed = True
    try:
        yield
    finally:
        _pause.armed = False
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
