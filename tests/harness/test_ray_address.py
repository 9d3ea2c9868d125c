"""A Ray address where no cluster answers fails at once, in one line naming it and what to check (issue #35).

Ray itself retries such an address for minutes, printing a warning every few seconds; the
backends and IMPALA's actors probe a ``HOST:PORT`` first (``wfbench.harness.backends.join_ray``).
"""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("ray")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("command", [
    ["evaluate", "--policy", "heuristic", "--scenario", "small", "--seeds", "2", "--backend", "ray", "--no-progress"],
    ["train", "--algo", "impala", "--scenario", "small", "--model", "tiny", "--steps", "64", "--no-progress"],
], ids=["evaluate", "train-impala"])
@pytest.mark.slow
def test_an_address_where_nothing_listens_fails_in_one_line(command, tmp_path):
    port = free_port()
    extra = ["--run-dir", str(tmp_path / "run")] if command[0] == "train" else []
    r = subprocess.run([sys.executable, "-m", "wfbench.cli", *command, *extra, "--address", f"127.0.0.1:{port}"],
                       capture_output=True, text=True, timeout=30, cwd=tmp_path)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith(f"wfbench: error: no Ray cluster answers at 127.0.0.1:{port}")
    assert f"ray start --head --port {port}" in lines[0]


def test_join_ray_names_the_address_and_leaves_ray_uninitialized():
    import ray

    from wfbench.harness.backends import ClusterError, join_ray

    port = free_port()
    with pytest.raises(ClusterError, match=rf"^no Ray cluster answers at 127\.0\.0\.1:{port} "):
        join_ray(f"127.0.0.1:{port}")
    assert not ray.is_initialized()


@pytest.fixture
def token_cluster():
    """A Ray head that wants token authentication, started in the foreground and stopped with its process group.

    Its own temporary folder keeps it out of the way of a local Ray that another test starts meanwhile (the
    address file a plain ``ray.init()`` looks for is in the default one), and stopping its process group (never
    ``ray stop``, which would stop every Ray of the machine) ends it alone.
    """
    import os
    import shutil
    import signal
    import tempfile
    import time

    port, token = free_port(), "a" * 32
    temp = tempfile.mkdtemp(prefix="wfr", dir="/tmp")  # short: Ray's socket paths live under it
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": token}
    ray_cli = str(Path(sys.executable).with_name("ray"))
    head = subprocess.Popen([ray_cli, "start", "--head", "--block", "--port", str(port), "--num-cpus", "1",
                             "--include-dashboard=false", "--disable-usage-stats", "--temp-dir", temp],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 90
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert head.poll() is None and time.monotonic() < deadline, "the Ray head did not start"
                time.sleep(0.5)
        yield port, token
    finally:
        os.killpg(head.pid, signal.SIGTERM)
        try:
            head.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(head.pid, signal.SIGKILL)
            head.wait(10)
        shutil.rmtree(temp, ignore_errors=True)


@pytest.mark.slow
def test_a_token_the_cluster_refuses_fails_in_one_line_at_once(token_cluster, tmp_path):
    import os
    import time

    port, token = token_cluster
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": "b" * 32}  # not the cluster's
    start = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "wfbench.cli", "evaluate", "--policy", "heuristic", "--scenario",
                        "small", "--seeds", "2", "--backend", "ray", "--no-progress", "--address",
                        f"127.0.0.1:{port}"], capture_output=True, text=True, timeout=60, cwd=tmp_path, env=env)
    took = time.monotonic() - start
    ours = [ln for ln in r.stderr.splitlines() if ln.startswith("wfbench:")]
    assert r.returncode == 2, r.stderr
    # Ray's C++ client logs one warning of its own before the answer; ours is the one line that says what to do
    assert len(ours) == 1 and ours[0] == r.stderr.strip().splitlines()[-1], r.stderr
    assert ours[0].startswith(f"wfbench: error: the Ray cluster at 127.0.0.1:{port} refused this machine's "
                              "authentication token"), ours[0]
    assert "RAY_AUTH_TOKEN" in ours[0] and took < 30, (took, r.stderr)
    env["RAY_AUTH_TOKEN"] = token  # the right token joins and runs
    ok = subprocess.run([sys.executable, "-m", "wfbench.cli", "evaluate", "--policy", "heuristic", "--scenario",
                         "small", "--seeds", "2", "--backend", "ray", "--no-progress", "--address",
                         f"127.0.0.1:{port}"], capture_output=True, text=True, timeout=180, cwd=tmp_path, env=env)
    assert ok.returncode == 0 and "heuristic" in ok.stdout, ok.stderr
