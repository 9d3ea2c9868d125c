"""Evaluation from a plain script: no ``__main__`` guard, a policy class defined in ``__main__``.

The script runs as a user's first script would (``python script.py`` in its own
folder), so the process backend meets a ``__main__`` it must not re-import and a class
that only exists there (what a notebook cell defines too).
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = textwrap.dedent("""
    import json
    import wfbench
    from wfbench.policies import get
    from wfbench.harness.budget import results_only
    from wfbench.harness.guard import PolicyError

    class Mine:
        decisions = ("dispatch", "workforce", "positioning")

        def __init__(self):
            self.inner = get("heuristic-stochastic")

        def reset(self, seeds):
            self.inner.reset(seeds)

        def act(self, obs):
            return self.inner.act(obs)

    class Breaks(Mine):
        def act(self, obs):
            raise KeyError("no such facility")  # BREAKS_LINE

    seeds = [0, 3, 5, 8, 11]
    out = {}
    for backend in ("serial", "process", "ray"):
        for label, policy in (("builtin", "heuristic-stochastic"), ("main-class", Mine())):
            df = wfbench.evaluate(policy, "small", seeds=seeds, execution=wfbench.Execution(backend=backend, workers=2))
            # JSON keeps every float exactly; the budget columns are measurements, not results
            out[f"{label} {backend}"] = results_only(df).to_dict("list")
    for backend in ("process", "ray"):
        try:
            wfbench.evaluate(Breaks(), "small", seeds=seeds, execution=wfbench.Execution(backend=backend, workers=2))
        except PolicyError as exc:
            out[f"error {backend}"] = str(exc)
    print(json.dumps(out))
""")


@pytest.mark.slow
def test_a_script_without_main_guard_runs_every_backend_with_identical_numbers(tmp_path):
    script = tmp_path / "first_script.py"
    script.write_text(SCRIPT)
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    serial = out["builtin serial"]
    assert serial["seed"] == [0, 3, 5, 8, 11], "rows in the order of the seeds given"
    for key in ("builtin process", "builtin ray", "main-class serial", "main-class process", "main-class ray"):
        assert out[key] == serial, f"{key} differs from the serial run of the registry policy"
    line = next(i for i, text in enumerate(SCRIPT.splitlines(), 1) if "BREAKS_LINE" in text)
    for backend in ("process", "ray"):
        assert out[f"error {backend}"] == (f"policy 'Breaks' failed in act at {script}:{line}: "
                                           "KeyError: 'no such facility'"), backend
    assert "leaked" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr[-3000:]
