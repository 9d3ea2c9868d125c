"""benchmarks/reference_campaign.py: a committed piece made by other code is never copied into a run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import load_script

DECIDES = "policies/lookahead/mpc.py"


@pytest.fixture(scope="module")
def campaign():
    return load_script("benchmarks/reference_campaign.py")


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture()
def repo(tmp_path) -> tuple[Path, str, str]:
    """A checkout whose deciding file changed between two commits: (its path, the old commit, HEAD)."""
    root = tmp_path / "checkout"
    (root / "policies/lookahead").mkdir(parents=True)
    _git(root, "init", "-q")
    for i in (1, 2):
        (root / DECIDES).write_text(f"CAPACITY = {i}\n")
        (root / "README.md").write_text(f"version {i}\n")
        _git(root, "add", "-A")
        _git(root, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", f"v{i}")
    return root, _git(root, "rev-parse", "HEAD~1"), _git(root, "rev-parse", "HEAD")


def _piece(folder: Path, policy: str, world: str, commits: list[str | None]) -> Path:
    meta = folder / "cache" / policy / f"{world}.json"
    meta.parent.mkdir(parents=True, exist_ok=True)
    parts = [{"seeds": [i], "provenance": {"commit": c, "dirty": False}} for i, c in enumerate(commits)]
    meta.write_text(json.dumps({"hash": "h", "seeds": list(range(len(commits))), "parts": parts}))
    meta.with_suffix(".csv").write_text("seed,nsw\n" + "".join(f"{i},0.5\n" for i in range(len(commits))))
    return meta


def test_a_piece_is_stale_when_a_deciding_file_differs_at_one_of_its_parts_commits(campaign, repo, tmp_path):
    root, old, head = repo
    assert campaign.stale(_piece(tmp_path, "mpc-ma", "a", [head]), root, [DECIDES]) is None
    assert campaign.stale(_piece(tmp_path, "mpc-ma", "b", [head, head]), root, ["README.md", DECIDES]) is None
    why = campaign.stale(_piece(tmp_path, "mpc-ma", "c", [head, old]), root, [DECIDES])
    assert why == f"{DECIDES} differs between {old[:7]} and the checkout"
    # a file the policy does not read may differ: README.md changed too, and the piece is not stale for it alone
    assert campaign.stale(_piece(tmp_path, "mpc-ma", "d", [old]), root, ["missing.py"]) is None
    assert campaign.stale(_piece(tmp_path, "mpc-ma", "e", [None]), root, [DECIDES]) == "a part records no commit"
    assert "differs" in campaign.stale(_piece(tmp_path, "mpc-ma", "f", ["0" * 40]), root, [DECIDES])


def test_start_from_copies_the_fresh_pieces_and_names_each_stale_one(campaign, repo, tmp_path, monkeypatch, capsys):
    root, old, head = repo
    committed = tmp_path / "committed"
    _piece(committed, "mpc-ma", "novice-64-v1", [head])
    _piece(committed, "mpc-ma", "slow-64-v1", [head, old])
    _piece(committed, "oracle-v2", "novice-64-v1", [old])
    _piece(committed, "heuristic", "novice-64-v1", [old])  # not a policy of the campaign: never read
    monkeypatch.setattr(campaign, "decided_by", lambda policy: [DECIDES])
    out = tmp_path / "run"
    copied = campaign.start_from(out, committed, [], {"mpc-ma", "oracle-v2"}, root)
    assert copied == 1
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*.*")) == ["cache/mpc-ma/novice-64-v1.csv",
                                                                       "cache/mpc-ma/novice-64-v1.json"]
    lines = capsys.readouterr().out.splitlines()
    assert lines == [f"not copied: mpc-ma/slow-64-v1.json: {DECIDES} differs between {old[:7]} and the checkout",
                     f"not copied: oracle-v2/novice-64-v1.json: {DECIDES} differs between {old[:7]} and the checkout"]
    assert campaign.start_from(out, committed, [], {"mpc-ma", "oracle-v2"}, root) == 0  # what it holds stays


def test_a_training_seeds_pieces_are_found_in_its_path_safe_folder(campaign, repo, tmp_path, monkeypatch):
    root, _, head = repo
    committed = tmp_path / "committed"
    _piece(committed, "scalefree-general_seed1", "novice-64-v1", [head, head])  # the suite's folder of #seed1
    seen = []
    monkeypatch.setattr(campaign, "decided_by", lambda policy: (seen.append(policy), [DECIDES])[1])
    out = tmp_path / "run"
    assert campaign.start_from(out, committed, [], {"scalefree-general#seed1"}, root) == 1 and seen == [
        "scalefree-general#seed1"]
    assert campaign.covered(out, ("novice-64-v1", "scalefree-general#seed1", 0, 1))
    assert not campaign.covered(out, ("novice-64-v1", "scalefree-general#seed1", 0, 9))
    # a job of several training seeds is covered when each one's piece is
    assert not campaign.covered(out, ("novice-64-v1", "scalefree-general#seed1,scalefree-general#seed3", 0, 1))
    _piece(out, "scalefree-general_seed3", "novice-64-v1", [head, head])
    assert campaign.covered(out, ("novice-64-v1", "scalefree-general#seed1,scalefree-general#seed3", 0, 1))


def test_worlds_are_scenario_ids_or_a_split_and_anything_else_is_refused_in_one_line(campaign, tmp_path):
    assert campaign.worlds_of(["heldout"]) == list(campaign.WORLDS)  # the held-out split, cheapest first
    assert campaign.worlds_of(["large-v1", "train", "small-v1"]) == [
        "large-v1", "small-v1", "paper-64-v1", "nonstationary-v1", "table2-g32-f25-s10-v1", "table2-g256-f25-s5-v1",
        "surge-64-v1", "clustered-64-v1", "real-benelux-v1"]  # in order, each once
    script = Path(__file__).resolve().parents[2] / "benchmarks/reference_campaign.py"
    done = subprocess.run([sys.executable, str(script), "plan", "--out", str(tmp_path / "run"), "--worlds", "heldout",
                           "large"],
                          capture_output=True, text=True)
    assert done.returncode == 1 and done.stdout == "" and not (tmp_path / "run").exists()
    assert done.stderr.startswith("reference_campaign: unknown world 'large'; allowed: heldout, train or a scenario "
                                  "id of suite-v1 (small-v1, ") and done.stderr.count("\n") == 1


@pytest.mark.slow
def test_each_oracle_of_a_chunk_waits_for_its_own_candidates_and_v3_plays_the_training_seeds(campaign):
    from wfbench.policies.oracle import references

    v2, v3 = campaign.candidates("v2"), campaign.candidates("v3")
    assert set(v2) < set(v3) and "scalefree-general#seed1" in v3 and "scalefree-general#seed2" not in v3
    assert "heuristic" not in v3  # a compiled candidate: its oracle plays it in seconds
    queue = campaign.jobs(["novice-64-v1"], list(dict.fromkeys([*v2, *v3])), 20,
                          {"oracle-v2": v2, "oracle-v3": v3})
    for a, b in ((0, 9), (10, 19)):
        needs = {job[1]: {n[1] for n in need} for job, need in queue if job[2:] == (a, b) and need}
        assert needs == {"oracle-v2": set(v2), "oracle-v3": set(v3)}
    assert [job[1] for job, _ in queue].count("oracle-v3") == 2 and len(queue) == 2 * (len(v3) + 2)
    assert campaign.replaying_oracles() == {n for n, r in references.ORACLES.items() if r in references.REPLAYING}
    # a method's training seeds play as one job per chunk, each its own piece, and an oracle waits for it
    args = type("Args", (), {"policies": None, "references": ["v2", "v3"]})()
    groups = [p for p in campaign.played(args) if "," in p]
    assert groups == [",".join(f"{m}#seed{k}" for k in ks) for m, ks in (
        ("ppo-general", (0, 1, 2, 4)), ("hindsight-general", (0, 1, 2, 3)), ("scalefree-general", (0, 1, 3, 4)),
        ("distill-general", (0, 1, 2, 4)))]
    assert campaign.kept(args) == {*v3, "oracle-v2", "oracle-v3"}
    queue = dict(campaign.jobs(["novice-64-v1"], campaign.played(args), 10, campaign.oracles_of(args)))
    assert {p for _, p, _, _ in queue[("novice-64-v1", "oracle-v3", 0, 9)]} == set(campaign.played(args))
    assert not any("#seed" in p for _, p, _, _ in queue[("novice-64-v1", "oracle-v2", 0, 9)])


def test_a_reference_that_does_not_replay_is_refused_in_one_line(tmp_path):
    script = Path(__file__).resolve().parents[2] / "benchmarks/reference_campaign.py"
    done = subprocess.run([sys.executable, str(script), "plan", "--out", str(tmp_path / "run"), "--references", "v1"],
                          capture_output=True, text=True)
    assert done.returncode == 1 and done.stdout == "" and not (tmp_path / "run").exists()
    assert done.stderr == "reference_campaign: --references v1 is not a replaying reference; allowed: v2, v3\n"


def test_reference_gap_reads_a_training_seed_candidate_as_its_method(monkeypatch, capsys):
    """v3 plays training seeds (METHOD#seedK), no table entries: the gap is computed, the seed that lifts v3 named."""
    import pandas as pd

    gap = load_script("benchmarks/reference_gap.py")
    assert gap.method_of("ppo-general#seed0") == "ppo-general" and gap.method_of("oracle-rollout") == "oracle-rollout"
    nsw = {"bound": [0.9, 0.9, 0.9], "oracle": [0.70, 0.70, 0.70], "oracle-v2": [0.72, 0.72, 0.72],
           "heuristic-tuned": [0.70, 0.70, 0.70], "scalefree-general": [0.72, 0.72, 0.72],
           "scalefree-general#seed1": [0.71, 0.75, 0.70], "oracle-v3": [0.72, 0.75, 0.72],
           "search-scalefree-general-playout": [0.80, 0.80, 0.80]}  # not a candidate of v3, above it
    pieces = {p: pd.DataFrame({"nsw": v}, index=pd.Index([0, 1, 2], name="seed")) for p, v in nsw.items()}
    monkeypatch.setattr(gap, "piece", lambda policy, world: pieces.get(policy))
    monkeypatch.setattr(sys, "argv", ["reference_gap.py", "--reference", "v3", "table2-g32-f100-s25-v1"])
    gap.main()
    out = capsys.readouterr().out
    assert "| `table2-g32-f100-s25-v1` | 3 | 0.9000 | 0.7000 | 0.7200 | 0.7300 | 0.1700 | " in out
    assert "candidate seeds above oracle-v3: 0;" in out and "oracle-v3 seeds above the bound: 0;" in out
    assert "v3 above v2 on 1 (seed 1: scalefree-general#seed1)" in out
    assert "above v3's mean: search-scalefree-general-playout (0.8000)" in out


def test_a_claim_whose_process_is_gone_is_played_again_unless_its_piece_holds_the_seeds(campaign, tmp_path):
    # a machine that stops under a worker leaves its claims behind: such a job is not failed, it is to play again
    state, out = tmp_path / "state", tmp_path / "run"
    state.mkdir()
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    lost, finished, broken = (("novice-64-v1", "mpc-ma", 0, 1), ("novice-64-v1", "mpc-rates", 0, 1),
                              ("novice-64-v1", "solver", 0, 1))
    for job in (lost, finished):
        (state / f"{campaign.name(job)}.running").write_text(f"w0 {gone.pid}")
    _piece(out, "mpc-rates", "novice-64-v1", [None, None])
    (state / f"{campaign.name(broken)}.failed").write_text("w1")
    assert campaign._state(state, out, lost) == "todo"
    assert not (state / f"{campaign.name(lost)}.running").exists()
    assert campaign._state(state, out, finished) == "done"
    assert (state / f"{campaign.name(finished)}.done").exists()
    assert campaign._state(state, out, broken) == "failed"
