"""``wfbench worker --server DBURL``: evaluate the hosted board's queued submissions in the sandbox.

A shell over :func:`wfbench.leaderboard.board.worker.run_worker`, which holds the loop
(docs/leaderboard.md, "The hosted leaderboard"); imported inside ``run`` so ``wfbench
--help`` stays fast.
"""

from __future__ import annotations

from wfbench.cli.common import Parser, positive, seconds


def add_parser(sub) -> None:
    p: Parser = sub.add_parser(
        "worker", help="evaluate a hosted board's queued submissions in the bubblewrap sandbox (any number, on any "
                       "host that reaches the database)")
    p.add_argument("--server", required=True, metavar="DBURL",
                   help="the board's database: a SQLite file or postgresql+psycopg://USER:PASSWORD@HOST/DB")
    p.add_argument("--id", dest="worker_id", default=None, help="this worker's name in the leases (default host:pid)")
    p.add_argument("--lease", type=seconds, default=None,
                   help="seconds a claim holds without a heartbeat (default 60; "
                        "wfbench.leaderboard.board.queue.DEFAULT_LEASE_S)")
    p.add_argument("--once", action="store_true", help="stop when the queue is empty")
    p.add_argument("--job-time", type=seconds, default=None, metavar="S",
                   help="worker seconds one upload may use per scenario of its track, over every attempt (default "
                        "3600; wfbench.leaderboard.board.worker.JOB_TIME_S)")
    limits = p.add_argument_group("the sandbox's limits per submission (default: "
                                  "wfbench.harness.isolation.sandbox.Limits)")
    limits.add_argument("--memory", type=positive, default=None, metavar="MB",
                        help="address space of the policy's process (default 4096)")
    limits.add_argument("--act-timeout", type=seconds, default=None, metavar="S",
                        help="each reset and act call (default 10)")
    limits.add_argument("--wall-time", type=seconds, default=None, metavar="S",
                        help="the policy's time over one chunk of episodes (default 1800)")
    limits.add_argument("--tmp", type=positive, default=None, metavar="MB", help="the size of its /tmp (default 64)")


LIMIT_FLAGS = {"memory": "memory_mb", "act_timeout": "act_timeout_s", "wall_time": "wall_time_s", "tmp": "tmp_mb"}


def run(args) -> int:
    from wfbench.harness.isolation.sandbox import Limits
    from wfbench.leaderboard.board.queue import DEFAULT_LEASE_S
    from wfbench.leaderboard.board.worker import JOB_TIME_S, run_worker

    chosen = {field: getattr(args, flag) for flag, field in LIMIT_FLAGS.items() if getattr(args, flag) is not None}
    return run_worker(args.server, args.worker_id, args.lease or DEFAULT_LEASE_S, args.once,
                      limits=Limits(**chosen) if chosen else None, job_time_s=args.job_time or JOB_TIME_S)
