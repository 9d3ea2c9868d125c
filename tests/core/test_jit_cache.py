"""numba's cache of wfbench is keyed by every source file the compiled code depends on (wfbench.core.jit)."""

import ast
import importlib
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numba
import pytest
from numba.core import caching
from numba.core.registry import CPUDispatcher

from wfbench.core import jit

ROOT = jit.ROOT
PACKAGES = ("wfbench", "policies", "solvers")  # the folders; policies/ and solvers/ install as wfbench.policies, ...
NAMES = {"wfbench": "wfbench", "policies": "wfbench.policies", "solvers": "wfbench.solvers"}


def sources(packages=PACKAGES):
    return sorted(p for pkg in packages for p in (ROOT / pkg).rglob("*.py") if "__pycache__" not in p.parts)


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = [NAMES[rel.parts[0]], *rel.parts[1:]]
    return ".".join(parts[:-1] if rel.name == "__init__" else parts)


def module_level_imports(tree: ast.Module):
    """Import nodes outside function and class bodies."""
    todo = list(tree.body)
    while todo:
        node = todo.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda)):
            todo.extend(ast.iter_child_nodes(node))


def find_file(name: str) -> Path | None:
    """The in-project source file of module ``name`` by importlib, or None."""
    if name.split(".")[0] != "wfbench" or name.startswith("wfbench.leaderboard"):
        return None
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, AttributeError, ValueError):
        return None
    return Path(spec.origin).resolve() if spec is not None and spec.origin else None


def ast_dependencies(path: Path) -> set[Path]:
    """In-project files imported by ``path`` at module level, by Python's ast and importlib."""
    tree = ast.parse(path.read_text())
    package = module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    found = set()
    for node in module_level_imports(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), package) if node.level \
                else node.module
            names = [base] + [f"{base}.{alias.name}" for alias in node.names]
        found.update(f for f in map(find_file, names) if f is not None)
    return found


def ast_closure(path: Path) -> set[Path]:
    seen, todo = {path}, [path]
    while todo:
        for dep in ast_dependencies(todo.pop()):
            if dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return seen


def uses_numba(path: Path) -> bool:
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "numba" for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "numba":
            return True
    return False


def test_the_import_scan_finds_what_ast_finds_in_every_module():
    for path in sources():
        scanned = {Path(f) for f in map(jit._module_file, jit.imported_modules(path)) if f is not None}
        assert scanned == ast_dependencies(path) - {path}, path


@pytest.mark.slow
def test_the_digest_covers_every_numba_module_and_what_it_imports():
    numba_modules = [p for p in sources() if uses_numba(p)]
    names = {module_name(p) for p in numba_modules}
    # the modules with compiled code at the time of writing, and wherever they moved
    assert {"wfbench.core.dynamics", "wfbench.core.observe", "wfbench.core.rng", "wfbench.policies.kernels.act",
            "wfbench.policies.kernels.dispatch", "wfbench.policies.episode", "wfbench.solvers.lap"} <= names
    for path in numba_modules:
        expected = ast_closure(path.resolve())
        assert {Path(p) for p in jit.dependencies(path)} == expected, path
        if path.relative_to(ROOT).parts[0] == "solvers":
            # solvers imports nothing of ours, so numba's own stamp (its file) is complete for it
            assert all(p.relative_to(ROOT).parts[0] == "solvers" for p in expected), path
        else:
            assert jit.is_ours(path), path
    rollout = {p.relative_to(ROOT).as_posix() for p in map(Path, jit.dependencies(ROOT / "policies/episode.py"))}
    assert {"wfbench/core/dynamics.py", "wfbench/core/observe.py", "wfbench/core/state.py", "wfbench/core/rng.py",
            "policies/kernels/act.py", "policies/kernels/dispatch.py", "policies/kernels/workforce.py",
            "policies/kernels/positioning.py", "policies/kernels/common.py", "solvers/lap.py"} <= rollout


def test_every_cached_function_of_ours_uses_the_digest_locator():
    # pins the numba internals wfbench.core.jit relies on
    assert caching.CacheImpl._locator_classes[0] is jit.DigestLocator
    assert issubclass(jit.DigestLocator, caching._CacheLocator)
    checked = 0
    for path in sources(jit.CACHED_PACKAGES):
        if not uses_numba(path):
            continue
        module = importlib.import_module(module_name(path))
        for obj in vars(module).values():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == module.__name__ \
                    and isinstance(obj._cache, caching.FunctionCache):
                locator = obj._cache._impl.locator
                assert isinstance(locator, jit.DigestLocator), obj
                assert locator.get_source_stamp() == jit.source_digest(path)
                assert obj._cache._cache_file._source_stamp == jit.source_digest(path)
                checked += 1
    assert checked > 50


def test_functions_of_other_files_keep_numba_locators(tmp_path):
    other = tmp_path / "elsewhere.py"
    other.write_text("def f():\n    return 1\n")
    assert not jit.is_ours(other) and not jit.is_ours(ROOT / "solvers" / "lap.py")
    namespace = {}
    exec(compile(other.read_text(), str(other), "exec"), namespace)
    assert jit.DigestLocator.from_function(namespace["f"], str(other)) is None


def test_digests_follow_imports_only():
    observe = jit.source_digest(ROOT / "wfbench/core/observe.py")
    rollout = jit.source_digest(ROOT / "policies/episode.py")
    assert observe != rollout and len(observe) == 64
    # the simulator core does not depend on the policies
    assert not any("policies" in p for p in jit.dependencies(ROOT / "wfbench/core/observe.py"))


# -- end to end: edit a copy, see new numbers ----------------------------------------------------------------
SCRIPT = """
import numpy as np
from wfbench.core.config import ScenarioConfig
from wfbench.core.simulator import Simulator
from wfbench.core.state import IDLE
sim = Simulator(ScenarioConfig.preset("small"), [0, 1])
S = sim.state
S.per_status[:, :4] = IDLE   # four idle people in each environment, nobody under notice
S.per_leave[:, :4] = -1
S.per_level[:, :4] = np.array([0, 1, 2, 2])
obs = sim.observe()
print(int(obs["dispatchable"].sum()), int(obs["workforce_mask"].sum()))
"""


# a user's policy on the process backend with two workers first: the parent compiles, the workers load
POOL_SCRIPT = """
import numpy as np
import wfbench

class Idle:
    def reset(self, seeds):
        pass

    def act(self, obs):
        B, M = obs["dispatch_mask"].shape[:2]
        N = obs["dispatch_mask"].shape[2] - 1
        return {"dispatch": np.full((B, M), N), "workforce": np.zeros(B, dtype=np.int64),
                "positioning": np.ones((B, 2, M))}

df = wfbench.evaluate(Idle(), "small", seeds=4, execution=wfbench.Execution(backend="process", workers=2))
assert len(df) == 4
""" + SCRIPT


def run_copy(root: Path, cache: Path, script: str = SCRIPT) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(root), WFBENCH_CACHE_DIR=str(cache), NUMBA_CACHE_DIR=str(cache / "numba"))
    out = subprocess.run([sys.executable, "-c", script], env=env, cwd=root, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    return out


@pytest.mark.slow
def test_editing_a_function_inlined_from_another_file_recompiles(tmp_path):
    root = tmp_path / "src"
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, root / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    cache = tmp_path / "cache"
    notice = "wfbench: compiling the simulator core once"

    cold = run_copy(root, cache)
    assert notice in cold.stderr and len(cold.stderr.strip().splitlines()) == 1, cold.stderr
    warm = run_copy(root, cache)
    assert warm.stdout == cold.stdout and notice not in warm.stderr, warm.stderr

    # a file nothing compiled imports: still warm
    cli = root / "wfbench" / "cli" / "__init__.py"
    cli.write_text(cli.read_text() + "\n# edited\n")
    untouched = run_copy(root, cache)
    assert untouched.stdout == cold.stdout and notice not in untouched.stderr, untouched.stderr

    # observe.py inlines dispatchable() from dynamics.py: numba's own stamp (observe.py) would not see this
    dynamics = root / "wfbench" / "core" / "dynamics.py"
    text = dynamics.read_text()
    body = '    return (status == IDLE or status == RETURNING) and leave < 0\n'
    assert text.count(body) == 1, "dispatchable() changed: update this test's edit"
    dynamics.write_text(text.replace(body, body.replace("leave < 0", "leave < -1")))
    # ... and a process pool on this cold core prints the notice once: its workers load what the parent compiled
    edited = run_copy(root, cache, POOL_SCRIPT)
    assert edited.stderr.count(notice) == 1, edited.stderr
    assert cold.stdout.split()[0] == "8" and edited.stdout.split()[0] == "0", (cold.stdout, edited.stdout)
    assert edited.stdout.split()[1] == cold.stdout.split()[1]


@pytest.mark.parametrize(("first", "said"), [
    ("wfbench.core.dynamics.reset_batch", "compiling the simulator core once"),
    ("wfbench.policies.episode.play_range", "compiling the compiled episode of these built-in rules (each "
                                            "combination of rules once)"),
    ("wfbench.policies.kernels.act.act_range", "compiling the kernels of this policy's built-in rules"),
    ("wfbench.policies.builtin.something", "compiling the built-in policies' compiled code"),
    ("wfbench.policies.lookahead.kernels.Plan.run", "compiling the lookaheads' kernels"),
    ("wfbench.policies.kernels.forward.roll_forward", "compiling the roll-forward of the lookaheads (for their base's "
                                                     "rules) and the oracle"),
    ("wfbench.solvers.assignment.auction", "compiling the solvers' compiled kernels once"),
    ("mypkg.kernel.step", "compiling mypkg.kernel's compiled code once"),
])
def test_the_cold_start_line_names_what_it_compiles(first, said):
    notice = jit._ColdCompileNotice()
    notice.first = first
    line = notice.first_line("/cache")
    assert line.startswith("wfbench: ") and said in line and line.endswith("; cached afterwards (/cache)"), line


@pytest.mark.parametrize("value", [0, -1, 1.5, "2"])
def test_simulator_threads_must_be_a_positive_integer(value):
    from wfbench.core.config import ScenarioConfig
    from wfbench.core.simulator import Simulator

    with pytest.raises(ValueError, match="threads"):
        Simulator(ScenarioConfig.preset("small"), [0], threads=value)


def test_step_observe_gives_the_same_bits_on_one_and_two_threads():
    import numpy as np

    from wfbench.core.config import ScenarioConfig
    from wfbench.core.simulator import Simulator

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.fail("numba has one thread here; this test needs NUMBA_NUM_THREADS >= 2")
    seeds = list(range(9))
    sims = [Simulator(ScenarioConfig.preset("small"), seeds, threads=t) for t in (1, 2)]
    rng = np.random.default_rng(3)
    for sim in sims:
        sim.reset()
    M, N = sims[0].M, sims[0].N
    steps = 0
    while not sims[0].done:
        actions = {"dispatch": rng.integers(0, N + 1, size=(len(seeds), M)),
                   "workforce": rng.integers(0, 7, size=len(seeds)),
                   "positioning": rng.random((len(seeds), 2, M))}
        results = [sim.step_observe(actions) for sim in sims]
        assert results[0][0].tobytes() == results[1][0].tobytes()
        steps += 1
    for a, b in zip(list(sims[0].state) + list(sims[0].obs_buffers), list(sims[1].state) + list(sims[1].obs_buffers),
                    strict=True):
        assert a.tobytes() == b.tobytes()
    assert steps == sims[0].config.horizon
    assert sims[0].counters()["hires"].sum() > 0  # random workforce actions hire: the heat-map path ran too
