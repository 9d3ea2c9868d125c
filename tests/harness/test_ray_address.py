"""A Ray address where no cluster answers fails at once, in one line naming it and what to check (issue #35).

Ray itself retries such an address for minutes, printing a warning every few seconds; the
backends and IMPALA's actors probe a ``HOST:PORT`` first (``wfbench.harness.backends.join_ray``).
"""

from __future__ import annotations

import socket
import subprocess
import sys

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
