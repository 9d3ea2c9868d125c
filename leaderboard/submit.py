"""Evaluate a policy on a track's test seeds in a child process and store one row per seed.

The policy runs in a fresh loky child (no ``__main__`` guard needed) with an address-space limit
(``memory_mb``); the parent enforces the wall-time limit, is the only writer of the store and
commits each finished chunk at once, so an interruption loses at most the chunks in flight. A
policy that cannot be loaded is a user error (nothing stored); any other failure marks the
submission ``failed`` with a one-line reason and leaves every stored row as it was. Entries carry
the policy's fingerprint (:func:`policy_fingerprint`): the same one resumes, another is refused
unless ``replace``. Rows carry their cost (:mod:`wfbench.harness.budget`). ``docs/leaderboard.md``,
"Submitting" and "What identifies an entry".
"""

from __future__ import annotations

import functools
import getpass
import hashlib
import json
import math
import os
import signal
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from joblib.externals.loky.backend.context import get_context
from wfbench.leaderboard.rows import ROW_COLUMNS, Entry, NameTaken, scrub_paths
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.tracks import Track, get_track
from wfbench.policies import registry as _registry
from wfbench.policies import tuned as _tuned

from wfbench import __version__
from wfbench.core.paths import package_dir
from wfbench.harness.backends import check_backend, run_chunks, shutdown_pools
from wfbench.harness.budget import BUDGET_COLUMNS, machine_line, policy_budget
from wfbench.harness.guard import (
    DEFAULT_ACT_TIMEOUT_S,
    NOT_USER,
    PolicyError,
    PolicyLoadError,
    check_act_timeout,
    load_policy,
    one_line,
)
from wfbench.harness.runner import results_frame

DEFAULT_WALL_TIME_S = 3600.0
DEFAULT_MEMORY_MB = 8192
BUILTIN_ENTRIES = _registry.LINEUPS["leaderboard"]  # the entries seed_builtins makes (the registry's lineups)


class SubmitError(Exception):
    """The submission cannot start (unknown track or policy, name taken, bad limits): one line, exit 2."""


@dataclass(frozen=True)
class Outcome:
    submission: Entry
    status: str  # complete | failed
    reason: str  # one line; empty when complete
    new_rows: int
    stored_rows: int
    seconds: float
    trace: str = ""  # the failure's whole traceback, formatted in the child (for --traceback)
    action: str = "resumed"  # new | resumed | replaced | legacy (Store.open_submission)
    # CPU seconds of this run's episodes per scenario ("" on a single-scenario track), as the rows report them
    scenario_seconds: dict[str, float] = field(default_factory=dict)


# -- fingerprints ----------------------------------------------------------------------------------------------


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
                c: _file_digest(spec, _tuned.TUNED_DIR / _registry.TUNED[c][0]) if c in _registry.TUNED
                else _file_digest(spec, _registry.CHECKPOINT_DIR / _registry.LEARNED[c][0]) if c in _registry.LEARNED
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




def _where(exc: BaseException) -> str:
    tb = traceback.extract_tb(exc.__traceback__)
    return f" (at {tb[-1].filename}:{tb[-1].lineno})" if tb else ""


def _child(conn, policy_spec: str, configs, backend, workers, address, chunk_size, memory_mb,
           act_timeout_s) -> None:
    """Runs in the child process: load the policy, then stream finished rows to the parent.

    Messages to the parent: ``("note", text)``, ``("load_error", line, trace)``,
    ``("ready", fingerprint, detail, budget)`` (the first two ``None`` unless the policy is an
    entry point; ``budget``, :func:`wfbench.harness.budget.policy_budget`),
    ``("rows", rows)``, ``("done",)``, ``("error", line, trace)``; from the parent, after
    ready: ``("run", units)`` (the (scenario, seed) pairs to evaluate, scenario a key of
    ``configs``: ``""`` on a one-scenario track) or ``("stop",)``. The child leads its own
    process group, so the parent can stop it together with any worker processes it started.
    """
    try:
        os.setsid()
    except OSError:  # already a group leader
        pass
    if memory_mb:
        try:
            import resource  # POSIX only: on other platforms the limit is reported as not applied

            limit = int(memory_mb) * 1024 * 1024
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        except (ImportError, ValueError, OSError) as exc:  # not on this platform: say so, run unlimited
            conn.send(("note", f"memory limit not applied: {exc}"))
    try:
        loaded = load_policy(policy_spec, act_timeout_s)
    except PolicyLoadError as exc:
        conn.send(("load_error", f"cannot load policy {policy_spec!r}: {exc}", ""))
        return
    except PolicyError as exc:
        conn.send(("load_error", exc.message, exc.trace))
        return
    except BaseException as exc:  # noqa: BLE001 - anything the user's import raises is a load error
        conn.send(("load_error", f"cannot load policy {policy_spec!r}: {one_line(exc)}{_where(exc)}",
                   traceback.format_exc()))
        return
    if loaded.guard is not None and getattr(loaded.policy, "reads_trace", False):
        conn.send(("load_error", f"policy {policy_spec!r} declares reads_trace = True: it reads the episode's "
                   "future, and the leaderboard ranks deployable policies only (its 'not deployable' section "
                   "holds wfbench's own oracles); compare it with 'wfbench compare' instead", ""))
        return
    fingerprint = detail = None
    if is_entry_point(policy_spec):
        try:
            fingerprint, detail = policy_fingerprint(policy_spec, loaded.policy)
        except SubmitError as exc:
            conn.send(("load_error", str(exc), ""))
            return
        except Exception as exc:  # noqa: BLE001 - the policy's params() raised
            conn.send(("load_error", f"policy {policy_spec!r}: its params() raised {one_line(exc)}{_where(exc)}",
                       traceback.format_exc()))
            return
    try:
        budget = policy_budget(policy_spec, loaded.policy)
    except (OSError, ValueError) as exc:  # a checkpoint or tuned file that went away since it loaded
        budget = {"kind": "other", "error": one_line(exc)}
    conn.send(("ready", fingerprint, detail, budget))
    msg = conn.recv()
    if msg[0] != "run":
        return
    by_scenario: dict[str, list[int]] = {}
    for scenario, seed in msg[1]:
        by_scenario.setdefault(scenario, []).append(seed)
    try:
        for scenario, seeds in by_scenario.items():
            config = configs[scenario]
            for batch in run_chunks(loaded, config, seeds, backend=backend, workers=workers, address=address,
                                    chunk_size=chunk_size, threads=1 if backend == "serial" else None):
                frame = results_frame([batch], config, policy_spec)[["seed", *ROW_COLUMNS, *BUDGET_COLUMNS]]
                where = machine_line({**batch.machine, "backend": backend,
                                      "workers": 1 if backend == "serial" else workers or os.cpu_count() or 1})
                conn.send(("rows", [{**row, "machine": where, "scenario": scenario}
                                    for row in frame.to_dict("records")]))
        shutdown_pools()  # before saying done: the parent may stop this process right after
        conn.send(("done",))
    except PolicyError as exc:
        shutdown_pools(kill_workers=True)  # the other chunks' results would not be stored
        conn.send(("error", exc.message, exc.trace))
    except MemoryError:
        conn.send(("error", f"the policy ran out of memory (limit {memory_mb} MiB)", traceback.format_exc()))
    except BaseException as exc:  # noqa: BLE001 - report any failure of the evaluation
        shutdown_pools(kill_workers=True)
        conn.send(("error", f"{one_line(exc)}{_where(exc)}", traceback.format_exc()))


class RemainingTime:
    """An honest estimate of the time left over episodes of unequal cost (a suite track's scenarios).

    An episode of ``city`` costs a hundred of ``small``, so a count of episodes done says little
    about the time left. The cost of a scenario's episode is measured (the mean CPU seconds its
    finished rows report); a scenario not started yet is estimated from its size (slots times
    horizon) at the cost per unit of size measured on the scenarios that have finished
    episodes. The wall seconds per unit of cost (which folds in the workers running side by
    side) come from what finished since :meth:`start`. Before the first rows there is no
    estimate (``None``), never a guess.

    Args:
        units: every (scenario, seed) the entry needs.
        configs: each scenario's config (``Track.configs()``).
        done: the units already stored (a resumed entry).
    """

    def __init__(self, units: list[tuple[str, int]], configs: dict[str, Any], done: set[tuple[str, int]]):
        self.size = {sc: float((c.max_facilities + c.max_personnel) * c.horizon) for sc, c in configs.items()}
        self.left: dict[str, int] = {}
        for sc, seed in units:
            if (sc, seed) not in done:
                self.left[sc] = self.left.get(sc, 0) + 1
        self.finished: dict[str, int] = {}
        self.cpu: dict[str, list[float]] = {}
        self.t0 = time.monotonic()

    def add(self, rows: list[dict[str, Any]]) -> None:
        """Count finished rows and their measured CPU seconds."""
        for row in rows:
            sc = row.get("scenario", "")
            self.left[sc] = max(0, self.left.get(sc, 0) - 1)
            self.finished[sc] = self.finished.get(sc, 0) + 1
            cpu = row.get("cpu_s")
            if cpu is not None and math.isfinite(cpu):
                self.cpu.setdefault(sc, []).append(float(cpu))

    def cost(self, scenario: str) -> float | None:
        """The estimated CPU seconds of one episode of ``scenario`` (None before any measurement)."""
        if self.cpu.get(scenario):
            return sum(self.cpu[scenario]) / len(self.cpu[scenario])
        measured = [sc for sc in self.cpu if self.cpu[sc]]
        if not measured:
            return None
        per_size = sum(self.cost(sc) for sc in measured) / sum(self.size[sc] for sc in measured)
        return per_size * self.size[scenario]

    def seconds_left(self) -> float | None:
        """Wall seconds until every unit is done, at the pace since the episodes started."""
        costs = {sc: self.cost(sc) for sc in self.size}
        if any(c is None for c in costs.values()):
            return None
        done_work = sum(n * costs[sc] for sc, n in self.finished.items())
        if done_work <= 0:
            return None
        left_work = sum(n * costs[sc] for sc, n in self.left.items())
        return (time.monotonic() - self.t0) * left_work / done_work

    def per_scenario(self) -> dict[str, float]:
        """CPU seconds of the finished episodes, per scenario."""
        return {sc: float(sum(v)) for sc, v in self.cpu.items()}


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.0f} min" if seconds < 5400 \
        else f"{seconds / 3600:.1f} h"


def submit(track: str | Track, policy: str, name: str, submitter: str | None = None, db: Any = None,
           backend: str = "process", workers: int | None = None, address: str | None = None,
           wall_time_s: float = DEFAULT_WALL_TIME_S, memory_mb: int | None = DEFAULT_MEMORY_MB,
           chunk_size: int | None = None, progress: bool = False, builtin: bool = False,
           act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S, replace: bool = False) -> Outcome:
    """Evaluate ``policy`` (a registry name or ``module:attr``) on the track's test seeds and store the rows.

    The policy runs on every scenario of the track, one row per (scenario, seed).

    Args:
        track: a track name or :class:`~wfbench.leaderboard.tracks.Track`.
        policy: a registry name or a ``module:attr`` entry point.
        name: the entry's name on the track; submitting it again resumes.
        submitter: who submits (default: the user name).
        db: a store path or :class:`~wfbench.leaderboard.store.Store` (default: the user's store).
        backend: where the child runs the episodes (:mod:`wfbench.harness.backends`).
        workers: processes or Ray tasks of the child.
        address: Ray cluster address.
        wall_time_s: the whole evaluation's limit in seconds.
        memory_mb: the child's address-space limit in MiB (``None``: none).
        chunk_size: seeds per stored chunk (default 5).
        progress: show a progress bar.
        builtin: mark the entry as one of wfbench's own.
        act_timeout_s: limit of each ``reset``/``act`` call of a user's policy in
            seconds; ``None`` or 0 for none.
        replace: when the name is taken, move its entry to the audit tables and
            evaluate every seed anew (whatever the fingerprints).

    Returns:
        The outcome: ``complete``, or ``failed`` with a one-line reason and its trace.

    Raises:
        SubmitError: the submission cannot start (unknown track or policy, a policy that
            cannot be loaded, a name taken by another fingerprint without ``replace``,
            bad limits); nothing is stored.
    """
    try:
        tr = track if isinstance(track, Track) else get_track(track)
        check_backend(backend, address)
        act_timeout_s = check_act_timeout(act_timeout_s)
    except ValueError as exc:
        raise SubmitError(str(exc)) from None
    if not isinstance(policy, str) or not policy:
        raise SubmitError("--policy must be a registry name or a module:attr entry point")
    if not (wall_time_s > 0):
        raise SubmitError(f"wall time {wall_time_s!r} is not allowed; allowed: seconds > 0")
    if memory_mb is not None and memory_mb < 256:
        raise SubmitError(f"memory limit {memory_mb} MiB is not allowed; allowed: >= 256 MiB")
    if ":" not in policy:  # a registry name or composite: check it here, no user code runs
        try:
            load_policy(policy)
        except PolicyLoadError as exc:
            raise SubmitError(str(exc)) from None
    submitter = submitter or getpass.getuser()
    fingerprint, detail = (None, None) if is_entry_point(policy) else policy_fingerprint(policy)
    store = db if isinstance(db, Store) else Store(db)
    t0 = time.perf_counter()
    existing = store.find(tr.name, name)
    if existing is not None and fingerprint is not None and not replace and not existing.legacy:
        _check_taken(existing, tr, name, policy, fingerprint, detail)  # no child needed to refuse
        done = store.done_units(existing.id)
        if all(u in done for u in tr.units()):  # nothing to evaluate, and no user code to load
            if existing.status != "complete":
                store.set_status(existing.id, "complete", "")
            sub = store.find(tr.name, name)
            return Outcome(sub, "complete", "", 0, len(done), time.perf_counter() - t0)  # type: ignore[arg-type]
    chunk = chunk_size or 5
    # loky's process: a fresh interpreter that does not re-import __main__ (multiprocessing's
    # spawn would run a guard-less calling script again in the child)
    ctx = get_context("loky")
    parent_conn, child_conn = ctx.Pipe(duplex=True)
    proc = ctx.Process(target=_child, args=(child_conn, policy, tr.configs(), backend, workers, address,
                                            chunk, memory_mb, act_timeout_s), daemon=False)
    proc.start()
    child_conn.close()
    done: set[tuple[str, int]] = set()
    units = tr.units()
    action = "resumed"
    bar = None
    clock: RemainingTime | None = None
    sub: Entry | None = None
    new_rows = 0
    status, reason, trace = "failed", "", ""
    child_ends = False  # the child said done or error and exits by itself
    deadline = time.monotonic() + wall_time_s
    try:
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                reason = (f"exceeded the wall-time limit of {wall_time_s:g} s after "
                          f"{len(done) + new_rows} of {len(units)} {tr.unit_word}")
                break
            if parent_conn.poll(min(remaining, 0.25)):
                try:
                    msg = parent_conn.recv()
                except EOFError:
                    msg = None
                if msg is None:
                    proc.join(5)
                    reason = _death_reason(proc.exitcode, memory_mb)
                    break
                kind = msg[0]
                if kind == "load_error":
                    raise SubmitError(msg[1])
                if kind == "ready":
                    if fingerprint is None:
                        fingerprint, detail = msg[1], msg[2]
                    try:
                        sub, action = store.open_submission(
                            tr, name, policy, submitter, __version__, builtin=builtin, fingerprint=fingerprint,
                            fingerprint_detail=json.dumps(detail, sort_keys=True), replace=replace,
                            budget=json.dumps(msg[3], sort_keys=True))
                    except NameTaken as exc:
                        _check_taken(exc.existing, tr, name, policy, fingerprint, detail)
                        raise
                    done = store.done_units(sub.id)
                    missing = [u for u in units if u not in done]
                    if not missing:
                        parent_conn.send(("stop",))
                        status, child_ends = "complete", True
                        break
                    parent_conn.send(("run", missing))
                    clock = RemainingTime(units, tr.configs(), done)
                    if progress:
                        from tqdm.auto import tqdm

                        # tqdm's own rate assumes episodes of equal cost: the estimate is RemainingTime's
                        bar = tqdm(total=len(units), initial=len(done), desc=f"{name} on {tr.name}",
                                   unit="episode", leave=False,
                                   bar_format="{desc}: {percentage:3.0f}%|{bar}| {n}/{total} episodes "
                                              "[{elapsed}{postfix}]")
                        bar.set_postfix_str("time left: after the first episodes", refresh=True)
                elif kind == "rows":
                    assert sub is not None
                    new_rows += store.add_results(sub, __version__, msg[1])
                    if clock is not None:
                        clock.add(msg[1])
                    if bar:
                        left = clock.seconds_left() if clock is not None else None
                        bar.set_postfix_str("time left: " + ("after the first episodes of each size" if left is None
                                                             else f"about {_duration(left)}"), refresh=False)
                        bar.update(len(msg[1]))
                elif kind == "done":
                    status, child_ends = "complete", True
                    break
                elif kind == "error":
                    reason, trace, child_ends = msg[1], msg[2], True
                    break
            elif not proc.is_alive():
                if parent_conn.poll():
                    continue  # drain what it sent before dying
                reason = _death_reason(proc.exitcode, memory_mb)
                break
    finally:
        if bar:
            bar.close()
        if child_ends:
            proc.join(30)  # it has shut its workers down; let it exit cleanly
        _stop(proc)
        parent_conn.close()
    if sub is None:  # the child died before loading the policy
        raise SubmitError(f"the evaluation of {policy!r} could not start: {reason}")
    stored = len(store.done_units(sub.id))
    if status == "complete" and stored < len(units):
        status, reason = "failed", f"only {stored} of {len(units)} {tr.unit_word} were stored"
    # the board shows the stored reason: no absolute path of the submitter's machine (the caller gets it whole)
    store.set_status(sub.id, status, scrub_paths(reason, os.getcwd()))
    return Outcome(store.find(tr.name, name), status, reason, new_rows, stored,  # type: ignore[arg-type]
                   time.perf_counter() - t0, trace, action,
                   clock.per_scenario() if clock is not None else {})


def _check_taken(existing: Entry, tr: Track, name: str, policy: str, fingerprint: str,
                 detail: dict[str, Any] | None) -> None:
    """Raise the one-line SubmitError when ``name`` is taken by another fingerprint or track version."""
    how = ("pass --replace to evaluate this policy under that name (the old entry's rows are kept in the store's "
           "audit tables) or choose another --name")
    if existing.fingerprint != fingerprint:
        change = fingerprint_change(existing.fingerprint_detail, detail or {})
        raise SubmitError(f"the name {name!r} on track {tr.name} is taken by a different policy ({existing.policy!r}, "
                          f"fingerprint {existing.fingerprint}; now {policy!r}, fingerprint {fingerprint}: {change}); "
                          f"{how}")
    if existing.track_hash != tr.hash:
        raise SubmitError(f"the entry {name!r} was made on another version of track {tr.name} (hash "
                          f"{existing.track_hash}, now {tr.hash}); {how}")


def _stop(proc) -> None:
    """Kill the child's whole process group (it and any workers it started), then reap it."""
    if proc.pid is not None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    proc.join(10)


def _death_reason(exitcode: int | None, memory_mb: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            sig = signal.Signals(-exitcode).name
        except ValueError:
            sig = str(-exitcode)
        hint = f"; out of memory? (limit {memory_mb} MiB)" if sig == "SIGKILL" else ""
        return f"the evaluation process was killed by {sig}{hint}"
    return f"the evaluation process exited unexpectedly (exit code {exitcode})"


def scenario_times(out: Outcome) -> str:
    """One line: the CPU seconds this run spent per scenario, costliest first ("" on a single-scenario track)."""
    times = {sc: t for sc, t in out.scenario_seconds.items() if sc}
    if not times:
        return ""
    parts = ", ".join(f"{sc} {t:.3g}" for sc, t in sorted(times.items(), key=lambda kv: (-kv[1], kv[0])))
    return f"CPU seconds per scenario (this run's episodes, costliest first): {parts}"


def seed_tracks(track: str | Track | None = None) -> list[Track]:
    """The tracks ``wfbench leaderboard seed`` fills: the one named, or every track marked ``seeded``.

    A track that runs a whole suite is not marked (:func:`~wfbench.leaderboard.tracks.suite_track`): named only.
    """
    from wfbench.leaderboard.tracks import TRACKS

    if track is not None:
        return [track if isinstance(track, Track) else get_track(track)]
    return [t for t in TRACKS.values() if t.seeded]


MOVED = {"replaced": "; the entry it replaced is in the audit tables",
         "legacy": "; its rows stored without a fingerprint (an older wfbench) are in the audit tables"}
"""What :func:`describe` adds for a submission that moved an entry to the audit tables, by ``Outcome.action``."""


def describe(out: Outcome, track: Track, store_path: Any, hint: str = "") -> str:
    """The line ``wfbench leaderboard submit`` prints for a submission's outcome.

    A complete one says how many rows it stored and, where it replaced an entry or a
    legacy one, that the old rows are in the audit tables (:data:`MOVED`); a failed one
    says why and that its rows are kept for a resume. ``hint`` ends the failure's note.
    """
    what = track.unit_word
    name = out.submission.name
    if out.status == "complete":
        return (f"{name} on {track.name}: complete, {out.stored_rows} {what} stored ({out.new_rows} new) "
                f"in {store_path}, {out.seconds:.1f} s{MOVED.get(out.action, '')}")
    return (f"submission {name!r} on {track.name} failed: {out.reason} ({out.stored_rows} {what} kept in "
            f"{store_path}; submit again to resume, or with --replace once the policy is changed{hint})")


def seed_builtins(track: str | Track, db: Any = None, names: tuple[str, ...] = BUILTIN_ENTRIES,
                  progress: bool = False, **kwargs: Any) -> list[Outcome]:
    """Submit (or resume) the built-in policies under their registry names.

    A built-in entry whose fingerprint is not the current code's (wfbench's policy code
    changed since it was stored) is replaced: its rows go to the audit tables.
    """
    tr = track if isinstance(track, Track) else get_track(track)
    store = db if isinstance(db, Store) else Store(db)
    out = []
    for n in names:
        existing = store.find(tr.name, n)
        stale = existing is not None and not existing.legacy and (
            existing.fingerprint != policy_fingerprint(n)[0] or existing.track_hash != tr.hash)
        out.append(submit(tr, n, n, submitter="wfbench", db=store, builtin=True, progress=progress, replace=stale,
                          **kwargs))
    return out
