"""Response times of the hosted board's server (``wfbench serve``): uploads and pages, p50 and p99.

Serves a fresh board under uvicorn on 127.0.0.1 (one process, as ``wfbench serve`` runs
it) and measures, from a pool of client threads over HTTP:

- uploads (``POST /api/submissions``): each a new small package on the development phase,
  ``--concurrency`` at a time (the board's writes are serialized on SQLite);
- dedupe hits: the same packages again (200, nothing stored);
- pages: the home page, a submission's JSON and page, and a track's board as JSON and
  HTML over ``--entries`` finished entries (the board renders the local report's page,
  figures included, on every request).

The rows of the finished entries are made up (no policy runs): this measures the web
server and the database, not an evaluation. Times are printed, never asserted.

Usage::

    python -m benchmarks.bench_server --uploads 64 --concurrency 8 --entries 8
    python -m benchmarks.bench_server --db postgresql+psycopg://wfbench:wfbench@127.0.0.1:5432/bench
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import numpy as np
from wfbench.leaderboard.board import queue
from wfbench.leaderboard.board.db import Board
from wfbench.leaderboard.board.worker import aggregate
from wfbench.leaderboard.server.app import create_app
from wfbench.leaderboard.tracks import scenario_track

from tests.leaderboard.live_server import LiveServer  # a test helper: run from the checkout with python -m
from wfbench.core.config import ScenarioConfig
from wfbench.harness.budget import machine, machine_line
from wfbench.harness.isolation.package import archive

TRACK = scenario_track(name="bench", config=ScenarioConfig.preset("small"), public_seeds=tuple(range(1000, 1050)),
                       test_seeds=tuple(range(50)), description="the benchmark's track (no policy runs)")


def make_package(i: int, size: int) -> bytes:
    """A package with ``size`` bytes of incompressible weights, distinct per ``i``."""
    rng = np.random.default_rng(i)
    members = {"wfbench-policy.json": json.dumps({"entry": "pol:Policy", "format": 1}).encode(),
               "pol.py": f"class Policy:  # {i}\n    decisions = ()\n".encode(), "weights.bin": rng.bytes(size)}
    return archive(list(members.items()))


def finish_all(board: Board, entries: int) -> None:
    """Finish the first ``entries`` queued jobs with made-up rows (NSW differs per submission), fail the others."""
    done = 0
    while (c := queue.claim(board.engine, "bench", lease_s=600)) is not None:
        sub = board.submission(c.submission_id)
        if done >= entries:
            queue.finish(c, "failed", reason="left out by the benchmark")
            continue
        done += 1
        nsw = 0.3 + 0.01 * (sub.id % 40)
        queue.write_rows(c, [{"scenario": sc, "seed_index": i, "seed": s, "workforce_cost": 10.0, "utilization": 0.6,
                              "downtime": 0.1, "nsw": nsw + 0.001 * i, "episode_length": 800, "invalid_actions": 0,
                              "decision_ms_p50": 0.1, "decision_ms_p99": 0.3, "cpu_s": 1.0, "machine": "bench"}
                             for sc, i, s in board.units(sub)])
        queue.finish(c, "done", result=aggregate(board.rows(sub.id)), log="made up\n")


def timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return (time.perf_counter() - t) * 1000.0


def report(label: str, ms: list[float]) -> None:
    a = np.asarray(ms)
    print(f"{label:<34s} n={len(a):4d}  p50 {np.percentile(a, 50):8.1f} ms  p99 {np.percentile(a, 99):8.1f} ms  "
          f"max {a.max():8.1f} ms")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", default=None, help="database URL (default: a SQLite file in a temporary folder)")
    p.add_argument("--uploads", type=int, default=64, help="new packages uploaded")
    p.add_argument("--concurrency", type=int, default=8, help="client threads")
    p.add_argument("--package-kb", type=int, default=256, help="size of each package's weights")
    p.add_argument("--entries", type=int, default=8, help="finished entries on the board the pages show")
    p.add_argument("--pages", type=int, default=20, help="requests per page kind")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        board = Board(args.db or str(Path(tmp) / "bench.sqlite"), tracks={TRACK.name: TRACK})
        board.create()
        tokens = [board.add_account(f"bench{i}-{time.time_ns()}") for i in range(args.concurrency)]
        packages = [make_package(i, args.package_kb * 1024) for i in range(args.uploads)]
        print(f"machine: {machine_line(machine())}")
        print(f"database: {board.engine.url.render_as_string(hide_password=True)}; {args.uploads} uploads of "
              f"{len(packages[0]) / 1024:.0f} kB, {args.concurrency} at a time")
        with LiveServer(create_app(board)) as url, httpx.Client(base_url=url, timeout=120) as http:
            def post(i: int) -> float:
                headers = {"Authorization": f"Bearer {tokens[i % len(tokens)]}"}
                return timed(lambda: http.post("/api/submissions", headers=headers, data={"track": TRACK.name},
                                               files={"package": ("p.zip", packages[i], "application/zip")}
                                               ).raise_for_status())

            with ThreadPoolExecutor(args.concurrency) as pool:
                start = time.perf_counter()
                report("upload (new package)", list(pool.map(post, range(args.uploads))))
                print(f"{'':34s} {args.uploads / (time.perf_counter() - start):.1f} uploads/s")
                report("upload (dedupe hit)", list(pool.map(post, range(args.uploads))))
            finish_all(board, args.entries)
            first = board.submissions(TRACK.name, "dev")[0].id
            for label, path in (("GET / (home page)", "/"), ("GET /api/submissions/{id}", f"/api/submissions/{first}"),
                                ("GET /submissions/{id} (page)", f"/submissions/{first}"),
                                ("GET /api/board/{track} (JSON)", f"/api/board/{TRACK.name}?phase=dev"),
                                ("GET /board/{track} (HTML)", f"/board/{TRACK.name}?phase=dev")):
                report(label, [timed(lambda p=path: http.get(p).raise_for_status()) for _ in range(args.pages)])
        board.close()


if __name__ == "__main__":
    main()
