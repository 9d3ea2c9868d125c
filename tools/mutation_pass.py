"""A quick mutation pass over the simulator core and the built-in policies: does the suite notice?

    .venv/bin/python tools/mutation_pass.py                    # every mutant, on a copy of HEAD
    .venv/bin/python tools/mutation_pass.py --worktree         # on a copy of the working tree
    .venv/bin/python tools/mutation_pass.py --only obs-util-window pol-letgo-threshold
    .venv/bin/python tools/mutation_pass.py --list             # the mutants, and whether each applies
    .venv/bin/python tools/mutation_pass.py --add tests/test_new.py   # HEAD plus a test not committed yet
    .venv/bin/python tools/mutation_pass.py --workdir /tmp/wfmut ...  # keep the folder: reruns reuse its cache

Each mutant is one small planted change (a flipped comparison, an off-by-one, a swapped
argument, a changed constant) given as the exact text it replaces, so it survives code
moving between lines and files (a mutant may name several files and alternative texts).
The checkout is never touched: the sources are copied to a temporary folder (``git
archive`` of ``--rev``, or the working tree's tracked and untracked files with
``--worktree``), each mutant is planted there, the test groups run there with
``PYTHONPATH`` on the copy and their own numba cache, and the file is restored.

A mutant is *killed* when a test group fails (the first group that fails is reported:
``existing`` is the suite before issue #11 part 5, ``blind-spots`` the tests added for
it) or times out, *survived* when every group passes, *stale* when its text is not in
the copy (the code changed: update the mutant), *invalid* when it does not compile
(a name the module lacks: fix the mutant). ``docs/testing.md`` records the last
pass.

numba's cache checks only the file of a cached function. Where the copy has no
dependency-aware cache locator (``wfbench/core/jit.py``), the entries of every module that
imports the mutated file (transitively) are deleted before each run, so no mutant runs
stale machine code. The whole-episode rollout takes minutes to compile, so the groups
leave out the tests that run it (``evaluate``, ``run_batch``).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PACKAGES = ("wfbench", "policies", "solvers")

# Test groups, run in this order with -x; tests that compile the rollout are left out.
ROLLOUT_TESTS = ("test_heuristic_beats_random_on_paper_64", "test_fixed_workforce_keeps_headcount",
                 "test_stochastic_variants_differ_by_seed_but_repeat")
GROUPS = {
    "existing": ["tests/core/test_reference_differential.py", "tests/core/test_handworked.py",
                 "tests/core/test_config.py", "tests/contracts/test_bad_input.py", "tests/core/test_properties.py",
                 "tests/core/test_heat_placement.py", "tests/policies/test_policies.py",
                 "-k", " and ".join(f"not {name}" for name in ROLLOUT_TESTS)],
    "blind-spots": ["tests/core/test_observe.py", "tests/core/test_schedule.py", "tests/core/test_trace.py",
                    "tests/core/test_metrics.py", "tests/core/test_workforce_threshold.py",
                    "tests/policies/test_policy_kernels.py"],
}

D, O, K = (("wfbench/core/dynamics.py", "wfbench/core/placement.py"), ("wfbench/core/observe.py",),
           ("policies/kernels/dispatch.py", "policies/kernels/workforce.py", "policies/kernels/positioning.py"))


@dataclass(frozen=True)
class Mutant:
    name: str
    files: tuple[str, ...]
    edits: tuple[tuple[str, str], ...]  # alternatives (old, new): the first old text found (once) is replaced
    what: str


def m(name: str, files: tuple[str, ...] | str, old: str, new: str, what: str, *alternatives: tuple[str, str]) -> Mutant:
    return Mutant(name, (files,) if isinstance(files, str) else files, ((old, new), *alternatives), what)


MUTANTS = [
    # -- schedules, trace, parameters (plain Python) ----------------------------------------------
    m("sched-seasonal-period", "wfbench/core/schedule.py", "np.sin(2.0 * np.pi * (t / self.period",
      "np.sin(np.pi * (t / self.period", "seasonal period doubled (planted in issue #11)"),
    m("sched-default-period", "wfbench/core/schedule.py", "period: float = 200.0", "period: float = 100.0",
      "default seasonal period 100"),
    m("sched-phase", "wfbench/core/schedule.py", "(t / self.period + self.phase)", "((t + self.phase) / self.period)",
      "phase in steps instead of periods"),
    m("sched-drift-end", "wfbench/core/schedule.py", "t / max(horizon, 1)", "t / max(horizon + 1, 1)",
      "drift reaches its end one step late"),
    m("sched-amplitude-bound", "wfbench/core/schedule.py", "0.0 <= self.amplitude < 1.0",
      "0.0 <= self.amplitude <= 1.0",
      "amplitude 1 accepted (a zero rate)"),
    m("sched-piecewise-side", "wfbench/core/schedule.py", 'side="right") - 1', 'side="left") - 1',
      "piecewise value starts a step late"),
    m("trace-arrival-at-0", "wfbench/core/trace.py", "rate[0] = 0.0", "rate[0] = rate[1]", "arrivals at step 0"),
    m("trace-lifetime-mean", "wfbench/core/trace.py", "life_mean = max(c.initial_facilities, 1) * c.churn_interval",
      "life_mean = max(c.initial_facilities, 1) * c.churn_interval / 2", "facility lifetimes halved"),
    m("trace-arrival-lifetime", "wfbench/core/trace.py", "arr_t + _lifetimes(arr_rng, A, life_mean)",
      "arr_t + _lifetimes(arr_rng, A, c.churn_interval)", "arrivals' lifetimes of the wrong mean"),
    m("trace-initial-facilities", "wfbench/core/trace.py", "fac0_active[: c.initial_facilities] = True",
      "fac0_active[: max(0, c.initial_facilities - 1)] = True", "one initial facility short"),
    m("trace-initial-personnel", "wfbench/core/trace.py", "per0_active[: c.initial_personnel] = True",
      "per0_active[1 : c.initial_personnel] = True", "one initial person short"),
    m("trace-level-probs", "wfbench/core/trace.py", "p=np.asarray(c.level_probs)",
      "p=np.asarray(c.level_probs)[[1, 0, 2]]",
      "initial levels drawn with swapped probabilities"),
    m("trace-y-by-width", "wfbench/core/trace.py", "fac0_y = fac_rng.integers(0, c.grid_height, size=M)",
      "fac0_y = fac_rng.integers(0, c.grid_width, size=M)", "initial facility rows drawn over the width"),
    m("config-max-cost", "wfbench/core/config.py", "self.max_personnel * max(self.level_salaries)",
      "self.max_personnel * min(self.level_salaries)", "u_WC scaled by the lowest salary"),
    m("params-placement", "wfbench/core/state.py", 'placement=0 if c.placement == "argmax" else 1',
      'placement=1 if c.placement == "argmax" else 0', "argmax and sample placement swapped"),
    m("params-hazard", "wfbench/core/state.py", "request_hazard=c.request_schedule.multipliers",
      "request_hazard=c.churn_schedule.multipliers", "failures follow the churn schedule"),
    # -- dynamics -------------------------------------------------------------------------------------
    m("dyn-onboarding-end", D, "st == ONBOARDING and ready[b, p] <= t", "st == ONBOARDING and ready[b, p] < t",
      "onboarding a step longer"),
    m("dyn-notice-returning", D, "leave[b, p] <= t and (st == IDLE or st == RETURNING)",
      "leave[b, p] <= t and st == IDLE", "a returning person under notice stays"),
    m("dyn-exit-step", D, "if fac_leave[b, f] <= t:", "if fac_leave[b, f] < t:", "facility exits a step late"),
    m("dyn-failure-first-step", D, "fac_ok_since[b, f] < t:", "fac_ok_since[b, f] <= t:",
      "failure clock runs in the step of a repair"),
    m("dyn-exit-cancels-job", D, "_person_goes_home(b, p, S)  # the job is cancelled", "pass  # the job is cancelled",
      "exit does not send the assignee home"),
    m("dyn-arrival-slot", D, "slot = f\n                break", "slot = f", "arrival into the highest free slot",
      ("slot = f\n            break", "slot = f")),
    m("dyn-request-visits", D, "S.fac_visits[b, f] = 0\n    S.counters[b, C_REQUESTS] += 1",
      "S.counters[b, C_REQUESTS] += 1", "a new request keeps the visit count"),
    m("dyn-zero-weights", D, "if total <= 0.0:", "if total < 0.0:", "all-zero weights are not 'no preference'"),
    m("dyn-release-ties", D, "if h > best_h:", "if h >= best_h:", "let-go ties to the highest slot"),
    m("dyn-release-min", D, "retained_headcount(b, S) <= P.min_personnel", "retained_headcount(b, S) < P.min_personnel",
      "let go down to min_personnel - 1"),
    m("dyn-hire-delay", D, "S.per_ready[b, slot] = t + P.hire_delay", "S.per_ready[b, slot] = t + P.hire_delay - 1",
      "onboarding a step short"),
    m("dyn-fire-delay", D, "S.per_leave[b, best] = S.t[b] + P.fire_delay",
      "S.per_leave[b, best] = S.t[b] + P.fire_delay + 1", "notice a step long"),
    m("dyn-duplicate", D, "if dispatched[b, p] == t:", "if dispatched[b, p] == t - 1:", "duplicate dispatch not seen"),
    m("dyn-dispatch-assigned", D, "fac_down[b, f] and fac_assigned[b, f] < 0)", "fac_down[b, f])",
      "dispatch to an assigned request"),
    m("dyn-dispatchable", D, "return (status == IDLE or status == RETURNING) and leave < 0",
      "return status == IDLE and leave < 0", "returning people not dispatchable"),
    m("dyn-releasable", D, "return status >= IDLE and leave < 0", "return status > IDLE and leave < 0",
      "idle people not releasable"),
    m("dyn-hire-levels", D, "if workforce >= 1 and workforce <= 3:", "if workforce >= 1 and workforce <= 2:",
      "expert hire ignored"),
    m("dyn-move-exact", D, "if abs(dx) <= budget:", "if abs(dx) < budget:", "an exact move does not arrive"),
    m("dyn-fix-level", D, "P.level_mult[S.per_level[b, p]]", "P.level_mult[1]", "repair ignores the level"),
    # (t - 1 instead is equivalent: the clock is first spent at t + 1 either way)
    m("dyn-repair-clock", D, "S.fac_ok_since[b, f] = t\n        S.counters[b, C_REPAIRS]",
      "S.fac_ok_since[b, f] = t + 1\n        S.counters[b, C_REPAIRS]",
      "failure clock starts two steps after a repair"),
    m("dyn-work-returning", D, "elif st == RETURNING:\n            work = np.uint8(1)",
      "elif st == RETURNING:\n            work = np.uint8(0)", "returning is not work"),
    m("dyn-pur-onboarded", D, "if st >= IDLE:\n                pur +=", "if st >= ONBOARDING:\n                pur +=",
      "onboarding people counted in PUR"),
    m("dyn-upur-band", D, "(max(target, 1.0 - target) - tolerance)", "(max(target, 1.0 - target))",
      "u_PUR scaled without the tolerance"),
    m("dyn-nsw-root", D, "THIRD = 1.0 / 3.0", "THIRD = 0.5", "NSW a square root"),
    m("dyn-log-headcount", D, "np.log(head) if head > 0", "np.log(head + 1) if head > 0", "log_headcount off by one"),
    m("dyn-u-cost-column", D, "row[K_UWC] = u_wc", "row[K_UWC] = u_afd", "u_cost column holds u_downtime"),
    m("dyn-totals", D, "totals[b, k] += row[k]", "totals[b, k] = row[k]", "episode means are the last step"),
    # -- observations ------------------------------------------------------------------------------
    m("obs-util-window", O, "S.per_sum[b, p] / max(1, min(W, t - since))",
      "S.per_sum[b, p] / max(1, min(W + 1, t - since))", "utilization feature window (planted in issue #11)"),
    m("obs-window-constant", O, "W = P.window", "W = 50", "feature windows fixed at the default 50"),
    m("obs-downtime-window", O, "max(1, min(W, t - S.fac_since[b, f]))", "max(1, min(W + 1, t - S.fac_since[b, f]))",
      "downtime feature window"),
    m("obs-requesting", O, "O.requesting[b, f] = 1 if (down and a < 0) else 0", "O.requesting[b, f] = 1 if down else 0",
      "assigned requests shown as open"),
    m("obs-can-release", O, "can_release = kept > P.min_personnel", "can_release = kept >= P.min_personnel",
      "let-go allowed at min_personnel"),
    m("obs-heading", O, "= 1.0 if st == TO_FACILITY else 0.0", "= 1.0 if st == SERVICING else 0.0",
      "heading flag while servicing"),
    m("obs-busy", O, "1.0 if (st == TO_FACILITY or st == SERVICING) else 0.0", "1.0 if st == TO_FACILITY else 0.0",
      "servicing not busy"),
    m("obs-time", O, "t / P.horizon", "(t + 1) / P.horizon", "time fraction a step ahead"),
    m("obs-onboarding", O, "if st == ONBOARDING:\n            onb += 1", "if st == IDLE:\n            onb += 1",
      "onboarding global counts idle people"),
    m("obs-wc-global", O, "S.last[b, K_WC] / P.max_cost", "S.last[b, K_WC] / P.max_cost / 2", "WC global halved"),
    m("obs-noop-column", O, "O.dispatch_mask[b, f, N] = 1", "O.dispatch_mask[b, f, N] = 0", "no-op not allowed"),
    m("obs-hire-mask", O, "h = 1 if any_empty else 0", "h = 1", "hire allowed with no free slot"),
    # -- built-in policies ----------------------------------------------------------------------------
    m("pol-letgo-threshold", K, '"low": 0.45,', '"low": 0.5,', "let-go threshold (planted in issue #11)"),
    m("pol-letgo-threshold-down", K, '"low": 0.45,', '"low": 0.4,', "let-go threshold lowered"),
    m("pol-hire-threshold", K, '"high": 0.8,', '"high": 0.75,', "hire threshold"),
    m("pol-warmup", K, "if t < hp[HP_WARMUP] or t < S.cooldown_until[b]:\n        return 0\n    pur",
      "if t <= hp[HP_WARMUP] or t < S.cooldown_until[b]:\n        return 0\n    pur", "warm-up a step long"),
    m("pol-cooldown", K, "S.cooldown_until[b] = t + int(hp[HP_COOLDOWN])",
      "S.cooldown_until[b] = t + int(hp[HP_COOLDOWN]) + 1", "cooldown a step long"),
    m("pol-level-draw", K, "if x < w0 + w1:", "if x < w1:", "level draw"),
    m("pol-letgo-mask", K, "lv = _draw_level(u, hp, m[4], m[5], m[6])", "lv = _draw_level(u, hp, 1, 1, 1)",
      "let-go level ignores the mask"),
    m("pol-epsilon", K, '"epsilon": 0.02,', '"epsilon": 0.2,', "epsilon"),
    m("pol-nearest-ties", K, "if d < best:\n                    best = d\n                    bi = i",
      "if d <= best:\n                    best = d\n                    bi = i",
      "nearest dispatch ties to the last pair"),
    m("pol-nearest-from-home", K, "abs(O.personnel[b, p, 2] - O.facilities[b, f, 0]) + abs(O.personnel[b, p, 3]",
      "abs(O.personnel[b, p, 0] - O.facilities[b, f, 0]) + abs(O.personnel[b, p, 1]", "distance from home",
      ("abs(O.personnel[b, p, PER_X] - O.facilities[b, f, FAC_X])\n            + abs(O.personnel[b, p, PER_Y]",
       "abs(O.personnel[b, p, PER_HOME_X] - O.facilities[b, f, FAC_X])\n"
       "            + abs(O.personnel[b, p, PER_HOME_Y]")),
    m("pol-inverse-weight", K, "w[p] = 1.0 / (1.0 + _dist(O, b, f, p))", "w[p] = 1.0 / (1.0 + 2.0 * _dist(O, b, f, p))",
      "inverse-distance weight"),
    m("pol-random-noop", K, "* (n_free + 1))", "* n_free)", "random dispatch never picks the no-op"),
    m("pol-random-workforce", K, "t, 3, 0) * n)", "t, 3, 0) * (n - 1))", "random workforce never picks the last"),
    m("pol-spatial-letgo", K, "out[1, f] = 1.0 - out[0, f]", "out[1, f] = out[0, f]", "let-go map is the hire map"),
    m("pol-spatial-mix", K, "wr = hp[HP_REQW]\n    top = 0.0", "wr = 1.0\n    top = 0.0",
      "spatial demand ignores downtime"),
    m("pol-smoothing", K, '"smoothing": 0.01,', '"smoothing": 0.1,', "request-rate smoothing"),
    m("pol-onset", K, "new = 1.0 if (down == 1 and S.prev_down[b, f] == 0) else 0.0", "new = 1.0 if down == 1 else 0.0",
      "an ongoing request counted as new"),
    m("pol-spatial-scale", K, "out[0, f] = out[0, f] / top if top > 0.0 else 1.0",
      "out[0, f] = out[0, f] if top > 0.0 else 1.0", "hire map not scaled to its maximum"),
    m("pol-random-rows", K, "out[1, f] = uniform(key, STREAM_POLICY_POSITIONING, t, f, 2)",
      "out[1, f] = uniform(key, STREAM_POLICY_POSITIONING, t, f, 1)", "random positioning rows equal"),
]

# Modules whose constants compiled code freezes although they define no compiled function.
CONSTANT_MODULES = {"wfbench/core/state.py"}


def copy_sources(dst: Path, rev: str | None) -> None:
    if rev is not None:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", rev], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(dst)], input=archive, check=True)
        return
    listed = subprocess.run(["git", "-C", str(REPO), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                            check=True, capture_output=True).stdout.decode().split("\0")
    for rel in filter(None, listed):
        src = REPO / rel
        if src.is_file():
            (dst / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / rel)


def locate(src: Path, mutant: Mutant) -> tuple[str, str, str] | None:
    """(file, old, new) of the first alternative whose text occurs exactly once in one of the mutant's files."""
    for old, new in mutant.edits:
        for rel in mutant.files:
            path = src / rel
            if path.is_file() and path.read_text().count(old) == 1:
                return rel, old, new
    return None


def module_of(rel: str) -> str:
    return rel[:-3].replace("/", ".")


def importers(src: Path) -> dict[str, set[str]]:
    """Module -> modules of the project that import it at any level (scan of import lines)."""
    graph: dict[str, set[str]] = {}
    pattern = re.compile(rf"^\s*(?:from|import)\s+((?:{'|'.join(PACKAGES)})(?:\.\w+)*)", re.M)
    for pkg in PACKAGES:
        for path in (src / pkg).rglob("*.py"):
            mod = module_of(str(path.relative_to(src)))
            for imported in pattern.findall(path.read_text()):
                graph.setdefault(imported, set()).add(mod)
    return graph


def stale_cache_modules(src: Path, rel: str) -> set[str]:
    """Modules whose cached machine code may contain the mutated file's code or constants."""
    text = (src / rel).read_text()
    if "njit" not in text and rel not in CONSTANT_MODULES:
        return set()
    graph = importers(src)
    todo, seen = [module_of(rel)], {module_of(rel)}
    while todo:
        for mod in graph.get(todo.pop(), ()):
            if mod not in seen:
                seen.add(mod)
                todo.append(mod)
    return seen


def fresh_cache(base: Path, run: Path, modules: set[str]) -> None:
    """``run`` = the warm cache ``base`` without the entries of ``modules`` (numba names them dir/module.func-...)."""
    shutil.rmtree(run, ignore_errors=True)
    shutil.copytree(base, run)
    for mod in modules:
        pkg, _, name = mod.rpartition(".")
        for folder in run.glob(f"{pkg.split('.')[-1]}_*"):
            for entry in folder.glob(f"{name}.*"):
                entry.unlink()


def run_groups(src: Path, cache: Path, timeout: float) -> tuple[str, str]:
    """(outcome, detail): 'passed', or 'killed' by a group (its name and first failing test), or 'timeout'."""
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(cache), WFBENCH_CACHE_DIR=str(cache),
               PYTHONDONTWRITEBYTECODE="1")
    for group, args in GROUPS.items():
        paths = [a for a in args if a.startswith("tests/")]
        present = [a for a in args if not a.startswith("tests/") or (src / a).is_file()]
        if not any((src / p).is_file() for p in paths):
            continue
        cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "--no-header", *present]
        try:
            out = subprocess.run(cmd, cwd=src, env=env, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return "timeout", group
        if out.returncode != 0:
            failed = re.findall(r"^(?:FAILED|ERROR) (\S+)", out.stdout, re.M)
            where = f"{group}: {failed[0] if failed else out.stdout.strip().splitlines()[-1]}"
            if re.search(r"TypingError|NameError|SyntaxError", out.stdout):
                return "invalid", where  # the mutant does not compile: no test was needed to see it
            return "killed", where
    return "passed", ""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", default="HEAD", help="git revision to copy (default HEAD)")
    ap.add_argument("--worktree", action="store_true", help="copy the working tree instead (untracked files included)")
    ap.add_argument("--add", nargs="*", default=[], help="also copy these files of the working tree (new tests)")
    ap.add_argument("--only", nargs="*", help="run only these mutants")
    ap.add_argument("--list", action="store_true", help="list the mutants and whether each applies, run nothing")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per test group (default 900)")
    ap.add_argument("--json", default=None, help="also write the results here")
    ap.add_argument("--workdir", default=None,
                    help="work in this folder and keep it: a rerun reuses its warm numba cache (default: a temporary "
                         "one)")
    args = ap.parse_args()
    mutants = [mu for mu in MUTANTS if not args.only or mu.name in args.only]
    unknown = set(args.only or ()) - {mu.name for mu in MUTANTS}
    if unknown:
        ap.error(f"unknown mutant(s) {sorted(unknown)}; --list shows them")
    work = Path(args.workdir) if args.workdir else Path(tempfile.mkdtemp(prefix="wfbench-mutants-"))
    src, pristine, base, cache = work / "src", work / "pristine", work / "cache-base", work / "cache"
    for d in (src, pristine, cache):
        shutil.rmtree(d, ignore_errors=True)
    for d in (src, pristine, base):
        d.mkdir(parents=True, exist_ok=True)
    copy_sources(src, None if args.worktree else args.rev)
    copy_sources(pristine, None if args.worktree else args.rev)
    for rel in args.add:
        for root in (src, pristine):
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / rel, root / rel)
    dependency_aware = (src / "wfbench" / "jit.py").is_file()
    print(f"sources: {'working tree' if args.worktree else args.rev} in {src}", flush=True)
    if args.list:
        for mu in mutants:
            found = locate(src, mu)
            print(f"{mu.name:<26s} {found[0] if found else 'STALE':<22s} {mu.what}")
        if not args.workdir:
            shutil.rmtree(work)
        return 0
    t0 = time.perf_counter()
    outcome, detail = run_groups(src, base, args.timeout)
    print(f"unmutated: {outcome} {detail} ({time.perf_counter() - t0:.0f} s, warms the numba cache)", flush=True)
    if outcome != "passed":
        print("the tests fail without a mutant: fix that first", file=sys.stderr)
        return 1
    results = []
    for i, mu in enumerate(mutants, 1):
        found = locate(src, mu)
        t0 = time.perf_counter()
        if found is None:
            outcome, detail = "stale", "text not found"
        else:
            rel, old, new = found
            path = src / rel
            path.write_text(path.read_text().replace(old, new))
            stale = set() if dependency_aware else stale_cache_modules(src, rel)
            fresh_cache(base, cache, stale)
            try:
                outcome, detail = run_groups(src, cache, args.timeout)
            finally:
                shutil.copy2(pristine / rel, path)  # restored with its timestamp: the warm cache stays valid
        outcome = {"passed": "SURVIVED"}.get(outcome, outcome)
        results.append({"mutant": mu.name, "what": mu.what, "outcome": outcome, "detail": detail,
                        "seconds": round(time.perf_counter() - t0, 1)})
        print(f"[{i}/{len(mutants)}] {mu.name:<26s} {outcome:<9s} {detail} ({results[-1]['seconds']:.0f} s)",
              flush=True)
    killed = [r for r in results if r["outcome"] in ("killed", "timeout")]
    invalid = [r["mutant"] for r in results if r["outcome"] == "invalid"]
    by_group = {g: sum(1 for r in killed if r["detail"].startswith(g)) for g in GROUPS}
    survived = [r["mutant"] for r in results if r["outcome"] == "SURVIVED"]
    stale = [r["mutant"] for r in results if r["outcome"] == "stale"]
    print(f"\n{len(results)} mutants: {len(killed)} killed ({', '.join(f'{n} by {g}' for g, n in by_group.items())}), "
          f"{len(survived)} survived {survived}, {len(stale)} stale {stale}, {len(invalid)} do not compile {invalid}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    if not args.workdir:
        shutil.rmtree(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
