"""The sandbox wherever Python is installed, and what of the worker reaches it (issue #42).

- Python, the virtual environment and the checkout under ``/tmp``: the sandbox's own tmpfs at
  ``/tmp`` once hid them (``exit code 127``, blamed on the policy). The layout is built
  once per module from hard links (``cp -al``: a second or so, no bytes copied) of this
  interpreter, this venv and the wfbench package folders, with the venv's ``pyvenv.cfg`` and
  the editable install's finder rewritten to the copies.
- ``check_sandbox`` starts Python in the sandbox and imports wfbench there, and says in one
  line what stops it.
- A worker that is not root (its environment holds the database URL with its password, and
  an inheritable descriptor) hands neither to the sandbox: a spy reads ``/proc/1/environ``,
  ``/proc/self/environ``, its parent's and every other environment it can see, and lists its
  descriptors.
- The policy writes only its capped ``/tmp``, root or not (issue #55): under a non-root worker
  the skeleton bubblewrap makes for its binds once belonged to the policy's own uid, an
  uncapped tmpfs that took 1.5 GiB of the host's memory. The spy tries every folder of its
  sandbox; a filler writes ``/tmp`` until it is refused.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from importlib.util import find_spec
from pathlib import Path

import pytest

from wfbench.harness.isolation import sandbox
from wfbench.harness.isolation.sandbox import PACKAGES, SandboxUnavailable, check_sandbox

SECRET_URL = "postgresql+psycopg://board:S3cr3t-Passw0rd@db.internal/board"
USER = 54_321  # a uid no account uses: setpriv needs no passwd entry


def _hardlink_copy(src: Path, dest: Path) -> None:
    subprocess.run(["cp", "-al", str(src), str(dest)], check=True)


def _replace(path: Path, text: str) -> None:
    """Write ``path`` anew (a hard link's other names keep the old bytes)."""
    path.unlink()
    path.write_text(text)


def build_layout(root: Path) -> dict[str, Path]:
    """This Python, its venv and the wfbench checkout, hard-linked under ``root``; the paths of the copies."""
    base = Path(sys.base_prefix).resolve()
    venv_src = Path(sys.prefix).resolve()
    if os.stat(base).st_dev != os.stat(root).st_dev or os.stat(venv_src).st_dev != os.stat(root).st_dev:
        pytest.skip(f"{root} is on another filesystem than the Python installation: hard links (the layout's copies) "
                    "cannot cross it")
    python_root, checkout = root / "python", root / "checkout"
    _hardlink_copy(base, python_root)
    checkout.mkdir()
    moved: dict[str, str] = {}
    for name in PACKAGES:
        spec = find_spec(name)
        for folder in (spec and spec.submodule_search_locations) or []:
            folder = Path(folder).resolve()
            target = checkout / folder.name
            if not target.exists():
                _hardlink_copy(folder, target)
            moved[str(folder)] = str(target)
    venv = checkout / ".venv"
    _hardlink_copy(venv_src, venv)
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    _replace(venv / "pyvenv.cfg", f"home = {python_root / 'bin'}\ninclude-system-site-packages = false\n"
                                  f"version = {sys.version.split()[0]}\n")
    for name in ("python", "python3", f"python{version}"):
        link = venv / "bin" / name
        if link.is_symlink() or link.exists():
            link.unlink()
        link.symlink_to(python_root / "bin" / f"python{version}")
    site = venv / "lib" / f"python{version}" / "site-packages"
    finders = list(site.glob("__editable__*finder.py"))
    for finder in finders:
        text = finder.read_text()
        for old, new in sorted(moved.items(), key=lambda kv: -len(kv[0])):
            text = text.replace(repr(old), repr(new))
        _replace(finder, text)
    python = venv / "bin" / "python"
    env = {"PATH": "/usr/bin:/bin", "HOME": str(root / "home"), "LD_LIBRARY_PATH": str(python_root / "lib")}
    (root / "home").mkdir(mode=0o777)
    (root / "home").chmod(0o777)
    out = subprocess.run([str(python), "-c", "import sys, wfbench, wfbench.policies as p; "
                          "print(sys.prefix, sys.base_prefix, wfbench.__file__, p.__file__)"],
                         capture_output=True, text=True, env=env, cwd=root)
    assert out.returncode == 0, out.stderr
    assert all(p.startswith(str(root)) for p in out.stdout.split()), out.stdout  # everything from under /tmp
    return {"python": python, "env": env, "root": root}


@pytest.fixture(scope="module")
def layout():
    if os.geteuid() != 0:
        pytest.skip("building the layout copies root's Python installation; run as root (CI does)")
    root = Path(tempfile.mkdtemp(prefix="wfbench-layout-", dir="/tmp"))
    root.chmod(0o755)
    try:
        yield build_layout(root)
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _run(layout, script: str, *, as_user: int | None = None, extra_env: dict[str, str] | None = None,
         timeout: float = 240) -> subprocess.CompletedProcess:
    cmd = [str(layout["python"]), "-c", textwrap.dedent(script)]
    if as_user is not None:
        cmd = ["setpriv", "--reuid", str(as_user), "--regid", str(as_user), "--clear-groups", "--", *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, env={**layout["env"], **(extra_env or {})},
                          cwd=layout["root"], timeout=timeout)


RULE = '''
import numpy as np


class Policy:
    decisions = ("dispatch", "workforce", "positioning")

    def reset(self, keys):
        pass

    def act(self, obs):
        mask = obs["dispatch_mask"]
        B, M, N1 = mask.shape
        return {"dispatch": np.full((B, M), N1 - 1, dtype=np.int64), "workforce": np.zeros(B, dtype=np.int64),
                "positioning": np.full((B, 2, M), 0.5)}
'''


def _write_package(root: Path, name: str, source: str) -> Path:
    """``source`` as ``pol.py`` of a package, packed and unpacked as a board does, readable by every user."""
    from wfbench.harness.isolation.package import pack, unpack

    src = root / f"{name}-src"
    src.mkdir()
    (src / "pol.py").write_text(source)
    dest = root / name
    unpack(pack("pol:Policy", src), dest)
    return dest


@pytest.mark.slow
def test_a_sandbox_runs_with_python_the_venv_and_the_checkout_under_tmp(bwrap, layout):
    package = _write_package(layout["root"], "rule", RULE)
    out = _run(layout, f'''
        import json, wfbench
        from wfbench.core.config import ScenarioConfig
        from wfbench.harness.isolation import sandbox
        sandbox.check_sandbox()
        rows = sandbox.evaluate_sandboxed({str(package)!r}, "pol:Policy", ScenarioConfig.preset("small").replace(
            horizon=5), [0, 1], None, b"s", "tests")
        print(json.dumps({{"wfbench": wfbench.__file__, "rows": len(rows), "nsw": rows["nsw"].tolist()}}))
        ''')
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["wfbench"].startswith(str(layout["root"])) and result["rows"] == 2


def test_check_sandbox_starts_python_and_imports_wfbench_inside(bwrap, monkeypatch):
    check_sandbox()  # this machine: it starts
    sandbox._trial.cache_clear()
    # the installation's own Python without the venv's packages: it starts, and cannot import wfbench there
    base = Path(sys.base_prefix).resolve()
    monkeypatch.setattr(sandbox, "python_folders", lambda: [base])
    monkeypatch.setattr(sandbox, "_interpreter", lambda: str(base / "bin" / f"python{sys.version_info[0]}."
                                                         f"{sys.version_info[1]}"))
    with pytest.raises(SandboxUnavailable) as info:
        check_sandbox()
    reason = str(info.value)
    assert "\n" not in reason and "the sandbox's Python cannot import wfbench" in reason, reason
    assert "ModuleNotFoundError: No module named" in reason, reason
    sandbox._trial.cache_clear()
    monkeypatch.setattr(sandbox, "python_folders", lambda: [])  # nor Python itself
    monkeypatch.setattr(sandbox, "_interpreter", lambda: "/nonexistent/bin/python3")
    with pytest.raises(SandboxUnavailable) as info:
        check_sandbox()
    reason = str(info.value)
    assert "\n" not in reason and "Python cannot start in the sandbox" in reason, reason
    assert "/nonexistent/bin/python3" in reason, reason
    sandbox._trial.cache_clear()


SPY = '''
import os


def _environ(path):
    try:
        with open(path, "rb") as f:
            return f.read().decode("utf-8", "replace").replace(chr(0), " ")
    except OSError as exc:
        return type(exc).__name__


def _fds():
    out = {}
    for fd in os.listdir("/proc/self/fd"):
        try:
            out[fd] = os.readlink(f"/proc/self/fd/{fd}")
        except OSError as exc:
            out[fd] = type(exc).__name__
    return out


def _writable():
    """Every folder outside /proc and /sys in which a new file can be made."""
    found = []
    for root, dirs, _ in os.walk("/"):
        if root in ("/proc", "/sys"):
            dirs[:] = []
            continue
        probe = os.path.join(root, ".wfbench-probe")
        try:
            os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        except OSError:
            continue
        os.unlink(probe)
        found.append(root)
    return found


REPORT = {
    "uid": os.getuid(), "pid": os.getpid(), "ppid": os.getppid(), "writable": _writable(),
    "self": _environ("/proc/self/environ"), "init": _environ("/proc/1/environ"),
    "parent": _environ(f"/proc/{os.getppid()}/environ"),
    "all": {p: _environ(f"/proc/{p}/environ") for p in os.listdir("/proc") if p.isdigit()},
    "fds": _fds(), "argv": open("/proc/self/cmdline", "rb").read().decode().split(chr(0)),
}


class Policy:
    decisions = ("dispatch",)

    def __init__(self):
        import json
        print("SPY " + json.dumps(REPORT), flush=True)
        raise RuntimeError("reported")

    def reset(self, keys):
        pass

    def act(self, obs):
        return {}
'''


def _spy_report(layout, as_user: int | None, source: str = SPY, prefix: str = "SPY ") -> tuple[dict, str]:
    """What the policy ``source`` printed after ``prefix`` in its constructor, run by a worker of ``as_user``."""
    package = _write_package(layout["root"], f"{prefix.strip().lower()}-{as_user}", source)
    leak = layout["root"] / f"board-{as_user}.sqlite"
    leak.write_text("the board's database")
    leak.chmod(0o644)
    out = _run(layout, f'''
        import json, os
        from wfbench.harness.isolation import sandbox
        fd = os.open({str(leak)!r}, os.O_RDONLY)  # a descriptor the worker holds, inheritable
        os.set_inheritable(fd, True)
        try:
            sandbox.SandboxPolicy({str(package)!r}, "pol:Policy", None, b"s", "tests")
        except sandbox.SandboxError as exc:
            print(json.dumps({{"reason": exc.reason, "log": exc.log, "leaked_fd": fd}}))
        ''', as_user=as_user, extra_env={"WFBENCH_SERVER_DB": SECRET_URL, "DATABASE_URL": SECRET_URL})
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["reason"].startswith("the policy could not be loaded: RuntimeError: reported"), result["reason"]
    spy_line = next(line for line in result["log"].splitlines() if line.startswith(prefix))
    return json.loads(spy_line[len(prefix):]), out.stdout + out.stderr


@pytest.mark.slow
@pytest.mark.parametrize("as_user", [USER, None], ids=["non-root", "root"])
def test_no_secret_and_no_stray_descriptor_reaches_the_sandbox(bwrap, layout, as_user):
    report, everything = _spy_report(layout, as_user)
    if as_user is not None:
        assert report["uid"] != 0
    seen = json.dumps(report)
    assert "S3cr3t-Passw0rd" not in seen, {k: v for k, v in report.items() if "S3cr3t" in json.dumps(v)}
    assert "HOME=/tmp" in report["self"] and "WFBENCH_SERVER_DB" not in report["self"]
    assert report["init"] != "", report["init"]  # readable or refused, never the worker's
    # only the standard streams and the two protocol pipes; the listing's own descriptor shows as one more entry
    config = json.loads(report["argv"][-2] if report["argv"][-1] == "" else report["argv"][-1])
    allowed = {0, 1, 2, config["in"], config["out"]}
    extra = {int(fd): target for fd, target in report["fds"].items() if int(fd) not in allowed}
    assert len(extra) <= 1 and all(t.startswith("/proc/") or t == "FileNotFoundError" for t in extra.values()), \
        report["fds"]
    assert "board-" not in json.dumps(report["fds"])
    # nowhere to write but its capped /tmp, root or not
    assert report["writable"] and all(w == "/tmp" or w.startswith("/tmp/") for w in report["writable"]), \
        report["writable"]


FILL = '''
import errno, json, os

MIB = 1 << 20


def fill(folder, most=256 * MIB):
    """Write files of 8 MiB (below RLIMIT_FSIZE) into ``folder`` until refused: the bytes written, the errno.

    It stops at ``most`` (twice the sandbox's cap: "no limit") and removes what it wrote, so that a sandbox that
    lets it write takes the test machine's memory only for a moment and only that much.
    """
    block, total, made = b"x" * MIB, 0, []
    try:
        while total < most:
            path = os.path.join(folder, f"fill-{len(made)}")
            try:
                fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            except OSError as exc:
                return total, errno.errorcode.get(exc.errno, str(exc.errno))
            made.append(path)
            try:
                for _ in range(8):
                    total += os.write(fd, block)
            except OSError as exc:
                return total, errno.errorcode.get(exc.errno, str(exc.errno))
            finally:
                os.close(fd)
        return total, "no limit"
    finally:
        for path in made:
            os.unlink(path)


class Policy:
    decisions = ("dispatch",)

    def __init__(self):
        # the root and every folder in it (issue #55 filled /etc, /opt, the checkout's parents and the root), /dev/shm,
        # then /tmp
        tops = sorted(os.path.join("/", d) for d in os.listdir("/") if os.path.isdir(os.path.join("/", d)))
        folders = ["/", *(f for f in tops if f not in ("/proc", "/sys", "/tmp")), "/dev/shm", "/tmp"]
        tried = {f: fill(f) for f in folders}
        print("FILL " + json.dumps(tried), flush=True)
        raise RuntimeError("reported")

    def reset(self, keys):
        pass

    def act(self, obs):
        return {}
'''


@pytest.mark.slow
@pytest.mark.parametrize("as_user", [USER, None], ids=["non-root", "root"])
def test_a_policy_writes_only_its_tmp_and_stops_at_its_cap(bwrap, layout, as_user):
    from wfbench.harness.isolation.sandbox import Limits

    tried, _ = _spy_report(layout, as_user, FILL, "FILL ")
    outside = {folder: r for folder, r in tried.items() if folder != "/tmp"}
    assert all(written == 0 and err in ("EROFS", "EACCES", "EPERM") for written, err in outside.values()), outside
    written, err = tried["/tmp"]
    cap = (Limits().tmp_mb + Limits().numba_cache_mb) << 20  # the tmpfs's size, the numba copies included
    assert err == "ENOSPC" and cap // 2 < written <= cap, (written, err, cap)
