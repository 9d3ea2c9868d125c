"""Same numbers before and after a refactor: capture what users see, then compare two captures bit for bit.

A refactor that moves code must not move a number. This script records, through the
public interfaces only (``wfbench.evaluate``, the ``wfbench`` command line), so that it
runs unchanged on the code before and after:

- the per-seed rows (every KPI, utility and counter) of every registered policy (the
  composites, the oracles, the tuned files and the shipped networks) on every scenario
  of suite-v1: ``--seeds`` seeds each (default 10), ``city`` 1 seed, the planners
  and the hindsight oracle at most 4 (they look over the whole future), and the references that play the
  lookaheads (``oracle-v2``, ``oracle-v3``, ``oracle-rollout``) at most 4 on the lookaheads' scenarios only;
- each deployable lookahead (``wfbench.policies.registry.lookahead_names()``, asked for by
  name and so not among the registered names above) on ``LOOKAHEAD_SCENARIOS``, one seed:
  a rollout costs seconds to minutes an episode, and on ``city`` hours;
- the reproduced tables (``wfbench reproduce table3|table2|gap``, CSV files);
- short training runs of each trainer (PPO joint, dispatch and independent agents,
  IMPALA, hindsight learning): the weights of ``latest.pt`` and ``best.pt``, the
  history of public scores, and ``config.json`` less the git commit.

Usage (the capture of the old code from a checkout of it, e.g. a git worktree)::

    git worktree add /tmp/old HEAD~1
    python benchmarks/identity_check.py capture /tmp/before --checkout /tmp/old
    python benchmarks/identity_check.py capture /tmp/after
    python benchmarks/identity_check.py compare /tmp/before /tmp/after

``--checkout`` imports ``wfbench`` and the folders it installs as ``wfbench.policies``,
``wfbench.solvers`` and ``wfbench.leaderboard`` from that checkout (a ``PYTHONPATH``
alone does not: an editable install maps those three to its own checkout, so a
change under ``policies/`` was compared with itself), and the capture fails if they do
not come from there. ``--scenarios`` narrows a capture while working; the check a
commit quotes covers them all (about an hour on the 2-core VM). ``compare`` prints every
difference and exits 1 if there is one; a training history or a run's settings that record
more in the second capture, every value of the first equal, are listed apart and are not
differences.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

SLOW = {"oracle-planner", "oracle-dispatch", "oracle"}  # fewer seeds: they look over the whole future
SLOW_SEEDS = 4
# the references that play the lookaheads (references v2's and v3's best in hindsight, the hindsight rollout): on the
# lookaheads' scenarios only, at SLOW_SEEDS; on paper-64 a seed of oracle-v2 plays every rollout, MPC and search
# preset, and a capture that gave it 10 seeds of every scenario was still on paper-64 after some 70 minutes (a loaded
# VM); oracle-v3, left out of this set until 2026-12-03, would have played them on large-v1 and city for hours
WITH_LOOKAHEADS = {"oracle-v2", "oracle-v3", "oracle-rollout"}
ONE_SEED = {"city-v1"}  # 1,000 facilities and people: a seed of a network is minutes here
# the lookaheads' scenarios: on these one seed of all eight takes about 4 minutes (the 100 ms preset on paper-64
# 1.7 of them, a loaded VM); on large-v1 that preset alone is some 10 minutes an episode
LOOKAHEAD_SCENARIOS = ("small-v1", "paper-64-v1")
MAPPED = {"wfbench": "wfbench", "wfbench.policies": "policies", "wfbench.solvers": "solvers",
          "wfbench.leaderboard": "leaderboard"}


def use_checkout(root: Path) -> None:
    """Import wfbench and its three mapped packages from the checkout ``root`` (before anything imports them)."""
    import importlib.util

    if any(name in sys.modules for name in MAPPED):
        raise RuntimeError("use_checkout must run before wfbench is imported")

    class Finder:
        @staticmethod
        def find_spec(fullname, path=None, target=None):
            if fullname not in MAPPED:
                return None
            folder = root / MAPPED[fullname]
            return importlib.util.spec_from_file_location(fullname, folder / "__init__.py",
                                                          submodule_search_locations=[str(folder)])

    sys.meta_path.insert(0, Finder)
    os.environ["PYTHONPATH"] = os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)


def from_checkout(root: Path) -> str | None:
    """:func:`use_checkout` of ``root``, then import ``wfbench.policies``: None, or why it did not come from there."""
    root = Path(root).resolve()
    use_checkout(root)
    import wfbench.policies

    where = Path(wfbench.policies.__file__).resolve()
    return None if where.is_relative_to(root) else f"wfbench.policies imports from {where}, not from {root}"


def policies() -> list[str]:
    """Every registered policy of the code being captured (its registry's names)."""
    from wfbench.policies.registry import names

    return names()


def lookaheads() -> list[str]:
    """The deployable lookaheads of the code being captured (none in code from before issue #43)."""
    from wfbench.policies import registry

    return list(getattr(registry, "lookahead_names", list)())


def scenarios() -> list[str]:
    from wfbench.scenarios import get_suite

    return [s.id for s in get_suite("suite-v1").scenarios]

TRAIN = {  # short runs of every trainer: a few updates, two public evaluations
    "ppo-joint": ["--algo", "ppo", "--variant", "joint", "--steps", "1536", "--num-envs", "8", "--num-steps", "64",
                  "--eval-every", "1", "--eval-seeds", "public:2", "--model", "tiny", "--scenario", "small"],
    "ppo-dispatch": ["--algo", "ppo", "--variant", "dispatch", "--steps", "1024", "--num-envs", "4",
                     "--num-steps", "64", "--eval-every", "2", "--eval-seeds", "public:2", "--model", "tiny",
                     "--scenario", "small"],
    "ppo-independent": ["--algo", "ppo", "--agents", "independent", "--steps", "1024", "--num-envs", "4",
                        "--num-steps", "64", "--eval-every", "2", "--eval-seeds", "public:2", "--model", "tiny",
                        "--scenario", "small"],
    # sync: the actor and the learner in turn, deterministic; the default async mode's policy lag depends on the
    # timing of its two threads (wfbench/train/impala.py), so two captures on a loaded machine differ by design
    "impala": ["--algo", "impala", "--steps", "1024", "--num-envs", "4", "--num-steps", "32", "--eval-every", "4",
               "--eval-seeds", "public:2", "--model", "tiny", "--scenario", "small", "--set", "mode=sync"],
    "hindsight": ["--algo", "hindsight", "--steps", "192", "--num-envs", "2", "--eval-every", "1",
                  "--eval-seeds", "public:2", "--model", "tiny", "--scenario", "small"],
}


def save_rows(df, path: Path) -> None:
    """The per-seed rows less the budget columns, measurements that differ run to run (an older wfbench has none)."""
    df = df.drop(columns=["decision_ms_p50", "decision_ms_p99", "cpu_s"], errors="ignore")
    df.attrs.pop("budget", None)
    df.to_pickle(path)


def capture(out: Path, seeds: int, only: set[str] | None, chosen: list[str] | None = None,
            names: list[str] | None = None) -> None:
    import pandas as pd
    import wfbench.policies
    import wfbench.solvers

    import wfbench
    from wfbench.cli import main as cli

    out.mkdir(parents=True, exist_ok=True)
    for mod in (wfbench, wfbench.policies, wfbench.solvers):
        print(f"{mod.__name__} from {Path(mod.__file__).parent}", flush=True)
    if only is None or "evaluate" in only:
        for scenario in chosen or scenarios():
            for name in names or policies():
                if name in WITH_LOOKAHEADS and scenario not in LOOKAHEAD_SCENARIOS:
                    continue
                t0 = time.perf_counter()
                n = 1 if scenario in ONE_SEED else min(seeds, SLOW_SEEDS) if name in SLOW | WITH_LOOKAHEADS else seeds
                save_rows(wfbench.evaluate(name, scenario, list(range(n))),
                          out / f"eval__{scenario}__{name}.pkl")
                print(f"evaluate {name:22s} {scenario:14s} {n} seeds {time.perf_counter() - t0:6.1f} s", flush=True)
    if only is None or "lookahead" in only:
        for scenario in [x for x in LOOKAHEAD_SCENARIOS if chosen is None or x in chosen]:
            for name in [x for x in lookaheads() if names is None or x in names]:
                t0 = time.perf_counter()
                save_rows(wfbench.evaluate(name, scenario, [0]),
                          out / f"eval__{scenario}__{name}.pkl")
                print(f"lookahead {name:22s} {scenario:14s} 1 seed {time.perf_counter() - t0:6.1f} s", flush=True)
    if only is None or "reproduce" in only:
        for target, runs in (("table3", "10"), ("table2", "4"), ("gap", "4")):
            t0 = time.perf_counter()
            code = cli(["reproduce", target, "--out", str(out / f"reproduce-{target}"), "--runs", runs,
                        "--backend", "serial", "--no-progress"])
            print(f"reproduce {target} exit {code} {time.perf_counter() - t0:6.1f} s", flush=True)
    if only is None or "train" in only:
        import torch

        for name, flags in TRAIN.items():
            t0 = time.perf_counter()
            run = out / f"train-{name}"
            cli(["train", *flags, "--device", "cpu", "--run-dir", str(run), "--no-progress", "--no-tensorboard"])
            for ckpt in ("latest.pt", "best.pt"):
                if (run / ckpt).exists():
                    c = torch.load(run / ckpt, map_location="cpu", weights_only=False)
                    torch.save({"model": c["model"], "history": c.get("history")}, run / f"{ckpt}.model")
            cfg = json.loads((run / "config.json").read_text())
            for key in ("git_commit", "run_dir"):  # the commit and the capture's folder, not the code's doing
                cfg.pop(key, None)
            (run / "config.clean.json").write_text(json.dumps(cfg, indent=1, sort_keys=True))
            print(f"train {name} {time.perf_counter() - t0:6.1f} s", flush=True)
    pd.Series({"python": sys.version}).to_json(out / "meta.json")


def _same(a, b) -> bool:
    import numpy as np
    import torch

    if isinstance(a, torch.Tensor):
        return isinstance(b, torch.Tensor) and a.dtype == b.dtype and a.shape == b.shape and torch.equal(a, b)
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return isinstance(b, list | tuple) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float):
        return (np.isnan(a) and np.isnan(b)) or a == b
    return a == b


_MISSING = object()


def _common(x, y) -> tuple[bool, list[str]]:
    """Whether a training history ``y`` holds every entry of ``x`` with the same values, and the keys only ``y`` has.

    A newer trainer may record more per evaluation (e.g. the selection mode); that moves no
    number of before, so it is reported apart from a difference.
    """
    if not (isinstance(x, list) and isinstance(y, list) and len(x) == len(y)):
        return _same(x, y), []
    new: set[str] = set()
    for ex, ey in zip(x, y, strict=True):
        if not (isinstance(ex, dict) and isinstance(ey, dict)):
            if not _same(ex, ey):
                return False, []
            continue
        if not ex.keys() <= ey.keys() or not all(_same(ex[k], ey[k]) for k in ex):
            return False, []
        new |= ey.keys() - ex.keys()
    return True, sorted(new)


def compare(a: Path, b: Path) -> int:
    import pandas as pd
    import torch

    diffs, added, checked = [], [], 0
    for fa in sorted(a.rglob("*")):
        if not fa.is_file() or fa.name == "meta.json":
            continue
        rel = fa.relative_to(a)
        fb = b / rel
        if rel.parts[0].startswith("train-") and fa.suffix not in (".model",) and fa.name != "config.clean.json":
            continue  # raw checkpoints hold the commit and paths; their models are compared through .model
        if not fb.exists():
            diffs.append(f"{rel}: missing in {b}")
            continue
        checked += 1
        if fa.suffix == ".pkl":
            x, y = pd.read_pickle(fa), pd.read_pickle(fb)
            try:
                pd.testing.assert_frame_equal(x, y, check_exact=True)
            except AssertionError as exc:
                diffs.append(f"{rel}: {str(exc).splitlines()[0]}")
        elif fa.suffix == ".model":
            x, y = torch.load(fa, weights_only=False), torch.load(fb, weights_only=False)
            if not _same(x["model"], y["model"]):
                diffs.append(f"{rel}: weights differ")
            history, new = _common(x.get("history"), y.get("history"))
            if not history:
                diffs.append(f"{rel}: history differs")
            elif new:
                added.append(f"{rel}: history records {new} too")
        elif fa.name == "config.clean.json":
            x, y = json.loads(fa.read_text()), json.loads(fb.read_text())
            changed = sorted(k for k in x.keys() if x[k] != y.get(k, _MISSING))
            if changed:
                diffs.append(f"{rel}: keys differ: {changed}")
            if y.keys() - x.keys():
                added.append(f"{rel}: settings {sorted(y.keys() - x.keys())} too")
        elif fa.read_bytes() != fb.read_bytes():
            diffs.append(f"{rel}: bytes differ")
    for d in diffs:
        print(d)
    for n in added:
        print(f"added (every value of before equal): {n}")
    print(f"{checked} files compared, {len(diffs)} differences, {len(added)} with fields only the second records")
    return 1 if diffs else 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("out", type=Path)
    c.add_argument("--seeds", type=int, default=10, help="test seeds 0..N-1 per policy and scenario (default 10)")
    c.add_argument("--only", default=None, help="comma-separated parts: evaluate, lookahead, reproduce, train")
    c.add_argument("--scenarios", default=None, help="comma-separated suite-v1 ids (default: every scenario)")
    c.add_argument("--policies", default=None, help="comma-separated registered names for the evaluate and lookahead "
                   "parts (default: every one); a change that decides only some policies' episodes is checked on "
                   "those, over every scenario")
    c.add_argument("--checkout", type=Path, default=None, help="capture the code of this checkout (a git worktree "
                   "of the commit before), not the installed one")
    d = sub.add_parser("compare")
    d.add_argument("a", type=Path)
    d.add_argument("b", type=Path)
    args = p.parse_args()
    if args.cmd == "capture":
        if args.checkout is not None:
            wrong = from_checkout(args.checkout)
            if wrong:
                print(f"identity_check: {wrong}", file=sys.stderr)
                return 2
        chosen = [x.strip() for x in args.scenarios.split(",")] if args.scenarios else None
        names = [x.strip() for x in args.policies.split(",")] if args.policies else None
        capture(args.out, args.seeds, set(args.only.split(",")) if args.only else None, chosen, names)
        return 0
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
