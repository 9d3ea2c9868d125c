"""The committed 50-seed suite run is what main computes: a fixed sample of its pieces recomputed, bit for bit.

docs/results/suite-v1-50 was once partly computed by older code (issue #42: the older
networks on large and table2-g32-f100-s25 were from before a change of their dispatch
order, and nothing caught it). Here CI plays one seed of a piece of every scenario but
city, every policy family among them, and fails on any differing bit; every piece also
says which commit and code made it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from wfbench.reproduce import provenance
from wfbench.reproduce.suite import family
from wfbench.reproduce.verify import CI_SAMPLE, differences, pieces, verify
from wfbench.scenarios import get_suite

ROOT = Path(__file__).resolve().parents[2]
RUN = ROOT / "docs" / "results" / "suite-v1-50"


def test_the_sample_covers_every_scenario_but_city_and_every_policy():
    from wfbench.reproduce.suite import default_policies, with_members

    assert {p for p, _, _ in CI_SAMPLE} == {*with_members(default_policies())[0], "bound"}
    suite = get_suite("suite-v1")
    assert {sc for _, sc, _ in CI_SAMPLE} == {s.id for s in suite.scenarios} - {"city-v1"}
    families = {family(p) for p, _, _ in CI_SAMPLE if p != "bound"}
    assert families >= {"random", "heuristic", "solver", "network", "lookahead", "oracle"}
    assert any(p == "bound" for p, _, _ in CI_SAMPLE)
    seeds = [s for _, _, s in CI_SAMPLE]
    assert min(seeds) < 25 <= max(seeds) and all(0 <= s < 50 for s in seeds)  # both chunks of a 2-worker run


@pytest.mark.slow
def test_a_sample_of_committed_pieces_equals_what_main_computes():
    out = verify(RUN, sample=CI_SAMPLE)
    bad = [f"{v.policy} on {v.scenario}: {v.differences[:3]}" for v in out.verdicts if v.differences]
    assert len(out.verdicts) == len(CI_SAMPLE)
    assert not bad, "committed results differ from main (recompute them, docs/suite.md):\n" + "\n".join(bad)


def test_differences_catch_one_bit():
    committed = pd.read_csv(RUN / "cache" / "heuristic" / "small-v1.csv", float_precision="round_trip").head(2)
    now = committed.copy()
    assert differences(committed, now) == []
    now.loc[1, "nsw"] = np.nextafter(now.loc[1, "nsw"], 1.0)
    now.loc[0, "cpu_s"] += 1.0  # a budget column is a measurement: never a difference
    diffs = differences(committed, now)
    assert len(diffs) == 1 and diffs[0].startswith(f"nsw seed {committed.loc[1, 'seed']}:")


def test_every_committed_piece_records_what_made_it():
    found = pieces(RUN)
    assert len(found) >= 16 * 33  # every policy, member, the oracle and the bound on 16 scenarios
    missing = []
    for piece in found:
        prov = piece.meta().get("provenance") or {}
        if not (prov.get("commit") and len(prov.get("code_sha256") or "") == 64 and "inputs" in prov):
            missing.append(str(piece.path.relative_to(ROOT)))
    assert not missing, f"{len(missing)} pieces without provenance, e.g. {missing[:3]}"


def test_a_recorded_network_input_is_its_checkpoint_file():
    meta = json.loads((RUN / "cache" / "ppo-general_seed3" / "small-v1.json").read_text())
    inputs = meta["provenance"]["inputs"]
    path = "policies/neural/checkpoints/ppo-general-seed3.pt"
    assert list(inputs) == [path]
    assert inputs[path] == provenance.file_sha256(ROOT / path)


def test_a_lookahead_records_its_base_s_file_and_a_tuned_one_its_own_too():
    net = "policies/neural/checkpoints/scalefree-general.pt"
    assert provenance.policy_inputs("search-scalefree-general") == {net: provenance.file_sha256(ROOT / net)}
    assert list(provenance.policy_inputs("mpc-ma-tuned-train")) == [
        "policies/tuned/mpc-ma-suite-v1-train.json", "policies/tuned/solver-suite-v1-train.json"]
    assert provenance.policy_inputs("heuristic") == {}


def test_a_piece_records_the_machine_it_was_made_on(monkeypatch):
    from importlib.metadata import version

    provenance.machine.cache_clear()
    monkeypatch.setenv("OPENBLAS_CORETYPE", "Haswell")
    got = provenance.current("heuristic")["machine"]
    provenance.machine.cache_clear()
    assert got["packages"]["numpy"] == version("numpy") and got["packages"]["scipy"] == version("scipy")
    assert set(got["packages"]) == set(provenance.MACHINE_PACKAGES)
    assert got["openblas_coretype"] == "Haswell" and set(got["cpu_flags"]) <= set(provenance.CPU_FLAGS)
    assert json.loads(json.dumps(got)) == got, "it is written into the piece's json"


def test_code_hash_of_a_checkout_equals_the_hash_from_git(tmp_path):
    repo = provenance.repository()
    if repo is None:
        pytest.fail("the tests run from a git checkout (CI clones main)")
    clean = not subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--", *provenance.CODE_ROOTS],
                               capture_output=True, text=True, check=True).stdout.strip()
    at_head = provenance.code_sha256_at(repo, "HEAD")
    assert len(at_head) == 64
    if clean:  # a clean tree hashes as its commit does; a dirty one (a developer's) must differ
        assert provenance.code_sha256() == at_head
    else:
        assert provenance.code_sha256() != at_head


@pytest.mark.slow
@pytest.mark.parametrize("bar", [["--no-progress"], []], ids=["quiet", "progress-bar"])
def test_verify_command_names_a_differing_piece(tmp_path, bar):
    """With and without its progress bar (verify's size is not known ahead: the bar once failed on that)."""
    src = RUN / "cache" / "random" / "small-v1"
    dst = tmp_path / "cache" / "random"
    dst.mkdir(parents=True)
    df = pd.read_csv(src.with_suffix(".csv"), float_precision="round_trip")
    df.loc[0, "workforce_cost"] += 0.5
    df.to_csv(dst / "small-v1.csv", index=False)
    (dst / "small-v1.json").write_text(src.with_suffix(".json").read_text())
    r = subprocess.run([sys.executable, "-m", "wfbench.cli", "reproduce", "verify", "--out", str(tmp_path),
                        "--scenarios", "small-v1", *bar], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1, r.stderr
    assert "small-v1" in r.stdout and "random" in r.stdout and "workforce_cost seed 0" in r.stdout
    assert "1 differ from the committed results" in r.stdout


# oracle-v2's candidates, played at one commit (docs/hindsight.md)
REFERENCE = ROOT / "docs" / "results" / "reference-v2"


def test_the_reference_pieces_are_the_suite_s_own_played_again_at_clean_commits():
    found = sorted((REFERENCE / "cache").glob("*/*.csv"))
    assert found, "docs/results/reference-v2 holds the candidates' pieces"
    compared = 0
    for csv in found:
        parts = json.loads(csv.with_suffix(".json").read_text()).get("parts") or [
            json.loads(csv.with_suffix(".json").read_text())]
        for part in parts:
            prov = part["provenance"]
            assert prov["commit"] and prov["dirty"] is False and "inputs" in prov, csv
        if _plays_a_network(_policy_of(csv.parent.name)):  # its totals depend on the batch: it must say which
            assert all(part.get("batches") for part in parts), csv
            continue
        suite_piece = RUN / "cache" / csv.parent.name / csv.name
        if suite_piece.exists():  # the same episodes: every result column, every bit, on every seed the piece holds
            now = pd.read_csv(csv, float_precision="round_trip")
            then = pd.read_csv(suite_piece, float_precision="round_trip")
            then = then[then["seed"].isin(now["seed"])].reset_index(drop=True)
            assert len(now) == len(then), csv  # a campaign's piece may hold fewer seeds (its chunks so far), not others
            assert differences(then, now.sort_values("seed").reset_index(drop=True)) == [], csv
            compared += 1
    assert compared >= 1


def _policy_of(folder: str) -> str:
    """The policy whose pieces a folder of ``cache/`` holds (a training seed's is ``METHOD_seedK``)."""
    from wfbench.policies.oracle.references import REFERENCES

    from wfbench.scenarios.pieces import piece_folder

    return {piece_folder(n): n for ref in REFERENCES.values() for n in ref}.get(folder, folder)


def _plays_a_network(name: str) -> bool:
    from wfbench.policies import registry

    if registry.parse_member(name):  # a training seed: a network
        return True
    e = registry.entry(name)
    return e.kind == "learned" or (e.kind == "lookahead" and _plays_a_network(registry.lookahead_base(name)))


def test_plays_a_network():
    assert _plays_a_network("scalefree-general") and _plays_a_network("search-scalefree-general")
    assert _plays_a_network("rollout-scalefree-general")
    assert not _plays_a_network("rollout-solver-tuned") and not _plays_a_network("mpc-ma-calibrated")
    assert _policy_of("scalefree-general_seed1") == "scalefree-general#seed1" and _plays_a_network(
        _policy_of("scalefree-general_seed1"))
