"""The policy sandbox (harness.isolation.sandbox): a clean package scores bit for bit as evaluate() scores it, and
hostile packages (fork bomb, huge allocation, disk fill, output flood, endless loops, network, reading the host,
another process's memory) each end in a SandboxError with the right one-line reason and leave no process behind
(issue #34)."""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import socket
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from wfbench.policies import get

from wfbench.cli import main
from wfbench.core.config import ScenarioConfig
from wfbench.core.simulator import Simulator
from wfbench.harness.budget import results_only
from wfbench.harness.evaluation import evaluate
from wfbench.harness.isolation.package import pack, unpack
from wfbench.harness.isolation.sandbox import (
    Limits,
    SandboxError,
    SandboxPolicy,
    SandboxUnavailable,
    check_sandbox,
    evaluate_sandboxed,
    opaque_keys,
    shared_caches,
    warm_cache,
)

SHORT = ScenarioConfig.preset("small").replace(horizon=20)
TIGHT = Limits(act_timeout_s=2, warmup_s=2, memory_mb=1024, wall_time_s=20, tmp_mb=32, start_timeout_s=30)
SECRET, CONTEXT = b"test-secret", "tests:dev"

RULE = '''
import numpy as np


class Rule:
    """Each requesting facility gets the first dispatchable person nobody else got; no hiring; stay home."""

    decisions = ("dispatch", "workforce", "positioning")
    hire = 0  # the workforce action every step: 0 does nothing

    def reset(self, keys):
        self.keys = [int(k) for k in keys]

    def act(self, obs):
        mask = obs["dispatch_mask"]
        B, M, N1 = mask.shape
        d = np.full((B, M), N1 - 1, dtype=np.int64)
        for b in range(B):
            used = set()
            for m in np.flatnonzero(obs["requesting"][b]):
                free = [n for n in np.flatnonzero(mask[b, m, :-1]) if n not in used]
                if free:
                    used.add(free[0])
                    d[b, m] = free[0]
        return {"dispatch": d, "workforce": np.full(B, self.hire, dtype=np.int64),
                "positioning": np.full((B, 2, M), 0.5)}
'''

HOSTILE = '''
import os, socket, sys, time
import numpy as np


class Policy:
    decisions = ("dispatch",)

    def reset(self, seeds):
        self.keys = [int(k) for k in seeds]

    def act(self, obs):
{body}
        return {{"dispatch": np.zeros((1, 1), dtype=np.int64)}}
'''


def _package(tmp_path: Path, source: str, module: str = "pol") -> Path:
    """``source`` as module ``module`` of a package, packed and unpacked as a board would."""
    src = tmp_path / "src"
    src.mkdir(exist_ok=True)
    (src / f"{module}.py").write_text(source)
    dest = tmp_path / "unpacked"
    unpack(pack(f"{module}:Policy", src), dest)
    return dest


def _hostile(tmp_path: Path, body: str) -> Path:
    return _package(tmp_path, HOSTILE.format(body=textwrap.indent(textwrap.dedent(body).strip(), " " * 8)))


def _namespace(sp: SandboxPolicy) -> str:
    """The PID namespace of the sandboxed Python (the deepest process under bubblewrap)."""
    pid = sp.pid
    for _ in range(5):
        kids = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
        if not kids:
            break
        pid = int(kids[0])
    ns = os.readlink(f"/proc/{pid}/ns/pid")
    assert ns != os.readlink("/proc/self/ns/pid"), "the policy runs in its own PID namespace"
    return ns


def _left_in(ns: str, wait_s: float = 5.0) -> list[int]:
    """Live processes still in PID namespace ``ns`` after up to ``wait_s`` seconds (the kernel tears it down).

    A zombie is dead already: the namespace's init, orphaned by bubblewrap's death, waits
    for the host's init to reap it.
    """
    deadline = time.monotonic() + wait_s
    while True:
        left = []
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    if os.readlink(f"/proc/{entry}/ns/pid") == ns and \
                            Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                        left.append(int(entry))
                except OSError:
                    pass
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.05)


def _fails(package: Path, limits: Limits = TIGHT) -> SandboxError:
    """Start the package, reset and act once; the SandboxError it ends with, after checking nothing is left."""
    with SandboxPolicy(package, "pol:Policy", limits, SECRET, CONTEXT) as sp:
        ns = _namespace(sp)
        sp.reset([7])
        with pytest.raises(SandboxError) as info:
            sp.act({"x": np.zeros(1)})
        assert sp.proc.poll() is not None, "the sandbox is killed at the failure"
    assert _left_in(ns) == [], "no process of the sandbox may outlive it"
    reason = info.value.reason
    assert "\n" not in reason and reason == str(info.value)
    with pytest.raises(SandboxError, match="^" + reason[:30].replace("(", r"\(").replace("[", r"\[")):
        sp.act({"x": np.zeros(1)})  # and every later call says the same
    return info.value


# -- a clean package ---------------------------------------------------------------------------------------------


def test_clean_package_scores_bit_for_bit_as_evaluate(bwrap, tmp_path, monkeypatch):
    package = _package(tmp_path, RULE.replace("class Rule", "class Policy"))
    monkeypatch.syspath_prepend(str(package))
    direct = evaluate("pol:Policy", SHORT, [5, 3, 4])
    sandboxed = evaluate_sandboxed(package, "pol:Policy", SHORT, [5, 3, 4], None, SECRET, CONTEXT, chunk_size=2)
    pd.testing.assert_frame_equal(results_only(sandboxed), results_only(direct), check_exact=True)
    assert sandboxed.attrs["policy"] == "pol:Policy" and sandboxed.attrs["budget"]["chunks"] == 2
    assert (sandboxed["cpu_s"] > 0).all() and (sandboxed["decision_ms_p50"] > 0).all()


def test_a_row_counts_the_cpu_the_sandboxed_policy_used(bwrap, tmp_path):
    """The budget's CPU seconds per episode include the sandbox's processes, not only the evaluator's waiting."""
    busy = RULE.replace("class Rule", "class Policy").replace(
        "    def act(self, obs):\n", "    def act(self, obs):\n        import time\n        t0 = time.process_time()\n"
        "        while time.process_time() - t0 < 0.02:\n            pass\n", 1)
    assert "process_time" in busy
    rows = evaluate_sandboxed(_package(tmp_path, busy), "pol:Policy", SHORT, [1, 2], None, SECRET, CONTEXT)
    burned = SHORT.horizon * 0.02 / 2  # 20 ms of CPU every step of the batch, over its 2 episodes
    assert (rows["cpu_s"] >= burned).all(), (rows["cpu_s"].tolist(), burned)
    assert (rows["cpu_s"] < burned + 5).all()


def test_policy_sees_opaque_keys_not_seeds(bwrap, tmp_path):
    package = _hostile(tmp_path, 'raise RuntimeError(f"keys {self.keys} uid {os.getuid()}")')
    with SandboxPolicy(package, "pol:Policy", TIGHT, SECRET, CONTEXT) as sp:
        assert sp.decisions == ("dispatch",) and sp.name == "Policy"
        sp.reset([0, 1])
        with pytest.raises(SandboxError) as info:
            sp.act({"x": np.zeros(2)})
    keys = opaque_keys([0, 1], SECRET, CONTEXT)
    assert sp.uid != 0  # as root, it runs as a user of its own
    assert info.value.reason == f"the policy raised RuntimeError: keys {keys.tolist()} uid {sp.uid} in act at pol.py:13"
    assert "Traceback" in info.value.trace and "pol.py" in info.value.trace


def test_opaque_keys_are_reproducible_and_hide_the_seed():
    keys = opaque_keys([0, 1, 2**62], SECRET, CONTEXT)
    assert keys.dtype == np.int64 and (keys >= 0).all() and len(set(keys.tolist())) == 3
    assert (opaque_keys([0, 1, 2**62], SECRET, CONTEXT) == keys).all()
    assert not (opaque_keys([0, 1, 2**62], SECRET, "tests:test") == keys).any()
    assert not (opaque_keys([0, 1, 2**62], b"other", CONTEXT) == keys).any()


def test_check_sandbox_says_how_to_install_bubblewrap(monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(SandboxUnavailable, match=r"bubblewrap \(bwrap\) is not installed.*apt-get install bubblewrap"):
        check_sandbox()


def test_limits_refuse_nonsense():
    with pytest.raises(ValueError, match="sandbox limit act_timeout_s = 0 is not allowed; allowed: a number > 0"):
        Limits(act_timeout_s=0)


# -- failures of the policy's own making -------------------------------------------------------------------------


def test_a_package_that_fails_to_import_names_its_line(bwrap, tmp_path):
    package = _package(tmp_path, "import numpy\n\nx = 1 / 0\n")
    with pytest.raises(SandboxError, match=r"^the policy could not be loaded: ZeroDivisionError: division by zero "
                                           r"at pol.py:3$"):
        SandboxPolicy(package, "pol:Policy", TIGHT, SECRET, CONTEXT)


def test_a_policy_that_reads_the_trace_is_refused(bwrap, tmp_path):
    package = _package(tmp_path, HOSTILE.format(body="        pass").replace("class Policy:",
                                                                             "class Policy:\n    reads_trace = True"))
    with pytest.raises(SandboxError, match="declares reads_trace .* a sandboxed policy sees observations only"):
        SandboxPolicy(package, "pol:Policy", TIGHT, SECRET, CONTEXT)


def test_a_malformed_action_fails_the_evaluation(bwrap, tmp_path):
    package = _hostile(tmp_path, "pass")  # a (1, 1) dispatch only
    with pytest.raises(SandboxError, match=r"^the policy returned a malformed action at step 0: ActionError: actions "
                                           r"must have exactly the keys"):
        evaluate_sandboxed(package, "pol:Policy", SHORT, [0], TIGHT, SECRET, CONTEXT)


def test_the_first_act_may_compile_within_the_warmup_allowance(bwrap, tmp_path):
    source = HOSTILE.format(body="        total(np.arange(100.0))") + textwrap.dedent('''

        from numba import njit


        @njit
        def total(x):
            s = 0.0
            for i in range(x.shape[0]):
                s += np.sin(x[i]) * np.cos(x[i])
            return s
        ''')
    with SandboxPolicy(_package(tmp_path, source), "pol:Policy", Limits(act_timeout_s=0.05), SECRET, CONTEXT) as sp:
        sp.reset([1])
        started = time.monotonic()
        sp.act({"x": np.zeros(1)})  # compiling takes longer than the act limit: the first act has Limits.warmup_s
        assert time.monotonic() - started > 0.05


# -- hostile packages ----------------------------------------------------------------------------------------------


def test_fork_bomb_hits_the_process_limit(bwrap, tmp_path):
    err = _fails(_hostile(tmp_path, "while True:\n    os.fork()"))
    assert "BlockingIOError: [Errno 11] Resource temporarily unavailable in act at pol.py:" in err.reason


def test_huge_allocation_hits_the_memory_limit(bwrap, tmp_path):
    err = _fails(_hostile(tmp_path, "np.ones(100 * 2**30 // 8)"))
    assert err.reason.startswith("MemoryError: Unable to allocate 100. GiB") and "in act at pol.py:" in err.reason
    assert err.reason.endswith("(memory limit 1024 MB)")


def test_filling_tmp_hits_its_size(bwrap, tmp_path):
    body = """
    for i in range(100):
        with open(f"/tmp/fill{i}", "wb") as f:
            f.write(bytes(8 << 20))
    """
    assert "OSError: [Errno 28] No space left on device in act at pol.py:" in _fails(_hostile(tmp_path, body)).reason


def test_one_huge_file_hits_the_file_size_limit(bwrap, tmp_path):
    body = """
    with open("/tmp/big", "wb") as f:
        f.write(bytes(20 << 20))
    """
    assert "OSError: [Errno 27] File too large in act at pol.py:" in _fails(_hostile(tmp_path, body)).reason


def test_the_package_is_read_only(bwrap, tmp_path):
    body = 'open("/policy/pol.py", "a").write("# mine now")'
    reason = _fails(_hostile(tmp_path, body)).reason
    # as root the policy runs as a user who may not write root's files; as another user, the mount is read-only
    assert re.search(r"(PermissionError: \[Errno 13\] Permission denied|OSError: \[Errno 30\] Read-only file "
                     r"system): '/policy/pol.py' in act at pol.py:", reason), reason


def test_stdout_flood_hits_the_log_limit(bwrap, tmp_path):
    err = _fails(_hostile(tmp_path, 'while True:\n    print("x" * 4096)'))
    assert err.reason == "wrote more than 1 MiB to stdout/stderr (the log limit)"
    assert len(err.log) == 1 << 20 and err.log.startswith("x" * 4096)


@pytest.mark.slow
def test_endless_python_loop_hits_the_act_time_limit(bwrap, tmp_path):
    err = _fails(_hostile(tmp_path, "while True:\n    pass"))
    assert err.reason == "act took longer than 2 s (the act time limit)"


@pytest.mark.slow
def test_endless_compiled_loop_hits_the_act_time_limit_after_compiling(bwrap, tmp_path):
    source = HOSTILE.format(body="        spin(1.0)") + textwrap.dedent('''

        from numba import njit


        @njit
        def spin(x):
            while x >= 0.0:  # floats: LLVM cannot prove the loop endless and drop it
                x += 1.0
            return x


        spin(-1.0)  # compiled as the package loads (the start limit), so that the act only loops
        ''')
    started = time.monotonic()
    err = _fails(_package(tmp_path, source))
    assert err.reason == "act took longer than 2 s (the act time limit)"
    assert time.monotonic() - started < 20  # the wall time limit did not have to stop it


def test_the_wall_time_limit_counts_the_whole_batch(bwrap, tmp_path):
    limits = Limits(act_timeout_s=5, wall_time_s=1, memory_mb=1024)
    with SandboxPolicy(_hostile(tmp_path, "time.sleep(0.6)"), "pol:Policy", limits, SECRET, CONTEXT) as sp:
        sp.reset([1])
        sp.act({"x": np.zeros(1)})  # 0.6 s of its 1 s
        with pytest.raises(SandboxError, match=r"^the policy took longer than 1 s over one batch of episodes \(the "
                                               r"wall time limit\)$"):
            sp.act({"x": np.zeros(1)})


@pytest.mark.parametrize(("body", "expected"), [
    ("os._exit(3)", "the policy's process exited with code 3 during act"),
    ("os.kill(os.getpid(), 9)", "the policy's process ended with signal 9 (SIGKILL: memory limit 1024 MB?) during act"),
    ('import json\nos.write(json.loads(sys.argv[1])["out"], b"garbage, not a frame")',
     "the policy's process broke the protocol during act: a frame starts with b'garb'; expected b'WFB1'"),
])
def test_a_process_that_dies_or_breaks_the_protocol(bwrap, tmp_path, body, expected):
    assert _fails(_hostile(tmp_path, body)).reason == expected


def test_no_connection_leaves_the_sandbox(bwrap, tmp_path):
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        listener.setblocking(False)
        port = listener.getsockname()[1]
        err = _fails(_hostile(tmp_path, f'socket.create_connection(("127.0.0.1", {port}), timeout=1)'))
        with pytest.raises(BlockingIOError):
            listener.accept()  # nobody came
    assert "ConnectionRefusedError: [Errno 111] Connection refused in act at pol.py:" in err.reason


def test_no_name_resolves(bwrap, tmp_path):
    err = _fails(_hostile(tmp_path, 'socket.getaddrinfo("example.com", 443)'))
    assert err.reason.startswith("the policy raised gaierror: [Errno -") and "in act at pol.py:" in err.reason


def test_files_outside_the_sandbox_are_not_there(bwrap, tmp_path):
    planted = tmp_path / "seeds.json"  # stands for the board's database and hidden seed list
    planted.write_text("[123456789]")
    planted.chmod(0o644)
    body = f"""
    seen = [p for p in ({str(planted)!r}, {str(Path.cwd() / 'pyproject.toml')!r}, "/etc/passwd", "/root")
            if os.path.exists(p)]
    open({str(planted)!r}).read()
    """
    err = _fails(_hostile(tmp_path, body))
    assert err.reason.startswith(f"the policy raised FileNotFoundError: [Errno 2] No such file or directory: "
                                 f"'{planted}'")


def test_no_secret_in_any_environment(bwrap, tmp_path, monkeypatch):
    monkeypatch.setenv("WFBENCH_TEST_SECRET", "s3cr3t-value")
    body = """
    found = []
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                found.append(open(f"/proc/{pid}/environ", "rb").read().decode())
            except OSError as exc:
                found.append(type(exc).__name__)
    raise RuntimeError("environments: " + " | ".join(found).replace(chr(0), " "))
    """
    err = _fails(_hostile(tmp_path, body))
    assert "environments: " in err.reason and "HOME=/tmp" in err.reason  # its own, cleared environment
    assert "s3cr3t-value" not in err.reason + err.trace + err.log


def test_another_process_memory_is_out_of_reach(bwrap, tmp_path):
    body = f"""
    for pid in ({os.getpid()}, 1):
        try:
            open(f"/proc/{{pid}}/mem", "rb").read(1)
        except OSError as exc:
            print(pid, type(exc).__name__)
        else:
            raise RuntimeError(f"read the memory of process {{pid}}")
    raise RuntimeError("no memory read")
    """
    err = _fails(_hostile(tmp_path, body))
    assert err.reason.startswith("the policy raised RuntimeError: no memory read"), err.reason
    assert f"{os.getpid()} FileNotFoundError" in err.log  # the test's process is not even visible
    assert "1 PermissionError" in err.log or "1 FileNotFoundError" in err.log


# -- the command line ----------------------------------------------------------------------------------------------


def test_cli_evaluates_a_package_in_the_sandbox(bwrap, tmp_path, monkeypatch, capsys):
    (tmp_path / "mypol").mkdir()
    (tmp_path / "mypol" / "__init__.py").write_text(RULE)
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "--sandbox", "--policy", "mypol:Rule", "--scenario", "small", "--seeds", "2",
                 "--format", "csv"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert rows[0].startswith("seed,workforce_cost") and len(rows) == 3
    broken = RULE.replace("self.keys = [int(k) for k in keys]", "print('hi'); 1 / 0")
    (tmp_path / "mypol" / "__init__.py").write_text(broken)
    assert main(["evaluate", "--sandbox", "--policy", "mypol:Rule", "--scenario", "small", "--seeds", "2"]) != 0
    err = capsys.readouterr().err
    assert "wfbench: error: the policy raised ZeroDivisionError: division by zero in reset at mypol/__init__.py:" in err
    assert "hi" in err  # what it printed before it failed


def test_cli_sandbox_refuses_a_bad_policy_spec(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "--sandbox", "--policy", "random", "--scenario", "small", "--seeds", "1"]) == 2
    assert "with --sandbox: allowed: a package folder" in capsys.readouterr().err



# -- numba's cache: a sandbox starts warm from the evaluator's cache, read-only ---------------------------------

WRAPPED = '''
from wfbench.policies import get


def Policy():
    return get("heuristic")
'''

# the wrapped heuristic, counting numba's compilations in its process, then spoiling every cache file it can reach
SPOILER = '''
import os

from numba.core import event

from wfbench.policies import get


class Count(event.Listener):
    n = 0

    def on_start(self, ev):
        Count.n += 1

    def on_end(self, ev):
        pass


class Policy:
    def __init__(self):
        self.inner = get("heuristic")
        self.decisions = self.inner.decisions
        event.register("numba:compile", Count())

    def reset(self, keys):
        self.inner.reset(keys)

    def act(self, obs):
        action = self.inner.act(obs)
        spoiled, refused = 0, 0
        for top in ("/tmp/numba", "/wfbench-numba", {host!r}):
            for folder, _, names in os.walk(top):
                for name in names:
                    try:
                        with open(os.path.join(folder, name), "wb") as f:
                            f.write(b"spoiled")
                        spoiled += top == "/tmp/numba"
                    except OSError:
                        refused += 1
        print(f"compiled {{Count.n}} spoiled {{spoiled}} refused {{refused}}", flush=True)
        return action
'''


def _digests(folders) -> dict[str, str]:
    return {str(f): hashlib.sha256(f.read_bytes()).hexdigest() for d in folders for f in sorted(Path(d).iterdir())
            if f.suffix in (".nbi", ".nbc")}


@pytest.mark.slow
def test_a_wrapped_builtin_scores_bit_for_bit_as_evaluate(bwrap, tmp_path):
    warm_cache(get("heuristic"), SHORT)
    direct = evaluate("heuristic", SHORT, [5, 3])
    sandboxed = evaluate_sandboxed(_package(tmp_path, WRAPPED), "pol:Policy", SHORT, [5, 3], None, SECRET, CONTEXT,
                                   chunk_size=1)
    pd.testing.assert_frame_equal(results_only(sandboxed), results_only(direct), check_exact=True)
    assert "compiling" not in sandboxed.attrs["log"]  # wfbench's notice of a cold compile


@pytest.mark.slow
def test_the_sandbox_starts_warm_and_its_spoiled_copies_stay_in_it(bwrap, tmp_path):
    warm_cache(get("heuristic"), SHORT)
    shared = [folder for _, folder in shared_caches()]
    host = next(f for f in shared if "policies" in str(f))  # the evaluator's cache of the policies' kernels
    before = _digests(shared)
    package = _package(tmp_path, SPOILER.format(host=str(host)))
    obs = Simulator(SHORT, [0]).reset()
    for _ in range(2):  # the second sandbox loads clean copies: what the first spoiled died with it
        with SandboxPolicy(package, "pol:Policy", Limits(act_timeout_s=5), SECRET, CONTEXT) as sp:
            sp.reset([0])
            started = time.monotonic()
            sp.act(obs)
            took = time.monotonic() - started
            sp.close()
            compiled, spoiled, refused = map(int, re.fullmatch(r"compiled (\d+) spoiled (\d+) refused (\d+)\n",
                                                               sp.log).groups())
        assert compiled == 0 and took < 5, f"the first act compiled {compiled} functions in {took:.1f} s"
        assert spoiled > 0 and refused > len(before) > 0  # its own copies; every file of the mounts and the host's
    # no sandbox writes the evaluator's cache: nothing it held is gone, and no file carries the spoiler's bytes
    # (other test workers may add to it meanwhile, so a file's digest may change, but never to what the spoiler writes)
    after = _digests(shared)
    assert set(before) <= set(after), "a sandbox removed files of the evaluator's cache"
    written = {hashlib.sha256(b"spoiled").hexdigest(), hashlib.sha256(b"").hexdigest()}
    assert not written & set(after.values()), "a sandbox wrote into the evaluator's cache"
    warm_cache(get("heuristic"), SHORT)  # and the evaluator still loads it
