"""What the sandbox keeps from a policy beyond its files and network (issue #42).

- The act clock is the evaluator's: a frame the policy writes (the old PAUSE of numba's
  compiling) neither stops nor resets it. numba's compiling of the policy's own kernels
  gets a warm-up allowance the evaluator grants: the first ``reset`` and the first ``act``
  of a sandbox, ``Limits.warmup_s``; any later call has ``act_timeout_s``, compiling or not.
- A seccomp filter (libseccomp's own bindings) refuses the system calls that reach the
  kernel's riskier corners: ptrace, mount, umount2, new namespaces (unshare, setns, clone
  with a CLONE_NEW* flag, clone3), bpf, perf_event_open, the key calls and userfaultfd. Each
  call is made with arguments the kernel would refuse with another error (EINVAL, EFAULT,
  EBADF, ESRCH, ...) or accept, so only the filter answers EPERM (ENOSYS for clone3, which
  makes the C library fall back to clone, whose flags the filter can read).
"""

from __future__ import annotations

import errno
import json
import platform
import textwrap
import time

import numpy as np
import pytest

from wfbench.harness.isolation.sandbox import Limits, SandboxError, SandboxPolicy, SandboxUnavailable, check_sandbox
from wfbench.harness.isolation.wire import MAGIC

from .test_sandbox import CONTEXT, HOSTILE, SECRET, _fails, _hostile, _package

# -- the act clock -------------------------------------------------------------------------------------------------

PAUSE = MAGIC + bytes([8]) + (0).to_bytes(2, "little") + (0).to_bytes(8, "little")  # the old PAUSE frame, whole
WRITE_THEN_SLEEP = """
import json
os.write(json.loads(sys.argv[-1])["out"], {frame!r})
time.sleep(8)
"""


@pytest.mark.slow
@pytest.mark.parametrize("frame", [PAUSE, PAUSE[:3]], ids=["pause-frame", "half-a-frame"])
def test_a_frame_of_the_policy_does_not_stop_the_act_clock(bwrap, tmp_path, frame):
    limits = Limits(act_timeout_s=2, warmup_s=2, memory_mb=1024, wall_time_s=60, start_timeout_s=30)
    started = time.monotonic()
    err = _fails(_hostile(tmp_path, WRITE_THEN_SLEEP.format(frame=frame)), limits)
    took = time.monotonic() - started
    assert took < 7, f"the sandbox lived {took:.1f} s: the frame held the clock"
    if frame == PAUSE:  # no such kind any more: the protocol is broken at once
        assert err.reason.startswith("the policy's process broke the protocol during act: unknown message kind 8"), \
            err.reason
    else:  # the reader waits for the rest of the frame, on the evaluator's clock
        assert err.reason == "act took longer than 2 s (the act time limit)", err.reason


# the first act compiles total(float64[:]) (numba's start-up with it: about 0.4 s); a later one compiles it for seven
# other dtypes, about 50 ms each once numba is warm: one alone came within 0.05 s on a fast machine
LATER_DTYPES = "(np.int8, np.int16, np.int32, np.uint8, np.uint16, np.uint32, np.float32)"
COMPILING = HOSTILE.format(body="        for dtype in ((np.float64,) if self.calls == 0 else " + LATER_DTYPES + "):\n"
                                "            total(np.arange(100, dtype=dtype))\n"
                                "        self.calls += 1") \
    .replace("self.keys = [int(k) for k in seeds]", "self.keys = [int(k) for k in seeds]\n        self.calls = 0") \
    + textwrap.dedent('''

        from numba import njit


        @njit
        def total(x):
            s = 0.0
            for i in range(x.shape[0]):
                s += np.sin(x[i]) * np.cos(x[i])
            return s
        ''')


@pytest.mark.slow
def test_compiling_is_allowed_in_the_first_act_only(bwrap, tmp_path):
    limits = Limits(act_timeout_s=0.05, warmup_s=60, memory_mb=2048, start_timeout_s=60)
    with SandboxPolicy(_package(tmp_path, COMPILING), "pol:Policy", limits, SECRET, CONTEXT) as sp:
        sp.reset([1])
        started = time.monotonic()
        sp.act({"x": np.zeros(1)})  # compiles total(float64[:]): longer than 0.05 s, within the warm-up allowance
        assert time.monotonic() - started > 0.05
        with pytest.raises(SandboxError, match=r"^act took longer than 0.05 s \(the act time limit\)$"):
            sp.act({"x": np.zeros(1)})  # compiles total for seven more dtypes: a later call has no allowance


def test_limits_refuse_a_warmup_below_the_act_timeout():
    with pytest.raises(ValueError, match="warmup_s = 1 is below act_timeout_s = 10"):
        Limits(warmup_s=1)


# -- the seccomp filter --------------------------------------------------------------------------------------------

# x86_64 and aarch64 numbers: (name, number, arguments); each argument list makes the kernel refuse the call with
# another errno than EPERM (or accept it: unshare(0)) when no filter is in the way
CLONE_THREAD = 0x10000
NS_FLAGS = {"NEWNS": 0x20000, "NEWCGROUP": 0x02000000, "NEWUTS": 0x04000000, "NEWIPC": 0x08000000,
            "NEWUSER": 0x10000000, "NEWPID": 0x20000000, "NEWNET": 0x40000000}
NUMBERS = {
    "x86_64": {"ptrace": 101, "mount": 165, "umount2": 166, "unshare": 272, "setns": 308, "clone": 56, "clone3": 435,
               "bpf": 321, "perf_event_open": 298, "keyctl": 250, "add_key": 248, "request_key": 249,
               "userfaultfd": 323, "shmget": 29},
    "aarch64": {"ptrace": 117, "mount": 40, "umount2": 39, "unshare": 97, "setns": 268, "clone": 220, "clone3": 435,
                "bpf": 280, "perf_event_open": 241, "keyctl": 219, "add_key": 217, "request_key": 218,
                "userfaultfd": 282, "shmget": 194},
}
CALLS = [
    ("ptrace", (0xDEADBEEF, 0, 0, 0)),  # an unknown request on pid 0: ESRCH/EIO
    ("mount", (1, 1, 1, 0, 0)),  # bad pointers: EFAULT
    ("umount2", (1, 0xFFFF0000)),  # unknown flags: EINVAL
    ("unshare", (0,)),  # nothing: succeeds
    ("unshare", (NS_FLAGS["NEWUSER"],)),  # a user namespace: succeeds (or EPERM as root without CAP_SYS_ADMIN)
    ("setns", (-1, 0)),  # EBADF
    *[("clone", (flag | CLONE_THREAD, 0, 0, 0, 0)) for flag in NS_FLAGS.values()],  # THREAD without SIGHAND: EINVAL
    ("clone3", (0, 0)),  # a size of 0: EINVAL
    ("bpf", (0xFFFF, 0, 0)),  # an unknown command
    ("perf_event_open", (0, 0, -1, -1, 0)),  # no attributes: EFAULT
    ("keyctl", (0xDEAD, 0, 0, 0, 0)),  # an unknown operation: EOPNOTSUPP
    ("add_key", (0, 0, 0, 0, 0)),  # EFAULT
    ("request_key", (0, 0, 0, 0)),  # EFAULT
    ("userfaultfd", (0x1 | 0x8000,)),  # user-mode-only and an unknown flag: EINVAL
    ("shmget", (0, 0, 0o1000)),  # a private segment of 0 bytes: EINVAL
]

SPY = '''
import ctypes, json

libc = ctypes.CDLL(None, use_errno=True)
libc.syscall.restype = ctypes.c_long


def call(number, args):
    ctypes.set_errno(0)
    r = libc.syscall(ctypes.c_long(number), *[ctypes.c_long(a) for a in args])
    return [int(r), ctypes.get_errno()]


class Policy:
    decisions = ("dispatch",)

    def __init__(self):
        found = [[name, list(args), call(number, args)] for name, number, args in {calls!r}]
        print("SECCOMP " + json.dumps(found), flush=True)
        raise RuntimeError("reported")

    def reset(self, keys):
        pass

    def act(self, obs):
        return {{}}
'''


def test_the_seccomp_filter_refuses_the_kernels_riskier_calls(bwrap, tmp_path):
    arch = platform.machine()
    if arch not in NUMBERS:
        pytest.skip(f"the test knows the system call numbers of x86_64 and aarch64, not {arch}")
    calls = [(name, NUMBERS[arch][name], args) for name, args in CALLS]
    package = _package(tmp_path, SPY.format(calls=calls))
    with pytest.raises(SandboxError) as info:
        SandboxPolicy(package, "pol:Policy", None, SECRET, CONTEXT)
    line = next(x for x in info.value.log.splitlines() if x.startswith("SECCOMP "))
    found = json.loads(line[len("SECCOMP "):])
    wrong = [(name, args, f"returned {r}, errno {errno.errorcode.get(e, e)}")
             for name, args, (r, e) in found if (r, e) != (-1, errno.ENOSYS if name == "clone3" else errno.EPERM)]
    assert not wrong, wrong


def test_no_seccomp_bindings_no_sandbox(monkeypatch):
    from wfbench.harness.isolation import sandbox

    monkeypatch.setattr(sandbox, "SECCOMP_PYTHONS", ("/nonexistent/python3",))
    sandbox._seccomp_program.cache_clear()
    sandbox._trial.cache_clear()
    try:
        with pytest.raises(SandboxUnavailable) as info:
            check_sandbox()
    finally:
        sandbox._seccomp_program.cache_clear()
        sandbox._trial.cache_clear()
    reason = str(info.value)
    assert "\n" not in reason and "libseccomp's Python bindings" in reason and "apt-get install python3-seccomp" \
        in reason, reason


def test_threads_still_start_under_the_filter(bwrap, tmp_path):
    """glibc's pthread_create tries clone3 first: ENOSYS sends it to clone, which the filter lets through."""
    body = """
    import threading
    box = []
    t = threading.Thread(target=lambda: box.append(1))
    t.start(); t.join()
    raise RuntimeError(f"threads ran: {len(box)}")
    """
    assert _fails(_hostile(tmp_path, body)).reason.startswith("the policy raised RuntimeError: threads ran: 1 ")
