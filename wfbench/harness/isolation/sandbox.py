"""Running someone else's policy package in a bubblewrap sandbox, as an ordinary policy of the evaluator.

:class:`SandboxPolicy` starts ``python -m wfbench.harness.isolation.child`` in bubblewrap and
speaks to it over two pipes (:mod:`wfbench.harness.isolation.wire`, never pickle); the simulator
stays in the evaluator, and the policy sees observations and :func:`opaque_keys` (HMAC-SHA256 of
the seed), never the seeds. The sandbox: read-only binds of what Python needs on a read-only
root, a capped tmpfs ``/tmp`` (the one place it can write), its own namespaces (no network),
its own uid as root, rlimits, a seccomp filter, clocks kept outside, a cleared environment.
:class:`SandboxUnavailable` is the set-up's fault (before STARTED), :class:`SandboxError` the
policy's. :func:`evaluate_sandboxed`; :func:`check_sandbox`.
The rules and why: ``docs/leaderboard.md``, "The threat model".
"""

from __future__ import annotations

import hashlib
import hmac
import json
import math
import os
import secrets
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import weakref
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from functools import cache
from importlib.util import find_spec
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wfbench.core.actions import ActionError
from wfbench.core.config import ScenarioConfig
from wfbench.core.simulator import Simulator
from wfbench.harness.guard import Guard, LoadedPolicy, PolicyError
from wfbench.harness.isolation.child import PROBE_OK, cache_folder
from wfbench.harness.isolation.wire import Decoder, Kind, Message, WireError, WireLimits, array_text, encode, text_array

# the policy's user when the evaluator runs as root: one drawn per sandbox from a range no account uses, so that
# the process limit (counted per user) is each sandbox's own and sandboxes cannot signal one another
SANDBOX_UIDS = range(1_000_000, 2_000_000)
PACKAGES = ("wfbench", "wfbench.policies", "wfbench.solvers", "wfbench.leaderboard")  # imported from their folders
INSTALL_HINT = "install it with `apt-get install bubblewrap` (Debian/Ubuntu; `dnf install bubblewrap` on Fedora)"
# the key secret of local runs (``wfbench evaluate --sandbox``), public on purpose: a local run hides no seed, and
# anyone can reproduce its keys; a hosted board keeps its own secret in its database
LOCAL_KEY_SECRET = b"wfbench-local-sandbox-v1"
LOCAL_KEY_CONTEXT = "local"
WARMUP_S = 300.0  # the default warm-up allowance of a sandbox's first reset and first act (Limits.warmup_s): a
# cold compile of the kernels a built-in needs took over 60 s on the loaded 2-core VM (issue #42)
CACHE_MOUNT = "/wfbench-numba"  # the evaluator's numba cache of each wfbench folder, read-only, at CACHE_MOUNT/<i>
_FROM_CHILD = WireLimits(max_bytes=64 << 20)  # an action is a few arrays of (B, M)
# bubblewrap's own environment: nothing of the evaluator's (a database URL, tokens) reaches it, whoever runs it; in a
# user namespace bubblewrap is the sandbox's PID 1, whose /proc/1/environ the policy can read
BWRAP_ENV = {"PATH": "/usr/local/bin:/usr/bin:/bin"}
# the Pythons that may hold libseccomp's own bindings (Debian's python3-seccomp installs them for /usr/bin/python3)
SECCOMP_PYTHONS = (sys.executable, "/usr/bin/python3")
SECCOMP_HINT = "install them with `apt-get install python3-seccomp` (Debian/Ubuntu; `dnf install python3-libseccomp` " \
               "on Fedora)"
_READ = 1 << 16


class SandboxUnavailable(RuntimeError):
    """The board's set-up, not the policy, failed: no sandbox starts here, or this one did not reach its handshake.

    ``reason`` (and ``str()``) is one line naming the cause and, where there is one, the fix:
    bubblewrap missing or refused, Python or wfbench unreachable inside, no seccomp bindings,
    a sandbox that exited or hung before the child's handshake (before any of the package's
    code ran). A worker retries the job elsewhere or later; it is never the policy's result.
    """

    def __init__(self, reason: str):
        lines = str(reason).strip().splitlines()
        super().__init__(lines[0] if lines else "the sandbox is not available")

    @property
    def reason(self) -> str:
        return str(self)


class SandboxError(PolicyError):
    """The sandboxed policy failed or broke a limit: ``reason`` is one line, ``log`` its captured output."""

    def __init__(self, reason: str, trace: str = "", log: str = ""):
        super().__init__(reason, trace)
        self.log = log

    @property
    def reason(self) -> str:
        return self.message


@dataclass(frozen=True)
class Limits:
    """What a sandboxed policy may use; the defaults are a hosted board's."""

    memory_mb: int = 4096  # address space of the policy's process (RLIMIT_AS)
    cpu_s: int = 3600  # CPU seconds of the process over its life (RLIMIT_CPU)
    processes: int = 64  # processes and threads of the sandbox's user (RLIMIT_NPROC)
    file_mb: int = 16  # the largest file it may write (RLIMIT_FSIZE)
    tmp_mb: int = 64  # the policy's room in its /tmp (a tmpfs)
    numba_cache_mb: int = 64  # more room in /tmp for the copies of the evaluator's compiled wfbench kernels
    act_timeout_s: float = 10.0  # each reset and act call after the first of each
    # the first reset and the first act of a sandbox (numba compiling the policy's kernels); None: the larger of
    # WARMUP_S and act_timeout_s
    warmup_s: float | None = None
    wall_time_s: float = 1800.0  # the policy's time over one batch of episodes (reset and every act)
    log_bytes: int = 1 << 20  # what it may write to stdout and stderr together
    open_files: int = 256  # open file descriptors (RLIMIT_NOFILE)
    start_timeout_s: float = 60.0  # starting Python and loading the package

    def __post_init__(self) -> None:
        if self.warmup_s is None:
            act = self.act_timeout_s
            object.__setattr__(self, "warmup_s", max(WARMUP_S, act) if isinstance(act, (int, float)) else WARMUP_S)
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value <= 0:
                raise ValueError(f"sandbox limit {f.name} = {value!r} is not allowed; allowed: a number > 0")
        if self.warmup_s < self.act_timeout_s:
            raise ValueError(f"sandbox limit warmup_s = {self.warmup_s!r} is below act_timeout_s = "
                             f"{self.act_timeout_s!r}; allowed: warmup_s >= act_timeout_s (it is the first call's "
                             "act timeout)")

    def rlimits(self) -> dict[str, int]:
        """The resource limits the child sets on itself (``resource.RLIMIT_<name>``)."""
        return {"CORE": 0, "AS": int(self.memory_mb) << 20, "CPU": math.ceil(self.cpu_s),
                "NPROC": int(self.processes), "FSIZE": int(self.file_mb) << 20, "NOFILE": int(self.open_files)}


def opaque_keys(seeds: Sequence[int], key_secret: bytes, key_context: str) -> np.ndarray:
    """The key of each seed: the first 8 bytes of HMAC-SHA256(secret, "context:seed"), as an int64 >= 0."""
    keys = [int.from_bytes(hmac.new(key_secret, f"{key_context}:{int(s)}".encode(), hashlib.sha256).digest()[:8],
                           "big") & (2**63 - 1) for s in seeds]
    return np.array(keys, dtype=np.int64)


# -- is there a sandbox here ---------------------------------------------------------------------------------------


def check_sandbox() -> None:
    """Raise :class:`SandboxUnavailable` (one line: the cause, and how to fix it) unless a sandbox runs here.

    Beyond bubblewrap and the namespaces it starts a real sandbox once per process, with
    its seccomp filter, and imports wfbench in its Python (:func:`_trial`).
    """
    if not shutil.which("bwrap"):
        raise SandboxUnavailable(f"bubblewrap (bwrap) is not installed; the sandbox needs it to run submitted "
                                 f"policies: {INSTALL_HINT}")
    if os.geteuid() == 0 and not shutil.which("setpriv"):
        raise SandboxUnavailable("setpriv is not installed (it drops the sandbox to an unprivileged user when run "
                                 "as root): install util-linux")
    if os.geteuid() != 0:
        for knob, fix in (("/proc/sys/kernel/unprivileged_userns_clone",
                           "sysctl -w kernel.unprivileged_userns_clone=1"),
                          ("/proc/sys/user/max_user_namespaces", "sysctl -w user.max_user_namespaces=10000")):
            try:
                disabled = Path(knob).read_text().strip() == "0"
            except OSError:
                continue
            if disabled:
                raise SandboxUnavailable(f"user namespaces are disabled ({knob} is 0); bubblewrap needs them to "
                                         f"sandbox policies without root: `{fix}` as root, or run as root")
    _trial()


@cache
def _trial() -> None:
    """Start the real sandbox once per process and import wfbench in its Python (the child's ``probe``).

    It runs what a submission runs (the same mounts, user, limits and seccomp filter) on an
    empty package, so AppArmor, a container, a Python the mounts miss or a broken install
    are found here, at start, and not by blaming the first policy.
    """
    with tempfile.TemporaryDirectory(prefix="wfbench-probe-") as tmp:
        package = Path(tmp) / "package"
        package.mkdir()
        package.chmod(0o755)
        filt = _seccomp_fd()
        try:
            cmd = sandbox_command(package, {"probe": True, "rlimits": Limits().rlimits()}, Limits(),
                                  SANDBOX_UIDS[0] if os.geteuid() == 0 else os.geteuid(), (), filt)
            try:
                r = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=dict(BWRAP_ENV),
                                   stdin=subprocess.DEVNULL, pass_fds=(filt,))
            except subprocess.TimeoutExpired:
                raise SandboxUnavailable("the sandbox's Python did not start within 120 s (the probe that imports "
                                         "wfbench inside)") from None
        finally:
            os.close(filt)
    if r.returncode == 0 and PROBE_OK in r.stdout:
        return
    lines = [x.strip() for x in (r.stderr + r.stdout).strip().splitlines() if x.strip()]
    line = lines[-1] if lines else f"exit code {r.returncode}"
    interpreter = _interpreter()
    if r.returncode == 127 or "execvp" in line or "failed to execute" in line:
        raise SandboxUnavailable(f"Python cannot start in the sandbox ({line}): {interpreter} or a library it loads "
                                 "is not among the sandbox's read-only mounts")
    if line.startswith("bwrap:"):
        raise SandboxUnavailable(f"bubblewrap cannot create a sandbox here ({line}); user namespaces may be "
                                 "disabled or forbidden (AppArmor, a container without them)")
    raise SandboxUnavailable(f"the sandbox's Python cannot import wfbench ({line}; exit code {r.returncode}): "
                             f"{interpreter} inside the sandbox does not see the installation it runs from")


# -- the bubblewrap command ---------------------------------------------------------------------------------------


def _namespaces() -> list[str]:
    if os.geteuid() == 0:  # privileged bwrap; a user namespace would map the sandbox to the host's root
        return ["--unshare-ipc", "--unshare-pid", "--unshare-net", "--unshare-uts", "--unshare-cgroup-try"]
    return ["--unshare-all"]


def _system_binds() -> list[str]:
    """/usr, the /bin and /lib folders (symlinks into /usr on merged systems) and the linker's configuration."""
    out = ["--ro-bind", "/usr", "/usr"]
    for top in ("/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32"):
        p = Path(top)
        if p.is_symlink():
            out += ["--symlink", os.readlink(p), top]
        elif p.is_dir():
            out += ["--ro-bind", top, top]
    for etc in ("/etc/ld.so.cache", "/etc/ld.so.conf", "/etc/ld.so.conf.d", "/etc/alternatives"):
        if Path(etc).exists():
            out += ["--ro-bind", etc, etc]
    return out


def _interpreter() -> str:
    """The Python the sandbox runs: this one, by the path it was started with, its folder's links resolved.

    Not the file the name finally points to: a virtual environment's ``python`` is a link,
    and Python finds its venv (``pyvenv.cfg``) beside the name it was started by.
    """
    exe = Path(sys.executable)
    return str(exe.parent.resolve() / exe.name)


def _libpython() -> Path | None:
    """The shared libpython this process runs on (None: a static build), from its memory map."""
    try:
        for line in Path("/proc/self/maps").read_text().splitlines():
            path = line.split(maxsplit=5)[-1]
            if path.startswith("/") and "/libpython" in path:
                return Path(path)
    except OSError:
        pass
    return None


def python_folders() -> list[Path]:
    """The folders the child's Python needs, read-only: the installation, the venv, the wfbench packages.

    - the interpreter's installation (``sys.base_prefix``), the venv (``sys.prefix``) and the
      folder the interpreter's file is in;
    - the folder of the libpython it loads, where that is elsewhere (its run path may name a
      folder the sandbox does not have: :func:`_child_env` points the loader at this one);
    - every ``site-packages`` or ``dist-packages`` folder on the import path (the installed
      dependencies, wherever a ``.pth`` file put them);
    - the folders the ``wfbench`` packages are imported from (an editable install maps
      ``wfbench.policies`` to the checkout's ``policies/``), never the checkout itself: it
      may hold results, the leaderboard's database or credentials.

    A folder inside another one is covered by it. Where they are does not matter: the sandbox
    mounts its ``/tmp`` before these, so a Python under ``/tmp`` stays visible.
    """
    exe = Path(_interpreter())
    found = [Path(sys.base_prefix), Path(sys.prefix), exe.parent, exe.resolve().parent.parent]
    lib = _libpython()
    if lib is not None:
        found.append(lib.parent)
    found += [Path(p) for p in sys.path if p and Path(p).name in ("site-packages", "dist-packages")]
    for name in PACKAGES:
        spec = find_spec(name)
        found += [Path(p) for p in ((spec and spec.submodule_search_locations) or [])]
    resolved = sorted({p.resolve() for p in found if p.is_dir()})
    return [p for p in resolved if not any(q != p and p.is_relative_to(q) for q in resolved)]


def _child_env() -> dict[str, str]:
    """The child's whole environment (bubblewrap clears the rest): paths inside the sandbox, one thread each."""
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": "/tmp", "NUMBA_CACHE_DIR": "/tmp/numba",
           "MPLCONFIGDIR": "/tmp", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1", "LANG": "C.UTF-8"}
    lib = _libpython()
    if lib is not None:  # a run path that names a folder the sandbox lacks (a relocated Python) is not consulted
        env["LD_LIBRARY_PATH"] = str(lib.parent.resolve())
    return env


def _ancestors(paths: Sequence[Path]) -> list[str]:
    """Every parent folder of the bind targets, created world-traversable (privileged bwrap makes them 0700)."""
    out = sorted({str(a) for p in paths for a in p.parents if str(a) not in ("/", "/tmp")},
                 key=lambda s: (s.count("/"), s))
    return [arg for a in out for arg in ("--perms", "0755", "--dir", a)]


@cache
def _compiled_sources() -> tuple[str, ...]:
    """One source file per folder of the wfbench packages with functions numba caches (``cache=True``)."""
    found: dict[Path, str] = {}
    for name in PACKAGES:
        spec = find_spec(name)
        for top in (spec and spec.submodule_search_locations) or []:
            for py in sorted(Path(top).resolve().rglob("*.py")):
                if py.parent not in found and b"cache=True" in py.read_bytes():
                    found[py.parent] = str(py)
    return tuple(found.values())


_host_cache_folder = cache(cache_folder)


def shared_caches() -> list[tuple[str, Path]]:
    """(a source file, the folder this process's numba caches its folder in) where that folder holds entries.

    What a sandbox mounts read-only for its child to copy from (:class:`wfbench.harness.isolation.child.CacheCopies`):
    this process's own cache, which only this process (or another trusted run of wfbench on the
    machine) writes, never a sandbox.
    """
    out = []
    for py_file in _compiled_sources():
        try:
            folder = _host_cache_folder(py_file)
            if folder is not None and any(n.endswith(".nbi") for n in os.listdir(folder)):
                out.append((py_file, Path(folder)))
        except OSError:
            continue
    return out


def sandbox_command(package_dir: Path, config: dict[str, Any], limits: Limits, uid: int,
                    caches: Sequence[tuple[str, Path]] = (), seccomp_fd: int | None = None) -> list[str]:
    """The bubblewrap command line that runs the child on ``package_dir`` with ``config``.

    ``caches``: (a source file, a numba cache folder) to mount read-only for the child to
    copy from (:func:`shared_caches`); ``config`` gets where each one is. ``seccomp_fd``: a
    descriptor bubblewrap reads the compiled seccomp filter from (:func:`_seccomp_fd`), loaded
    just before it starts the child (it must be passed to bubblewrap with ``pass_fds``).

    The order matters: bubblewrap applies its operations one by one, so the tmpfs at
    ``/tmp`` comes before every bind, or it would hide those under ``/tmp`` (a venv or a
    checkout there), and the root and ``/dev`` are remounted read-only after the last
    bind, leaving ``/tmp`` the one writable folder. The child runs isolated (``-I``: no
    ``PYTHON*`` variables, no user site, not the current folder on its path): the package
    joins the path only once the child has imported what it needs and told the evaluator it
    started.
    """
    folders = python_folders()
    mounts = [f"{CACHE_MOUNT}/{i}" for i in range(len(caches))]
    config = {**config, "numba_cache": [[py_file, m] for (py_file, _), m in zip(caches, mounts, strict=True)],
              "numba_cache_bytes": int(limits.numba_cache_mb) << 20}
    cmd = [shutil.which("bwrap") or "bwrap", *_namespaces(), "--die-with-parent", "--new-session", "--clearenv"]
    for k, v in _child_env().items():
        cmd += ["--setenv", k, v]
    cmd += _system_binds()
    tmp_bytes = (int(limits.tmp_mb) + int(limits.numba_cache_mb)) << 20
    cmd += ["--perms", "1777", "--size", str(tmp_bytes), "--tmpfs", "/tmp"]
    cmd += _ancestors([*folders, Path("/policy"), *map(Path, mounts)])
    for f in folders:
        cmd += ["--ro-bind", str(f), str(f)]
    for (_, folder), m in zip(caches, mounts, strict=True):
        cmd += ["--ro-bind", str(folder), m]
    cmd += ["--ro-bind", str(package_dir), "/policy", "--proc", "/proc", "--dev", "/dev", "--chdir", "/policy"]
    # the skeleton bubblewrap made for the binds (its root, the binds' parent folders, /dev) is a tmpfs with no size
    # cap that RLIMIT_AS does not count; under a non-root worker it belongs to the policy's own uid: read-only, so
    # that the capped /tmp is the one place the policy can write, root or not (issue #55)
    cmd += ["--remount-ro", "/dev", "--remount-ro", "/"]
    if seccomp_fd is not None:
        cmd += ["--seccomp", str(seccomp_fd)]
    if os.geteuid() == 0:  # the child drops to ``uid``, with no capability left in any set
        cmd += ["--cap-add", "CAP_SETUID", "--cap-add", "CAP_SETGID", "--cap-add", "CAP_SETPCAP", "--",
                "setpriv", "--reuid", str(uid), "--regid", str(uid), "--clear-groups",
                "--inh-caps=-all", "--bounding-set=-all"]
    cmd += ["--", _interpreter(), "-I", "-B", "-u", "-m", "wfbench.harness.isolation.child", json.dumps(config)]
    return cmd


# -- the seccomp filter ---------------------------------------------------------------------------------------------

# refused with EPERM: debugging other processes, mounting, namespaces, the kernel's programmable and keyring corners,
# and System V shared memory (a segment outlives its mapping, so RLIMIT_AS would not count it)
SECCOMP_DENY = ("ptrace", "process_vm_readv", "process_vm_writev", "mount", "umount2", "pivot_root",
                "fsopen", "fsconfig", "fsmount", "fspick", "move_mount", "open_tree", "mount_setattr",
                "unshare", "setns", "bpf", "perf_event_open", "keyctl", "add_key", "request_key", "userfaultfd",
                "io_uring_setup", "io_uring_enter", "io_uring_register", "kexec_load", "kexec_file_load",
                "init_module", "finit_module", "delete_module", "open_by_handle_at", "shmget")
# clone with any of these flags (a new namespace) is refused; clone3 passes its flags in memory the filter cannot
# read, so it answers ENOSYS, on which the C library falls back to clone
CLONE_NEW_FLAGS = (0x00020000, 0x02000000, 0x04000000, 0x08000000, 0x10000000, 0x20000000, 0x40000000)
_SECCOMP_SCRIPT = """
import errno, os, sys
import seccomp
deny, flags = sys.argv[1].split(","), [int(x) for x in sys.argv[2].split(",")]
f = seccomp.SyscallFilter(seccomp.ALLOW)
for name in deny:
    f.add_rule(seccomp.ERRNO(errno.EPERM), name)
for flag in flags:
    f.add_rule(seccomp.ERRNO(errno.EPERM), "clone", seccomp.Arg(0, seccomp.MASKED_EQ, flag, flag))
f.add_rule(seccomp.ERRNO(errno.ENOSYS), "clone3")
with os.fdopen(1, "wb", closefd=False) as out:
    f.export_bpf(out)
"""


@cache
def _seccomp_program() -> bytes:
    """The sandbox's seccomp filter as a BPF program, compiled by libseccomp's own Python bindings, once.

    The bindings are a C extension of one Python build (Debian's ``python3-seccomp`` serves
    ``/usr/bin/python3``), so the filter is compiled in a separate process by the first of
    :data:`SECCOMP_PYTHONS` that has them, whatever Python runs wfbench. Without them no
    sandbox starts: :class:`SandboxUnavailable`, never a sandbox without its filter.
    """
    tried = []
    for python in dict.fromkeys(SECCOMP_PYTHONS):
        try:
            r = subprocess.run([python, "-I", "-c", _SECCOMP_SCRIPT, ",".join(SECCOMP_DENY),
                                ",".join(map(str, CLONE_NEW_FLAGS))], capture_output=True, timeout=60,
                               env=dict(BWRAP_ENV), stdin=subprocess.DEVNULL)
        except (OSError, subprocess.TimeoutExpired) as exc:
            tried.append(f"{python}: {type(exc).__name__}")
            continue
        if r.returncode == 0 and r.stdout and len(r.stdout) % 8 == 0:
            return r.stdout
        last = (r.stderr.decode("utf-8", "replace").strip().splitlines() or [f"exit code {r.returncode}"])[-1]
        tried.append(f"{python}: {last}")
    raise SandboxUnavailable(f"libseccomp's Python bindings (the module seccomp) are not available to "
                             f"{' or '.join(dict.fromkeys(SECCOMP_PYTHONS))} ({'; '.join(tried)}); the sandbox "
                             f"does not run without its seccomp filter: {SECCOMP_HINT}")


def _seccomp_fd() -> int:
    """A pipe's read end holding the filter (:func:`_seccomp_program`), for bubblewrap's ``--seccomp``; close it."""
    program = _seccomp_program()
    r, w = os.pipe()
    try:
        view = memoryview(program)
        while view:  # a few hundred bytes: far below a pipe's buffer
            view = view[os.write(w, view):]
    except BaseException:
        os.close(r)
        raise
    finally:
        os.close(w)
    return r


def _check_readable(package_dir: Path) -> None:
    """As root the policy runs as a user of its own, who must be able to read the package (``unpack`` sees to it)."""
    if os.geteuid() != 0:
        return
    for p in [package_dir, *package_dir.rglob("*")]:
        need = 0o005 if p.is_dir() else 0o004
        if p.stat().st_mode & need != need:
            raise ValueError(f"the package folder {package_dir} is not readable by the sandbox's user: {p} has "
                             f"mode {oct(p.stat().st_mode & 0o777)}; allowed: readable by "
                             f"all (chmod -R a+rX {package_dir})")


# -- the sandboxed policy ------------------------------------------------------------------------------------------


def _children(pid: int) -> list[int]:
    """The pids of ``pid``'s children (of every thread of it), from ``/proc``; [] once it is gone."""
    try:
        return [int(c) for task in os.listdir(f"/proc/{pid}/task")
                for c in Path(f"/proc/{pid}/task/{task}/children").read_text().split()]
    except OSError:
        return []


def _kill(proc: subprocess.Popen, fds: list[int]) -> None:
    """Kill bubblewrap and its child, the PID namespace's init (every process inside dies with it); close our pipes.

    The init is in a session of its own (``--new-session``), so it is killed by pid as well
    as by ``--die-with-parent``: at once rather than when bubblewrap's death reaches it.
    """
    inner = _children(proc.pid)
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    for pid in inner:  # bubblewrap's children only, while it is unreaped: the pids cannot have been reused
        try:
            os.kill(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass
    fds.clear()


def _size(n: int) -> str:
    return f"{n >> 20} MiB" if n % (1 << 20) == 0 else f"{n} bytes"


class SandboxPolicy:
    """A policy package run in a bubblewrap sandbox, behind the policy protocol (``decisions``, ``reset``, ``act``).

    Starting it starts the sandbox and loads the package (its HELLO); :meth:`close` (or
    the end of a ``with`` block) ends it. After a failure every call raises the same
    :class:`SandboxError`.

    Args:
        package_dir: the unpacked package (mounted read-only at ``/policy``, on the import path).
        entry: the ``module:attr`` entry point inside it.
        limits: the sandbox's limits (``None``: the defaults).
        key_secret: the secret of the opaque keys (:func:`opaque_keys`).
        key_context: what the keys are for (a track and phase), so keys differ between boards.
    """

    reads_trace = False

    def __init__(self, package_dir: str | Path, entry: str, limits: Limits | None, key_secret: bytes,
                 key_context: str):
        check_sandbox()
        self.package_dir = Path(package_dir).resolve()
        if not self.package_dir.is_dir():
            raise ValueError(f"package folder {package_dir} does not exist")
        _check_readable(self.package_dir)
        self.entry = entry
        self.limits = limits or Limits()
        self.key_secret, self.key_context = bytes(key_secret), key_context
        self.uid = SANDBOX_UIDS[secrets.randbelow(len(SANDBOX_UIDS))] if os.geteuid() == 0 else os.geteuid()
        self.decisions: tuple[str, ...] = ()
        self.name = entry
        self.failure: SandboxError | SandboxUnavailable | None = None
        self._starting = True  # until the child's handshake (STARTED): a failure is the board's, not the policy's
        self._calls = {"reset": 0, "act": 0}  # the first of each gets the warm-up allowance
        self._log = bytearray()
        self._logged = 0
        self._decoder = Decoder(_FROM_CHILD)
        self._inbox: deque[Message] = deque()
        self._episode_left = self.limits.wall_time_s
        filt = _seccomp_fd()
        to_child_r, self._to_child = os.pipe()
        self._from_child, from_child_w = os.pipe()
        self._log_r, log_w = os.pipe()
        config = {"in": to_child_r, "out": from_child_w, "entry": entry, "rlimits": self.limits.rlimits(),
                  "memory_mb": self.limits.memory_mb}
        try:
            # bubblewrap gets a minimal environment of its own (BWRAP_ENV), never the evaluator's, and only the
            # descriptors it needs: the two protocol pipes, the log and the filter
            self.proc = subprocess.Popen(sandbox_command(self.package_dir, config, self.limits, self.uid,
                                                         shared_caches(), filt),
                                         stdin=subprocess.DEVNULL, stdout=log_w, stderr=log_w, env=dict(BWRAP_ENV),
                                         pass_fds=(to_child_r, from_child_w, filt), close_fds=True,
                                         start_new_session=True)
        except OSError as exc:
            for fd in (self._to_child, self._from_child, self._log_r):
                os.close(fd)
            raise SandboxUnavailable(f"the sandbox could not start (the board's set-up, not the policy): bubblewrap "
                                     f"did not run: {type(exc).__name__}: {exc}") from None
        finally:
            for fd in (to_child_r, from_child_w, log_w, filt):
                os.close(fd)
        for fd in (self._to_child, self._from_child, self._log_r):
            os.set_blocking(fd, False)
        self._fds = [self._to_child, self._from_child, self._log_r]
        self._finalizer = weakref.finalize(self, _kill, self.proc, self._fds)
        self._exchange(b"", "starting", Kind.STARTED, self.limits.start_timeout_s, "start time limit")
        self._starting = False
        hello = self._exchange(b"", "loading the policy", Kind.HELLO, self.limits.start_timeout_s, "start time limit")
        self.decisions = tuple(d for d in array_text(hello.arrays.get("decisions")).split(",") if d)
        self.name = array_text(hello.arrays.get("name")) or entry

    # the policy protocol

    def _timeout(self, call: str) -> tuple[float, str]:
        """The time limit of this ``call``: the warm-up allowance for the first reset and act, else the act timeout."""
        self._calls[call] += 1
        if self._calls[call] == 1 and self.limits.warmup_s > self.limits.act_timeout_s:
            return self.limits.warmup_s, f"warm-up limit of the first {call}"
        return self.limits.act_timeout_s, "act time limit"

    def set_world(self, config: ScenarioConfig) -> None:
        """The world's public parameters (:func:`wfbench.harness.runner.public_world`), sent with the next RESET.

        The child hands them to the policy's own ``set_world`` before its ``reset``, if it has one.
        """
        self._world = config.to_json()

    def reset(self, seeds: Sequence[int]) -> None:
        """Hand the policy the opaque keys of ``seeds`` (one per environment) for a new batch of episodes."""
        self._episode_left = self.limits.wall_time_s
        keys = opaque_keys(np.asarray(seeds).tolist(), self.key_secret, self.key_context)
        world = getattr(self, "_world", None)
        arrays = {"keys": keys} if world is None else {"keys": keys, "world": text_array(world)}
        self._exchange(encode(Kind.RESET, arrays), "reset", Kind.READY, *self._timeout("reset"))

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The policy's batched action for ``obs``."""
        try:
            frame = encode(Kind.ACT, obs)
        except WireError as exc:  # our observation, not the policy's fault
            raise ValueError(f"cannot send the observation to the sandbox: {exc}") from None
        return self._exchange(frame, "act", Kind.ACTION, *self._timeout("act")).arrays

    # life cycle

    @property
    def log(self) -> str:
        """What the policy wrote to stdout and stderr (the first ``limits.log_bytes`` bytes)."""
        return self._log.decode("utf-8", "replace")

    @property
    def pid(self) -> int:
        """The process id of bubblewrap (the leader of the sandbox's process group)."""
        return self.proc.pid

    def cpu_s(self) -> float:
        """CPU seconds the sandbox's processes have used so far: bubblewrap and every process under it.

        Each live process's user and system time, plus what its ended children used
        (``cutime``/``cstime``: the kernel adds a child's time to its parent when it is
        reaped), read from ``/proc``; 0 for processes already gone.
        """
        tick = os.sysconf("SC_CLK_TCK")
        total, todo, seen = 0, [self.proc.pid], set()
        while todo:
            pid = todo.pop()
            if pid in seen:
                continue
            seen.add(pid)
            try:
                fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
                total += sum(int(f) for f in fields[11:15])  # utime, stime, cutime, cstime
            except (OSError, ValueError, IndexError):
                continue
            todo += _children(pid)
        return total / tick

    def close(self) -> None:
        """End the sandbox: BYE, a moment to exit, then kill what is left. Idempotent."""
        if not self._fds:
            return
        if self.failure is None and self.proc.poll() is None:
            try:
                os.write(self._to_child, encode(Kind.BYE))
                self.proc.wait(timeout=2)
            except (OSError, subprocess.TimeoutExpired):
                pass
        self._drain_log()
        self._finalizer()

    def __enter__(self) -> SandboxPolicy:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # the exchange

    def _exchange(self, frame: bytes, what: str, expect: Kind, timeout_s: float,
                  limit: str = "act time limit") -> Message:
        """Send ``frame``, then wait for the ``expect`` reply within the limits; any failure kills the sandbox.

        The clocks are this process's alone: nothing the child writes stops, pauses or
        extends them (a frame other than ``expect`` or ERROR breaks the protocol).
        """
        if self.failure is not None:
            raise self.failure
        if not self._fds:
            raise SandboxError(f"the sandbox of {self.entry!r} is closed")
        start = time.monotonic()
        act_deadline = start + timeout_s
        wall_deadline = start + self._episode_left if expect not in (Kind.STARTED, Kind.HELLO) else math.inf
        out = memoryview(frame)
        poller = select.poll()
        poller.register(self._from_child, select.POLLIN)
        poller.register(self._log_r, select.POLLIN)
        if out:
            poller.register(self._to_child, select.POLLOUT)
        try:
            while True:
                while self._inbox:
                    msg = self._inbox.popleft()
                    if msg.kind == Kind.ERROR:
                        reason = array_text(msg.arrays.get("reason")).strip().splitlines()
                        self._fail(reason[0][:500] if reason else f"the policy failed in {what}",
                                   array_text(msg.arrays.get("trace")))
                    elif msg.kind == expect and not out:
                        return msg
                    else:
                        self._fail(f"the policy's process broke the protocol: it sent {msg.kind.name} during {what} "
                                   f"(expected {expect.name})")
                now = time.monotonic()
                if now >= wall_deadline:
                    self._fail(f"the policy took longer than {self.limits.wall_time_s:g} s over one batch of "
                               "episodes (the wall time limit)")
                if now >= act_deadline:
                    self._fail(f"{what} took longer than {timeout_s:g} s (the {limit})")
                deadline = min(wall_deadline, act_deadline)
                for fd, _ in poller.poll(max(0, min(deadline - now, 3600)) * 1000 + 1):
                    if fd == self._to_child:
                        out = self._write(out, what)
                        if not out:
                            poller.unregister(self._to_child)
                    elif fd == self._log_r:
                        self._drain_log()
                    elif fd == self._from_child:
                        self._read(what)
        finally:
            self._episode_left -= time.monotonic() - start

    def _write(self, out: memoryview, what: str) -> memoryview:
        try:
            return out[os.write(self._to_child, out[:_READ]):]
        except BlockingIOError:
            return out
        except BrokenPipeError:
            self._died(what)
            raise AssertionError("unreachable") from None

    def _read(self, what: str) -> None:
        try:
            data = os.read(self._from_child, 1 << 20)
        except BlockingIOError:
            return
        if not data:
            self._died(what)
        try:
            self._inbox.extend(self._decoder.feed(data))
        except WireError as exc:
            self._fail(f"the policy's process broke the protocol during {what}: {exc}")

    def _drain_log(self) -> None:
        while self._fds:
            try:
                data = os.read(self._log_r, _READ)
            except BlockingIOError:
                return
            if not data:
                return
            self._logged += len(data)
            self._log += data[: max(0, self.limits.log_bytes - len(self._log))]
            if self._logged > self.limits.log_bytes and self.failure is None:
                self._fail(f"wrote more than {_size(self.limits.log_bytes)} to stdout/stderr (the log limit)")

    def _died(self, what: str) -> None:
        """The child closed its end: wait for the exit status and say what ended it."""
        try:
            rc = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            rc = None
        self._drain_log()
        last = (self.log.strip().splitlines() or [""])[-1]
        if self._starting:  # before the handshake no code of the package has run: the set-up failed
            status = "did not exit" if rc is None else f"exited with code {rc}" if rc >= 0 else f"got signal {-rc}"
            reason = f"Python in the sandbox {status} before its handshake" + (f" ({last[:300]})" if last else "")
        elif rc is None:
            reason = f"the policy's process closed its pipe during {what}"
        elif last.startswith("bwrap:"):
            reason = f"the sandbox could not start: {last}"
        elif rc > 128 or rc < 0:
            reason = f"the policy's process ended with {_signal(abs(rc) - 128 if rc > 128 else -rc, self.limits)} " \
                     f"during {what}"
        else:
            reason = f"the policy's process exited with code {rc} during {what}" + (f" ({last[:200]})" if last else "")
        self._fail(reason)

    def _fail(self, reason: str, trace: str = "") -> None:
        """Kill the sandbox and raise (from now on, on every call) a SandboxError with ``reason``.

        Before the child's handshake it is a :class:`SandboxUnavailable`: the sandbox or its
        Python failed before any code of the package ran.
        """
        if self.failure is None:
            if self._fds and self._logged <= self.limits.log_bytes:
                self._drain_log()
            if self._starting:
                self.failure = SandboxUnavailable(f"the sandbox could not start (the board's set-up, not the "
                                                  f"policy): {reason}")
            else:
                self.failure = SandboxError(reason, trace, self.log)
            self._finalizer()
        raise self.failure


def _signal(sig: int, limits: Limits) -> str:
    """``signal 9 (SIGKILL: memory limit 4096 MB?)``: the signal and the limit that likely sent it."""
    try:
        name = signal.Signals(sig).name
    except ValueError:
        return f"signal {sig}"
    hint = {signal.SIGKILL: f"memory limit {limits.memory_mb} MB?", signal.SIGXCPU: f"CPU limit {limits.cpu_s} s",
            signal.SIGXFSZ: f"file size limit {limits.file_mb} MB"}.get(signal.Signals(sig), "")
    return f"signal {sig} ({name}{': ' + hint if hint else ''})"


# -- a warm cache for the sandboxes ---------------------------------------------------------------------------------


def warm_cache(policy: Any, config: ScenarioConfig, steps: int = 4) -> None:
    """Compile here, into this process's numba cache (which sandboxes copy from), what a sandbox of ``policy`` loads.

    ``policy`` is trusted: its code runs here (a built-in). It plays ``steps`` steps as
    the sandbox's child plays them: keys as an int64 array, observations through the
    wire format, since numba compiles one version per argument type and a direct call
    could cache versions the child never asks for. On a warm cache it only loads
    (about 0.1 s a policy); on a cold one it compiles, once per machine and version of
    the code.
    """
    sim = Simulator(config.replace(horizon=steps), [0])
    obs = sim.reset()
    policy.reset(opaque_keys([0], LOCAL_KEY_SECRET, "warm"))
    decoder = Decoder()
    while not sim.done:
        (msg,) = decoder.feed(encode(Kind.ACT, obs))
        sim.step(policy.act(msg.arrays))
        obs = sim.observe()


# -- evaluating a package --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _SandboxGuard(Guard):
    """The runner's guard for a :class:`SandboxPolicy`: its limits are enforced from outside, its errors are its own."""

    def call(self, what: str, fn: Any, *args: Any) -> Any:
        return fn(*args)

    def step(self, sim: Simulator, actions: Any, act: Any) -> None:
        try:
            sim.step(actions)
        except (ActionError, TypeError, ValueError) as exc:
            lines = str(exc).strip().splitlines()
            raise SandboxError(f"the policy returned a malformed action at step {sim.t}: "
                               f"{type(exc).__name__}: {lines[0] if lines else ''}") from exc


def evaluate_sandboxed(package_dir: str | Path, entry: str, config: ScenarioConfig | str, seeds: Sequence[int],
                       limits: Limits | None, key_secret: bytes, key_context: str,
                       chunk_size: int | None = None) -> pd.DataFrame:
    """Evaluate a policy package in a sandbox: the rows :func:`~wfbench.harness.evaluation.evaluate` gives.

    One sandbox serves every chunk (``chunk_size`` seeds per batch; ``None``: one batch).
    The KPI and counter columns equal ``evaluate``'s for the same policy bit for bit
    when its decisions do not depend on its seeds (it sees opaque keys here). The budget
    columns are measured in this process: the milliseconds per decision include the
    policy's time over the pipes, and the CPU seconds per episode add the sandbox's
    processes' to this process's.

    Returns:
        One row per seed, in seed order; ``attrs``: ``scenario``, ``policy`` (``entry``),
        ``log`` (what the policy printed, capped) and ``budget``.

    Raises:
        SandboxError: the policy failed, broke a limit or returned a malformed action
            (``reason``, and ``log``).
        SandboxUnavailable: no sandbox on this machine.
    """
    from wfbench.harness.budget import machine
    from wfbench.harness.runner import results_frame, run_batch
    from wfbench.scenarios.resolve import resolve_scenario

    config = resolve_scenario(config)
    seed_list = [int(s) for s in seeds]
    if chunk_size is not None and (isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1):
        raise ValueError(f"chunk_size = {chunk_size!r} is not allowed; allowed: an integer >= 1, or None")
    size = chunk_size or max(1, len(seed_list))
    with SandboxPolicy(package_dir, entry, limits, key_secret, key_context) as policy:
        loaded = LoadedPolicy(policy, entry, _SandboxGuard(entry, None))
        results = []
        for i in range(0, len(seed_list), size):
            chunk = seed_list[i:i + size]
            before = policy.cpu_s()
            r = run_batch(loaded, config, chunk)
            # the row's CPU seconds per episode are the evaluator's and the sandboxed policy's together
            results.append(replace(r, cpu_s=r.cpu_s + max(0.0, policy.cpu_s() - before) / len(chunk)))
        log = policy.log
    df = results_frame(results, config, entry)
    df.attrs.update(scenario=config.name, policy=entry, log=log,
                    budget={"backend": "sandbox", "workers": 1, "threads": None,
                            "timing": results[0].timing if results else "", "chunks": len(results),
                            "policy": {"kind": "sandboxed"}, "machine": machine()})
    return df
