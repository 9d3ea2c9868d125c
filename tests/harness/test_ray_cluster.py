"""``--backend ray`` on a local 2-node cluster (issue #35): the same rows as this process, and a node lost mid-run.

The cluster is Ray's own test cluster (:class:`ray.cluster_utils.Cluster`): a head and a
second node, each a raylet with its own workers and object store on this machine, one CPU
each, so the chunks spread over both. The second node is killed while chunks run on it;
Ray retries the lost tasks on the head (its default ``max_retries``), and the rows are
those of a serial run, bit for bit.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import Execution
from wfbench.harness.budget import results_only
from wfbench.harness.evaluation import evaluate

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
SLOW = ScenarioConfig.preset("small").replace(name="slow-small", horizon=60)
SEEDS = list(range(8))
RESETS = "WFBENCH_TEST_RAY_RESETS"  # a file Patient notes each chunk's start in


class Patient:
    """Dispatches nobody and thinks 20 ms a step: a chunk of one seed lasts over a second, so a node dies mid-chunk."""

    decisions = ("dispatch", "workforce", "positioning")

    def reset(self, seeds):
        log = os.environ.get(RESETS)
        if log:  # one line per chunk started: the node it runs on, then its seeds
            import ray

            node = ray.get_runtime_context().get_node_id() if ray.is_initialized() else "driver"
            with open(log, "a") as f:
                f.write(f"{node} " + " ".join(str(int(s)) for s in seeds) + "\n")

    def act(self, obs):
        time.sleep(0.02)
        B, M, N1 = obs["dispatch_mask"].shape
        return {"dispatch": np.full((B, M), N1 - 1), "workforce": np.zeros(B, dtype=np.int64),
                "positioning": np.full((B, 2, M), 0.5)}


@pytest.fixture
def cluster(monkeypatch, tmp_path):
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    # the nodes' workers unpickle Patient by reference: they import this module from the repository
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    monkeypatch.setenv(RESETS, str(tmp_path / "resets.txt"))
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    node = c.add_node(num_cpus=1)
    c.wait_for_nodes()
    try:
        yield c, node
    finally:
        ray.shutdown()
        c.shutdown()


def on_cluster(c) -> Execution:
    """Every seed its own Ray task on the test's cluster."""
    return Execution(backend="ray", address=c.address, workers=len(SEEDS))


def _alive_nodes() -> int:
    import ray

    return sum(1 for n in ray.nodes() if n["Alive"])


def test_two_nodes_give_the_serial_rows(cluster):
    c, _ = cluster
    serial = evaluate(Patient(), SLOW, SEEDS)
    spread = evaluate(Patient(), SLOW, SEEDS, execution=on_cluster(c))
    assert _alive_nodes() == 2
    assert spread.attrs["budget"]["workers"] == len(SEEDS)
    assert results_only(spread).equals(results_only(serial))


def test_a_node_lost_mid_run_is_retried_and_changes_nothing(cluster):
    c, node = cluster
    serial = evaluate(Patient(), SLOW, SEEDS)
    resets = Path(os.environ[RESETS])
    resets.write_text("")
    removed = {}

    def kill_second_node():
        # as soon as a chunk starts on the second node (each lasts over a second), however slow its start was
        deadline = time.monotonic() + 120
        while node.node_id not in resets.read_text() and time.monotonic() < deadline:
            time.sleep(0.05)
        c.remove_node(node, allow_graceful=False)
        removed["at"] = time.monotonic()

    started = time.monotonic()
    killer = threading.Thread(target=kill_second_node)
    killer.start()
    spread = evaluate(Patient(), SLOW, SEEDS, execution=on_cluster(c))
    finished = time.monotonic()
    killer.join()
    assert started < removed["at"] < finished, "the node must die while the run goes on"
    assert results_only(spread).equals(results_only(serial))
    started_chunks = resets.read_text().splitlines()
    assert len(started_chunks) > len(SEEDS), f"no chunk was run again after the node died: {started_chunks}"
    deadline = time.monotonic() + 60  # the head's health checks declare the node dead within seconds
    while _alive_nodes() != 1:
        assert time.monotonic() < deadline, "the head still counts the killed node alive after 60 s"
        time.sleep(0.5)
