"""The suite's reference campaign: a world's candidates of the replaying references, then their oracles.

``oracle-v2`` and ``oracle-v3`` (docs/hindsight.md, "Versioned references") read their candidates' totals from
suite pieces made by clean commits and replays the episodes the runner recorded. On the
eight held-out worlds at 50 test seeds its candidates cost tens of CPU hours on the 2-core
VM, more than one session (the training worlds, whose v1 reference is below
``scalefree-general`` on ``table2-g256-f25-s5-v1``, about 7 more), so this script plays them
as a queue of small jobs that any session resumes: per world and chunk of ten seeds, each candidate
(``wfbench reproduce suite --seeds A-B --no-members --policies P --scenarios S``; a training seed
``METHOD#seedK``, a candidate from v3 on, is played so too), then each oracle (``--references``,
default ``v2 v3``) on that chunk once its own candidates are done (``$WFBENCH_ORACLE_PIECES``
naming the run, so a piece from other code fails in one line). A network's total depends on its batch, so the candidates
and the oracle play the same chunks; and the oracle, played on the machine that just played
the chunk's candidates, finds their recorded episodes instead of playing its winners again.

Each worker claims the next job whose inputs are done (a lock file per job under
``--state``), runs it niced from ``--checkout`` (a clean worktree with its own virtual
environment: a piece records its commit, and one made from a dirty tree is not read), and
marks it done. Stopped at any point, a job's piece keeps what earlier chunks made
(``reproduce suite`` extends pieces by the seeds they lack); started again, the queue goes
on where it stopped; on a fresh machine ``run`` first copies the committed run's pieces (and the
suite's bound) into ``--out``, so only what no commit holds is played. ``collect`` copies the
finished pieces into the committed run.

    git worktree add /tmp/clean HEAD && python -m venv /tmp/clean/.venv && ...   # a clean checkout
    python benchmarks/reference_campaign.py plan --out runs/reference-v2
    python benchmarks/reference_campaign.py run --out runs/reference-v2 --checkout /tmp/clean --workers 2
    python benchmarks/reference_campaign.py collect --out runs/reference-v2 --into docs/results/reference-v2

Run this file from the checkout whose committed run is current (main), ``--checkout`` naming the
clean worktree that plays: ``--into`` defaults to this file's own checkout, and a worktree of an
older commit may still hold pieces a later commit dropped (on 2026-11-30 an older worktree's
script copied 30 MPC pieces made before the MPC's fix, and an ``oracle-v2`` piece that read
them, back into a run; they were found by their provenance and played again).

``--policies A,B`` plays those policies' pieces instead, in the same chunks and with no oracle
(a lookahead registered after ``oracle-v2``'s candidates were fixed, for the frontier), e.g.
``run --out runs/playout --policies search-scalefree-general-playout --into docs/results/suite-v1-50``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from wfbench.scenarios.pieces import piece_folder, piece_path

ROOT = Path(__file__).resolve().parents[1]
WORLDS = ("novice-64-v1", "churn-64-v1", "slow-64-v1", "real-nyc-v1", "table2-g128-f50-s25-v1",
          "table2-g32-f100-s25-v1", "large-v1", "city-v1")  # the held-out split, cheapest first
CHUNK = 10


def worlds_of(names: list[str]) -> list[str]:
    """``--worlds`` as scenario ids in order: ``heldout`` and ``train`` stand for their splits' worlds.

    SystemExit of one line naming what is allowed for a name that is neither.
    """
    from wfbench.scenarios import get_suite

    suite = get_suite("suite-v1")
    split = {"heldout": list(WORLDS), "train": suite.ids("train")}
    out = []
    for n in names:
        if n not in split and n not in suite.ids():
            raise SystemExit(f"reference_campaign: unknown world {n!r}; allowed: heldout, train or a scenario id of "
                             f"suite-v1 ({', '.join(suite.ids())})")
        out += split.get(n, [n])
    return list(dict.fromkeys(out))


def replaying_oracles() -> set[str]:
    """The oracles of the replaying references (``references.REPLAYING``): the jobs that read the run's pieces."""
    from wfbench.policies.oracle.references import ORACLES, REPLAYING

    return {n for n, r in ORACLES.items() if r in REPLAYING}


def oracle_of(ref: str) -> str:
    """The registry's best-in-hindsight oracle of the reference ``ref`` (``v2`` -> ``oracle-v2``)."""
    from wfbench.policies.oracle.references import ORACLES

    return next(n for n, r in ORACLES.items() if r == ref)


def candidates(ref: str = "v2") -> list[str]:
    """The candidates of the reference ``ref`` that are not compiled (its oracle plays those itself in seconds)."""
    import warnings

    from wfbench.policies.oracle.references import REFERENCES

    from wfbench import policies

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return [n for n in REFERENCES[ref] if not getattr(policies.get(n), "compiled", False)]


def played(args: argparse.Namespace) -> list[str]:
    """What each chunk's jobs play: ``--policies``, else every reference's candidates (:func:`candidates`).

    A method's training seeds play as one job (``A#seed0,A#seed1,...``: one process start for
    four networks that play a chunk in seconds on most worlds), each still its own piece.
    """
    if args.policies:
        return args.policies.split(",")
    out: list[str] = []
    for n in dict.fromkeys(n for ref in args.references for n in candidates(ref)):
        method = n.split("#seed")[0] if "#seed" in n else None
        if method and out and out[-1].startswith(f"{method}#seed"):
            out[-1] += f",{n}"
        else:
            out.append(n)
    return out


def policies_of(job_policy: str) -> list[str]:
    """The policies a job plays: one, or a method's training seeds (:func:`played`)."""
    return job_policy.split(",")


def jobs(worlds: list[str], cands: list[str], seeds: int,
         oracles: dict[str, list[str]] | None = None) -> list[tuple[tuple[str, str, int, int], list]]:
    """(world, policy, first seed, last seed) in order, each with the jobs it waits for (an oracle's chunk).

    ``oracles``: oracle -> its candidates among ``cands``; each plays a chunk once they have.
    """
    out = []
    for w in worlds:
        for a in range(0, seeds, CHUNK):
            b = min(a + CHUNK, seeds) - 1
            out += [((w, p, a, b), []) for p in cands]
            for oracle, mine in (oracles or {}).items():
                out.append(((w, oracle, a, b), [(w, p, a, b) for p in cands if set(policies_of(p)) & set(mine)]))
    return out


def oracles_of(args: argparse.Namespace) -> dict[str, list[str]]:
    """The oracles the queue plays (none with ``--policies``), each with its non-compiled candidates."""
    return {} if args.policies else {oracle_of(ref): candidates(ref) for ref in args.references}


def queue_of(args: argparse.Namespace) -> list[tuple[tuple[str, str, int, int], list]]:
    return jobs(args.worlds, played(args), args.seeds, oracles_of(args))


def kept(args: argparse.Namespace) -> set[str]:
    """The policies whose pieces the campaign copies in and out."""
    return {*(n for p in played(args) for n in policies_of(p)), *oracles_of(args)}


def name(job: tuple[str, str, int, int]) -> str:
    return f"{job[0]}__{job[1]}__{job[2]}-{job[3]}"


def covered(out: Path, job: tuple[str, str, int, int]) -> bool:
    """Whether the run's piece of each of the job's policies on its world holds its seeds."""
    metas = [piece_path(out, p, job[0]).with_suffix(".json") for p in policies_of(job[1])]
    return all(m.exists() and set(range(job[2], job[3] + 1)) <= set(json.loads(m.read_text())["seeds"])
               for m in metas)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
        return True
    except (ProcessLookupError, PermissionError):
        return False


def _state(state: Path, out: Path, job: tuple[str, str, int, int]) -> str:
    """done, running, failed or todo; a claim whose process is gone is judged by the piece.

    A job whose process exited with an error is failed and stays so (``--state``'s ``.failed``
    file: remove it to play the job again). A claim whose process is gone without a word (the
    machine stopped under it) is done when the piece holds the job's seeds, else the job is to
    play again: the claim is removed.
    """
    base = state / name(job)
    if base.with_suffix(".done").exists() or covered(out, job) and not base.with_suffix(".running").exists():
        return "done"
    if base.with_suffix(".failed").exists():
        return "failed"
    run = base.with_suffix(".running")
    if run.exists():
        words = run.read_text().split()
        if len(words) < 2 or _alive(int(words[1])):
            return "running"
        if covered(out, job):
            run.rename(base.with_suffix(".done"))
        else:
            run.unlink(missing_ok=True)
        return _state(state, out, job)
    return "todo"


def work(args: argparse.Namespace) -> None:
    """One worker: claim the next job whose inputs are done, play it, mark it; until none is left or STOP exists."""
    out, state, checkout = Path(args.out).resolve(), Path(args.state).resolve(), Path(args.checkout).resolve()
    state.mkdir(parents=True, exist_ok=True)
    queue = queue_of(args)
    log = state / f"worker-{args.worker}.log"
    while not (state / "STOP").exists():
        states = {name(j): _state(state, out, j) for j, _ in queue}
        ready = [j for j, needs in queue if states[name(j)] == "todo" and all(states[name(n)] == "done" for n in needs)]
        if not ready:
            if all(s in ("done", "failed") for s in states.values()):
                return
            time.sleep(30)
            continue
        job = ready[0]
        try:
            fd = os.open(state / f"{name(job)}.running", os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            continue
        os.write(fd, args.worker.encode())
        os.close(fd)
        env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
        if job[1] in replaying_oracles():
            env["WFBENCH_ORACLE_PIECES"] = str(out)
        cmd = ["nice", "-n", "5", str(checkout / ".venv" / "bin" / "wfbench"), "reproduce", "suite", "--out",
               str(out), "--seeds", f"{job[2]}-{job[3]}", "--backend", "serial", "--no-members", "--no-progress",
               "--policies", job[1], "--scenarios", job[0]]
        start = time.time()
        with open(log, "a") as f:
            f.write(f"\n### {time.strftime('%H:%M:%S')} {' '.join(cmd)}\n")
            f.flush()
            child = subprocess.Popen(cmd, cwd=checkout, env=env, stdout=f, stderr=subprocess.STDOUT)
            (state / f"{name(job)}.running").write_text(f"{args.worker} {child.pid}")
            rc = child.wait()
            f.write(f"### rc={rc} {time.time() - start:.0f} s\n")
        (state / f"{name(job)}.running").rename(state / f"{name(job)}.{'done' if rc == 0 else 'failed'}")


def decided_by(policy: str) -> list[str]:
    """The repository files that decide ``policy``'s episodes (an oracle: its candidates' and its own)."""
    import warnings

    from wfbench.policies.oracle.episodes import decisive_files
    from wfbench.policies.oracle.references import ORACLES, REFERENCES

    from wfbench import policies

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        names = [*REFERENCES[ORACLES[policy]], policy] if policy in replaying_oracles() else [policy]
        return sorted({f for n in names for f in decisive_files(policies.get(n))})


def stale(meta: Path, checkout: Path, files: list[str]) -> str | None:
    """Why a piece was made by other code than ``checkout``'s in ``files`` (a part's commit differs there), or None."""
    d = json.loads(meta.read_text())
    for part in d.get("parts") or [d]:
        commit = (part.get("provenance") or {}).get("commit")
        if not commit:
            return "a part records no commit"
        diff = subprocess.run(["git", "diff", "--name-only", commit, "HEAD", "--", *files], cwd=checkout,
                              capture_output=True, text=True)
        if diff.returncode or diff.stdout.strip():
            return f"{(diff.stdout.split() or ['its commit'])[0]} differs between {commit[:7]} and the checkout"
    return None


def start_from(out: Path, committed: Path, worlds: list[str], policies: set[str], checkout: Path) -> int:
    """Copy into ``out`` the committed pieces of ``policies`` it lacks, and each world's bound (a fresh machine).

    A piece whose deciding files differ between the commit of one of its parts and
    ``checkout``'s HEAD is not copied (its seeds are played again), and said so.
    """
    copied = 0
    files: dict[str, list[str]] = {}
    by_folder = {piece_folder(p): p for p in policies}  # a training seed's folder: METHOD_seedK
    for meta in sorted(m for m in (committed / "cache").glob("*/*.json") if m.parent.name in by_folder):
        dest = out / "cache" / meta.parent.name
        if (dest / meta.name).exists():
            continue
        policy = by_folder[meta.parent.name]
        why = stale(meta, checkout, files.setdefault(policy, decided_by(policy)))
        if why:
            print(f"not copied: {meta.parent.name}/{meta.name}: {why}", flush=True)
            continue
        copy_piece(meta, dest)
        copied += 1
    for meta in (ROOT / "docs/results/suite-v1-50/cache/bound" / f"{w}.json" for w in worlds):
        dest = out / "cache" / "bound"
        if meta.exists() and not (dest / meta.name).exists():
            copy_piece(meta, dest)
            copied += 1
    return copied


def copy_piece(meta: Path, dest: Path) -> None:
    """Copy a piece (its ``.json`` and ``.csv``) into the folder ``dest``."""
    dest.mkdir(parents=True, exist_ok=True)
    for f in (meta, meta.with_suffix(".csv")):
        shutil.copy2(f, dest / f.name)


def run(args: argparse.Namespace) -> None:
    """Start ``--workers`` workers (one a core) and wait for them, after copying what a fresh ``--out`` lacks."""
    copied = start_from(Path(args.out), Path(args.into), args.worlds, kept(args), Path(args.checkout).resolve())
    print(f"{copied} committed pieces copied into {args.out}", flush=True)
    procs = [subprocess.Popen([sys.executable, __file__, "work", "--worker", f"w{i}", *sys.argv[2:]])
             for i in range(args.workers)]
    for p in procs:
        p.wait()


def plan(args: argparse.Namespace) -> None:
    """What is left, per world: jobs, and the estimate of wfbench's plan for the candidates' missing pieces."""
    out, state = Path(args.out).resolve(), Path(args.state).resolve()
    queue = queue_of(args)
    for w in args.worlds:
        mine = [j for j, _ in queue if j[0] == w]
        left = [j for j in mine if _state(state, out, j) != "done"] if state.exists() else mine
        print(f"{w}: {len(mine) - len(left)} of {len(mine)} jobs done")
    cmd = [str(Path(sys.executable).parent / "wfbench"), "reproduce", "suite", "--plan", "--no-members",
           "--no-progress", "--out", str(out), "--seeds", f"0-{args.seeds - 1}", "--policies", ",".join(played(args)),
           "--scenarios", ",".join(args.worlds)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    print(done.stdout or done.stderr)


def collect(args: argparse.Namespace) -> None:
    """Copy the run's pieces of the candidates and oracles (or ``--policies``') no job plays into ``--into``."""
    out, state, into = Path(args.out).resolve(), Path(args.state).resolve(), Path(args.into)
    keep = {piece_folder(p) for p in kept(args)}
    busy = {(w, piece_folder(n)) for w, p, *_ in (f.name.split("__") for f in state.glob("*.running"))
            for n in policies_of(p)} if state.exists() else set()
    copied = []
    for meta in sorted((out / "cache").glob("*/*.json")):
        policy, world = meta.parent.name, meta.stem
        if policy not in keep or (world, policy) in busy:
            continue
        dest = into / "cache" / policy
        same = all((dest / f.name).exists() and (dest / f.name).read_bytes() == f.read_bytes()
                   for f in (meta, meta.with_suffix(".csv")))
        if not same:
            copy_piece(meta, dest)
            copied.append(f"{policy}/{world}")
    print(f"{len(copied)} pieces copied into {into}: {' '.join(copied)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("action", choices=["plan", "run", "work", "collect"])
    ap.add_argument("--out", required=True, help="the campaign's suite run folder (its cache/ holds the pieces)")
    ap.add_argument("--state", default=None, help="the queue's lock files and logs (default: OUT/queue)")
    ap.add_argument("--checkout", default=str(ROOT), help="a clean checkout with its .venv to play from "
                    "(default: this one; pieces from a dirty tree are not read by the oracles)")
    ap.add_argument("--workers", type=int, default=2, help="run: workers, one a core (default 2)")
    ap.add_argument("--worker", default="w0", help=argparse.SUPPRESS)
    ap.add_argument("--worlds", nargs="+", default=["heldout"],
                    help="worlds of the suite, in order: scenario ids, or heldout and train for a split's, the "
                    "held-out ones cheapest first (default: heldout)")
    ap.add_argument("--policies", default=None, help="comma-separated registered policies to play instead of "
                    "the references' candidates, with no oracle (e.g. a lookahead for the frontier)")
    ap.add_argument("--references", nargs="+", default=["v2", "v3"], help="the replaying references whose candidates "
                    "and oracle each chunk plays, in order (default: v2 v3)")
    ap.add_argument("--seeds", type=int, default=50, help="test seeds 0..N-1 (default 50)")
    ap.add_argument("--into", default=str(ROOT / "docs/results/reference-v2"), help="the committed run: run starts "
                    "from its pieces, collect copies into it (default: docs/results/reference-v2)")
    args = ap.parse_args()
    args.state = args.state or str(Path(args.out) / "queue")
    args.worlds = worlds_of(args.worlds)
    from wfbench.policies.oracle.references import REPLAYING

    if bad := [r for r in args.references if r not in REPLAYING]:
        raise SystemExit(f"reference_campaign: --references {' '.join(bad)} is not a replaying reference; allowed: "
                         f"{', '.join(sorted(REPLAYING))}")
    {"plan": plan, "run": run, "work": work, "collect": collect}[args.action](args)


if __name__ == "__main__":
    main()
