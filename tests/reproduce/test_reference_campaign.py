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
