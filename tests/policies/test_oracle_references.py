"""Versioned references, the hindsight rollout, and the replaying oracle (docs/hindsight.md, issue #53)."""

from __future__ import annotations

import hashlib
import json
import subprocess

import numpy as np
import pandas as pd
import pytest
from wfbench.policies import registry
from wfbench.policies.oracle import cache, episodes, pieces, references
from wfbench.policies.oracle.best import BestInHindsight
from wfbench.policies.oracle.hindsight import HindsightRollout
from wfbench.policies.table import CompositeOf, Entry, RolloutPreset, TunedFile

import wfbench
from wfbench import policies
from wfbench.core.simulator import Simulator
from wfbench.harness.evaluation import evaluate

SHORT = wfbench.scenario("small").replace(horizon=120)  # 5 facilities, 4 people: a lookahead episode in a second
SEEDS = [3, 5, 8]


@pytest.fixture
def store(tmp_path, monkeypatch):
    """An empty totals cache and episode store, on disk in ``tmp_path``, nothing in memory."""
    monkeypatch.setenv(cache.ENV, str(tmp_path / "cache"))
    monkeypatch.setenv(pieces.ENV, "off")
    cache.clear_memory()
    episodes.clear_memory()
    yield tmp_path / "cache"
    cache.clear_memory()
    episodes.clear_memory()


def _recorded() -> set:
    root = cache.directory()
    return set() if root is None else set(root.glob(f"{episodes.PREFIX}*/*.npz"))


def _nsw(name: str, seeds=SEEDS, record: bool = False) -> np.ndarray:
    """The evaluator's mean NSW per seed of a registry name on ``SHORT``.

    The runner records the episodes of a replaying reference's candidate; without ``record`` they are forgotten, so
    that an oracle played next takes its totals where the test puts them.
    """
    before = _recorded()
    out = evaluate(name, SHORT, seeds)["nsw"].to_numpy()
    if not record:
        for path in _recorded() - before:
            path.unlink()
        episodes.clear_memory()
    return out


def _episode(policy, seeds=SEEDS) -> np.ndarray:
    """Mean NSW per seed of a policy object, played as the runner plays a built-in."""
    sim = Simulator(SHORT, seeds)
    obs = sim.reset()
    policy.attach(SHORT)
    policy.reset(sim.seeds)
    while not sim.done:
        sim.step(policy.act(obs))
        obs = sim.observe()
    return sim.episode_means()["nsw"]


# -- the references ---------------------------------------------------------------------------------------------------

def test_references__the_oracle_plays_v1_exactly_and_v2_every_deployable_family():
    assert registry.oracle_candidates("oracle") == [n for n in references.V1 if registry._available(n)]
    oracle = policies.get("oracle")
    assert not oracle.replay and oracle.candidates == tuple(registry.oracle_candidates("oracle"))
    v2 = policies.get("oracle-v2")
    assert v2.replay and v2.reads_trace
    # issue #53's families, as registered when v2 was made (a policy registered later enters v3, never v2)
    families = {*references.V1, "solver-sparse", "heuristic-tuned-train", "solver-tuned-train", "scalefree-general",
                "oracle-rollout", "rollout-scalefree-general",
                *(f"{f}{b}" for f in ("rollout-solver-tuned", "rollout-solver-sparse-tuned", "search-scalefree-general")
                  for b in ("-1ms", "", "-100ms")),
                *(f"mpc-{k}{o}" for k in ("rates", "ma") for o in ("", "-calibrated", "-tuned-train"))}
    assert set(references.V2) == families and len(set(references.V2)) == len(references.V2)
    assert [n for n in references.V2 if n in references.V1] == list(references.V1)  # v1's tie order kept
    assert all(n in registry.names() or n in registry.lookahead_names() for n in references.V2)


def test_references__v3_adds_every_deployable_policy_v2_does_not_play():
    v3 = policies.get("oracle-v3")
    assert v3.replay and v3.reads_trace and references.reference("oracle-v3") == "v3"
    assert list(references.V3[:len(references.V2)]) == list(references.V2)  # v2's tie order kept
    assert len(set(references.V3)) == len(references.V3)
    # every registered deployable policy, lookaheads included, is a candidate, save those registered after v3 was made
    registered = [n for n in [*registry.deployable_names(), *registry.lookahead_names()]]
    assert [n for n in registered if n not in references.V3] == ["distill-switch-general",
                                                                  "search-scalefree-general-playout",
                                                                  "switch-scalefree-general",
                                                                  "switch-scalefree-general-5ms"]
    # every training seed of every method trained over seeds, except the seed its shipped pick is a copy of
    before_v3 = [m for m in registry.seed_runs() if m in references.V3]  # distill-switch-general came after
    seeds = {m for method in before_v3 for m in registry.seed_members(method)}
    picks = {registry.shipped_member(method) for method in before_v3}
    assert picks <= seeds and len(picks) == len(before_v3) == len(registry.seed_runs()) - 1
    assert {n for n in references.V3 if registry.parse_member(n)} == seeds - picks
    assert registry.oracle_candidates("oracle-v3") == list(references.V3)  # each one can be built here
    assert not registry._available("scalefree-general#seed9")  # a seed the method has not is no candidate


def test_references__a_policy_added_to_the_registry_enters_no_existing_reference(monkeypatch):
    before = {name: registry.oracle_candidates(name) for name in references.ORACLES}
    monkeypatch.setitem(registry.TABLE, "heuristic-new", Entry("heuristic-new", "composite",
                                                                CompositeOf("nearest", "threshold", "spatial"), "new"))
    monkeypatch.setitem(registry.TABLE, "rollout-heuristic-new", Entry("rollout-heuristic-new", "rollout",
                                                                        RolloutPreset("heuristic-new", "1ms"), "new",
                                                                        listed=False))
    monkeypatch.setitem(registry.TABLE, "solver-new-tuned", Entry("solver-new-tuned", "tuned",
                                                                   TunedFile("solver-paper-64.json"), "new"))
    assert {"heuristic-new", "solver-new-tuned"} <= set(registry.deployable_names())
    assert {name: registry.oracle_candidates(name) for name in references.ORACLES} == before


def test_references__an_unknown_reference_is_refused_in_one_line():
    with pytest.raises(ValueError, match=r"^'v9' is neither a best-in-hindsight oracle nor a reference; allowed: "
                                         r"oracle, oracle-v2, oracle-v3, v1, v2, v3$"):
        references.candidates("v9")


def test_suite_checks_each_oracle_against_its_own_reference():
    from wfbench.reproduce.suite import outside_oracle

    assert outside_oracle("rollout-solver-tuned") and not outside_oracle("rollout-solver-tuned", "oracle-v2")
    assert outside_oracle("scalefree-general#seed2") and not outside_oracle("scalefree-general#seed2", "oracle-v2")
    assert not outside_oracle("solver-tuned") and not outside_oracle("solver-tuned", "oracle-v2")
    # a training seed is played where its reference lists it; the shipped pick's seed wherever its method is
    assert outside_oracle("scalefree-general#seed1", "oracle-v2") and not outside_oracle("scalefree-general#seed1",
                                                                                         "oracle-v3")
    assert not outside_oracle("ppo-general#seed3") and outside_oracle("ppo-general#seed1")
    assert outside_oracle("ppo-general#seed3@greedy", "oracle-v3")  # another mode is another policy
    assert outside_oracle("distill-general", "oracle-v2") and not outside_oracle("distill-general", "oracle-v3")


def test_suite_checks_the_newest_reference_that_ran_against_its_candidates():
    from wfbench.reproduce.suite import _checks
    from wfbench.scenarios import get_suite

    sc = get_suite("suite-v1").scenario("small-v1")

    def rows(nsw):
        return pd.DataFrame({"scenario": [sc.id] * 2, "seed": [0, 1], "nsw": [nsw, nsw]})

    runs = {"solver-tuned": rows(0.6), "rollout-solver-tuned": rows(0.7), "oracle": rows(0.65),
            "scalefree-general": rows(0.62)}
    (check,), (row,) = _checks([sc], runs, {})
    assert (check["oracle"], check["best_deployable"], check["oracle_at_least_deployable"]) == \
        ("oracle", "solver-tuned", True)  # the rollout is no candidate of v1
    # ... but it is above v1, and said so beside; the network, outside v1 too, is below it and not named
    assert json.loads(check["above_oracle_outside"]) == {"rollout-solver-tuned": 0.7}
    assert row[-1] == "rollout-solver-tuned (0.7000)"
    (check,), (row,) = _checks([sc], {**runs, "oracle-v2": rows(0.69)}, {})
    assert (check["oracle"], check["best_deployable"], check["oracle_at_least_deployable"]) == \
        ("oracle-v2", "rollout-solver-tuned", False)
    assert json.loads(check["above_oracle_outside"]) == {} and row[-1] == "none"  # v2 plays them all
    # per scenario, the newest reference that ran there: v3 on one world only leaves v2 checked on the other
    other = get_suite("suite-v1").scenario("paper-64-v1")
    both = {n: pd.concat([df, df.assign(scenario=other.id)]) for n, df in
            {**runs, "oracle-v2": rows(0.69), "scalefree-general#seed1": rows(0.705)}.items()}
    both["oracle-v3"] = rows(0.71)
    (v3, v2), _ = _checks([sc, other], both, {})
    assert (v3["oracle"], v3["best_deployable"], v3["oracle_at_least_deployable"]) == \
        ("oracle-v3", "scalefree-general#seed1", True)
    assert (v2["oracle"], v2["best_deployable"]) == ("oracle-v2", "rollout-solver-tuned")
    assert json.loads(v2["above_oracle_outside"]) == {"scalefree-general#seed1": 0.705}  # a seed v2 does not play


# -- the hindsight rollout --------------------------------------------------------------------------------------------

def test_oracle_rollout__reads_the_trace_and_improves_on_its_base_on_every_seed():
    rollout = policies.get("oracle-rollout")
    assert isinstance(rollout, HindsightRollout) and rollout.reads_trace and "oracle-rollout" not in \
        registry.deployable_names()
    ours, base = _nsw("oracle-rollout"), _nsw("solver-tuned")
    # to the end of the episode, each score is the exact rest of it: one step of exact policy improvement
    assert (ours >= base).all() and (ours > base).any(), (ours, base)


def test_oracle_rollout__refuses_a_base_it_cannot_compile_in_one_line():
    with pytest.raises(ValueError, match=r"^oracle-rollout base 'ppo-joint' is not a composite of built-in kernels"):
        HindsightRollout(type("Net", (), {"name": "ppo-joint"})())
    with pytest.raises(ValueError, match=r"^oracle-rollout knob H = 0 is not allowed; allowed: an integer >= 1"):
        HindsightRollout(policies.get("solver-tuned"), H=0)


def test_oracle_rollout__on_a_world_as_large_as_city_plays_the_rollouts_city_preset():
    from wfbench.policies.lookahead.rollout import AUTO_SPARSE_PAIRS, sparse_twin, spatial_twin

    registered = policies.get("oracle-rollout")
    pairs, twin, futures = registered.large
    assert pairs == AUTO_SPARSE_PAIRS and twin.name == "solver-tuned-sparse" and futures.name == \
        "solver-tuned-sparse-spatial"
    base = policies.get("solver-tuned")
    twin = sparse_twin(base)
    size = SHORT.max_facilities * SHORT.max_personnel
    plain, at_limit, above = (HindsightRollout(base, large=large) for large in
                              (None, (size, twin, spatial_twin(twin)), (size - 1, twin, spatial_twin(twin))))
    dense = _episode(plain)
    assert _episode(at_limit).tolist() == dense.tolist() and at_limit.base is base  # not more pairs: the base
    sparse = _episode(above)
    assert above.base is twin and above.period  # more: the twin, deciding every R steps only
    assert above.timing["decisions"] == len(SEEDS) * len(range(0, SHORT.horizon, above.R))
    assert plain.timing["decisions"] > above.timing["decisions"]
    assert sparse.tolist() != dense.tolist()
    with pytest.raises(ValueError, match=r"^oracle-rollout base 'x' is not a composite of built-in kernels"):
        HindsightRollout(base, large=(1, twin, type("X", (), {"name": "x"})()))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rollout-solver-tuned-1ms", "mpc-rates", "oracle-rollout"])
def test_a_lookahead_plays_a_seed_the_same_alone_and_in_any_batch(name):
    # the replaying oracle keys these episodes by the seed alone, and takes their totals from pieces played in other
    # chunks: that is only sound if the batch cannot move a bit
    batch = _nsw(name, seeds=SEEDS)
    alone = [_nsw(name, seeds=[s])[0] for s in SEEDS]
    other = _nsw(name, seeds=[SEEDS[2], 11, SEEDS[0]])
    assert batch.tolist() == alone and [other[2], other[0]] == [batch[0], batch[2]]
    _, _, network = episodes.identity(policies.get(name))
    assert not network


# -- the replaying oracle ---------------------------------------------------------------------------------------------

CANDIDATES = ("heuristic", "solver-tuned", "rollout-solver-tuned-1ms", "oracle-rollout")


def _oracle(candidates=CANDIDATES) -> BestInHindsight:
    return BestInHindsight(candidates, policies.get, name="oracle-test", replay=True, inputs=registry.input_files)


def test_replaying_oracle__scores_the_best_candidate_per_seed_then_replays_without_playing(store, monkeypatch):
    each = {n: _nsw(n) for n in CANDIDATES}
    best = np.max(np.stack(list(each.values())), axis=0)
    first = _oracle()
    rows = _episode(first)
    assert rows.tolist() == best.tolist()  # bit for bit the chosen candidate's episode
    assert first.choice == [CANDIDATES[int(np.argmax([each[n][i] for n in CANDIDATES]))] for i in range(3)]
    finished = [n for k, n in enumerate(CANDIDATES[2:], 2) if not np.isnan(first.scores[:, k]).any()]
    assert "oracle-rollout" in finished  # it scores at least solver-tuned on every seed: never stopped early
    # a fresh process reads the episodes from disk: what finished is not played through act again
    episodes.clear_memory()
    played = []
    real = BestInHindsight._play_recorded

    def spy(self, policy, *a, **k):
        played.append(policy.name)
        return real(self, policy, *a, **k)

    monkeypatch.setattr(BestInHindsight, "_play_recorded", spy)
    again = _oracle()
    assert _episode(again).tolist() == rows.tolist()
    assert not set(played) & set(finished)
    assert again.sources["oracle-rollout"] == {"episodes": 3, "pieces": 0, "cache": 0, "played": 0}


@pytest.mark.parametrize("name", ["rollout-solver-tuned-1ms",
                                  pytest.param("scalefree-general", marks=pytest.mark.slow),
                                  pytest.param("scalefree-general#seed1", marks=pytest.mark.slow)])  # a v3 candidate
def test_replaying_oracle__reads_the_episodes_the_runner_recorded_and_plays_none_again(store, monkeypatch, name):
    # the suite plays each candidate once for its piece: recorded there, the oracle neither plays nor replays it
    truth = _nsw(name, record=True)
    assert len(list(store.glob("episode-*/*.npz"))) == len(SEEDS)
    played = []
    real = BestInHindsight._play_recorded
    monkeypatch.setattr(BestInHindsight, "_play_recorded",
                        lambda self, policy, *a, **k: (played.append(policy.name), real(self, policy, *a, **k))[1])
    cache.clear_memory()  # a network's totals would come from the totals cache: the episodes alone must do
    episodes.clear_memory()
    oracle = _oracle(("heuristic", name))
    assert _episode(oracle).tolist() == np.maximum(_nsw("heuristic"), truth).tolist()
    assert name in oracle.choice and played == []
    assert oracle.sources[name] == {"episodes": 3, "pieces": 0, "cache": 0, "played": 0}


def test_the_runner_records_no_episode_of_a_policy_no_replaying_reference_reads(store):
    assert "nearest+staffing+spatial" not in references.replayed() and "oracle-rollout" in references.replayed()
    _nsw("nearest+staffing+spatial", record=True)
    assert not list(store.glob("episode-*"))


def _piece(folder, name, seeds, nsw, commit="HEAD", dirty=False, inputs=None, batches=None):
    """A piece as the suite writes it: its provenance names the commit and the files the policy reads (``inputs``)."""
    from wfbench.reproduce import provenance

    path = folder / "cache" / name / "tiny-v1.csv"
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame({"seed": seeds, "nsw": nsw}).to_csv(path, index=False)
    if commit == "HEAD":
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    inputs = provenance.policy_inputs(name) if inputs is None else inputs
    meta = {"hash": "h", "seeds": list(seeds), "provenance": {"commit": commit, "dirty": dirty, "inputs": inputs}}
    if batches is not None:
        meta["batches"] = batches
    path.with_suffix(".json").write_text(json.dumps(meta))
    return path


@pytest.fixture
def tiny_suite(store, tmp_path, monkeypatch):
    """``SHORT`` as the suite scenario ``tiny-v1`` (hash ``h``), its pieces read from ``tmp_path/run``."""
    monkeypatch.setattr(pieces, "_suite_scenarios", lambda text: (("tiny-v1", "h"),))
    monkeypatch.setenv(pieces.ENV, str(tmp_path / "run"))
    return tmp_path / "run"


def test_replaying_oracle__takes_totals_from_matching_pieces_and_plays_only_the_seeds_a_piece_wins(tiny_suite,
                                                                                                   monkeypatch):
    name = "rollout-solver-tuned-1ms"
    truth = _nsw(name)
    _piece(tiny_suite, name, SEEDS, truth)
    # as if made at a commit with these files
    monkeypatch.setattr(pieces, "mismatch", lambda meta, files, inputs=None: None)
    oracle = _oracle(("heuristic", name))
    oracle.attach(SHORT)
    oracle.reset(SEEDS)
    wins = sum(c == name for c in oracle.choice)
    assert wins and oracle.sources[name] == {"episodes": 0, "pieces": 3, "cache": 0, "played": 0}
    assert len(list((tiny_suite.parent / "cache").glob("episode-*/*.npz"))) == wins  # played where it wins, stored


def test_replaying_oracle__a_piece_that_disagrees_with_the_code_fails_in_one_line_naming_it(tiny_suite,
                                                                                          monkeypatch):
    name = "rollout-solver-tuned-1ms"
    path = _piece(tiny_suite, name, SEEDS, _nsw(name) + 0.5)  # a seed it wins says what no play gives
    monkeypatch.setattr(pieces, "mismatch", lambda meta, files, inputs=None: None)
    with pytest.raises(pieces.PieceMismatch) as err:
        _episode(_oracle(("heuristic", name)))
    text = str(err.value)
    assert "\n" not in text and str(path) in text and "playing it now gives" in text


def test_replaying_oracle__a_piece_from_other_code_fails_in_one_line_naming_it(tiny_suite):
    name = "rollout-solver-tuned-1ms"
    path = _piece(tiny_suite, name, SEEDS, np.zeros(3), commit=None)
    with pytest.raises(pieces.PieceMismatch) as err:
        _episode(_oracle(("heuristic", name)))
    assert str(err.value) == (f"oracle-test: the piece {path} of {name!r} was not made by this code (it records no "
                              f"commit); recompute it (wfbench reproduce suite) or leave its folder out of "
                              f"${pieces.ENV}")
    path = _piece(tiny_suite, name, SEEDS, np.zeros(3), dirty=True)
    with pytest.raises(pieces.PieceMismatch, match=r"made from a dirty tree at [0-9a-f]{12}\); recompute it"):
        _episode(_oracle(("heuristic", name)))


def test_replaying_oracle__passes_over_a_piece_from_other_code_in_the_checkouts_own_results(store, tmp_path,
                                                                                            monkeypatch):
    name = "rollout-solver-tuned-1ms"
    monkeypatch.delenv(pieces.ENV)
    monkeypatch.setattr(pieces, "ROOT", tmp_path)  # its docs/results: the committed runs found by default
    monkeypatch.setattr(pieces, "_suite_scenarios", lambda text: (("tiny-v1", "h"),))
    path = _piece(tmp_path / pieces.RESULTS / "run", name, SEEDS, np.zeros(3), commit=None)
    assert pieces.folders() == ([tmp_path / pieces.RESULTS / "run"], False)
    oracle = _oracle(("heuristic", name))
    assert _episode(oracle).tolist() == np.maximum(_nsw("heuristic"), _nsw(name)).tolist()
    assert oracle.skipped == [(name, str(path), "it records no commit")]
    assert oracle.sources[name] == {"episodes": 0, "pieces": 0, "cache": 0, "played": 3}


def test_provenance_matches_when_every_decisive_file_is_the_commits():
    files = episodes.decisive_files(policies.get("rollout-solver-tuned"))
    assert {"policies/lookahead/rollout.py", "policies/kernels/forward.py", "wfbench/core/simulator.py",
            "wfbench/core/belief.py"} <= set(files)
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    clean = [f for f in files if subprocess.run(["git", "diff", "--quiet", "HEAD", "--", f]).returncode == 0]
    assert clean, "every file that decides the rollout is edited: commit first"
    assert pieces.mismatch({"provenance": {"commit": head, "dirty": False}}, clean[:5]) is None
    first = subprocess.run(["git", "rev-list", "--max-parents=0", "HEAD"], capture_output=True, text=True,
                           check=True).stdout.split()[0]
    why = pieces.mismatch({"provenance": {"commit": first, "dirty": False}}, ["policies/lookahead/rollout.py"])
    assert why == f"policies/lookahead/rollout.py differs from its commit {first[:12]}"
    assert pieces.mismatch({"provenance": {"commit": "0" * 40, "dirty": False}}, files) == \
        f"its commit {'0' * 12} is not in this repository"


@pytest.mark.parametrize("name", ["solver-tuned", "rollout-solver-tuned-1ms", "mpc-ma-calibrated",
                                  "search-scalefree-general"])
def test_a_deployable_policys_decisive_files_hold_no_table_registry_or_oracle(name):
    """Listing a policy, registering a family or editing an oracle leaves every other piece's provenance whole."""
    files = set(episodes.decisive_files(policies.get(name)))
    assert {"policies/kernels/act.py", "policies/episode.py", "wfbench/core/dynamics.py"} <= files
    assert not files & {"policies/table.py", "policies/registry.py", "policies/tuned/__init__.py",
                        "policies/lookahead/__init__.py", "policies/neural/__init__.py"}
    assert not [f for f in files if f.startswith("policies/oracle/")]


def test_episode_keys_change_with_what_decides_the_policy():
    a = episodes.candidate_key(SHORT, "r", policies.get("rollout-solver-tuned"))
    assert a == episodes.candidate_key(SHORT, "r", policies.get("rollout-solver-tuned"))
    assert a[1]  # per seed: no network plays
    assert a != episodes.candidate_key(SHORT, "r", policies.get("rollout-solver-tuned-1ms"))
    assert a != episodes.candidate_key(SHORT.replace(horizon=121), "r", policies.get("rollout-solver-tuned"))
    assert a != episodes.candidate_key(SHORT, "r", policies.get("rollout-solver-sparse-tuned"))
    assert a != episodes.candidate_key(SHORT, "r", policies.get("mpc-rates"))


def test_replay_gives_the_recorded_actions_back():
    from wfbench.policies.oracle.replay import Replay, episode_of

    oracle = _oracle(("heuristic",))
    oracle.attach(SHORT)
    sim = Simulator(SHORT, SEEDS)
    total, rec = oracle._play_recorded(policies.get("random"), np.array(SEEDS), np.full(3, -np.inf))
    replay = Replay(sim.M, sim.N, {i: episode_of(rec, i, total[i]) for i in range(3)})
    sim.reset()
    while not sim.done:
        d, w, p = replay.actions(sim.t, np.arange(3))
        sim.step({"dispatch": d, "workforce": w, "positioning": p})
    assert sim.episode_means()["nsw"].tolist() == (total / SHORT.horizon).tolist()


def test_a_piece_extended_over_runs_is_judged_seed_by_seed_by_the_part_that_played_it(tmp_path, monkeypatch):
    name = "rollout-solver-tuned-1ms"
    monkeypatch.setattr(pieces, "_suite_scenarios", lambda text: (("tiny-v1", "h"),))
    run = tmp_path / "run"
    monkeypatch.setattr(pieces, "folders", lambda: ([run], False))  # as the checkout's own results: passed over
    path = _piece(run, name, SEEDS, [0.1, 0.2, 0.3])  # its top-level provenance: this commit, the last run's
    head = json.loads(path.with_suffix(".json").read_text())["provenance"]
    meta = json.loads(path.with_suffix(".json").read_text())
    meta["parts"] = [{"seeds": SEEDS[:1], "provenance": {"commit": None}}, {"seeds": SEEDS[1:], "provenance": head}]
    path.with_suffix(".json").write_text(json.dumps(meta))
    files = episodes.decisive_files(policies.get(name))
    out, where, skipped = pieces.scores(name, SHORT, np.array(SEEDS), files)
    # the seed the first run played is not taken on the strength of the last run's provenance
    assert np.isnan(out[0]) and out[1:].tolist() == [0.2, 0.3] and sorted(where) == [1, 2]
    assert skipped == [(path, f"it records no commit, seeds {SEEDS[0]}..{SEEDS[0]} (1)")]
    out, _, skipped = pieces.scores(name, SHORT, np.array(SEEDS[1:]), files)  # the old part is not asked for
    assert out.tolist() == [0.2, 0.3] and skipped == []
    monkeypatch.setattr(pieces, "folders", lambda: ([run], True))  # asked for by name: one line, piece and seeds
    with pytest.raises(pieces.PieceMismatch) as err:
        pieces.scores(name, SHORT, np.array(SEEDS), files, who="oracle-v2")
    assert str(err.value) == (f"oracle-v2: the piece {path} of {name!r} was not made by this code (it records no "
                              f"commit, seeds {SEEDS[0]}..{SEEDS[0]} (1)); recompute it (wfbench reproduce suite) or "
                              f"leave its folder out of ${pieces.ENV}")


def test_provenance_matches_only_with_the_files_the_policy_reads_now_at_the_bytes_it_read(tmp_path, monkeypatch):
    """A checkpoint or tuned file is not code: the piece's recorded inputs must be those read now, byte for byte."""
    tuned = tmp_path / "solver-x.json"
    tuned.write_text('{"a": 1}')
    sha = hashlib.sha256(tuned.read_bytes()).hexdigest()
    monkeypatch.setattr(pieces, "ROOT", tmp_path)  # the recorded paths are repository paths
    ok = {"inputs": {"solver-x.json": sha}}
    assert pieces._inputs_differ(ok, [tuned]) is None
    assert pieces._inputs_differ({"inputs": {"solver-x.json": "0" * 64}}, [tuned]) == \
        "solver-x.json differs from the one it was made with"
    assert pieces._inputs_differ({"inputs": {}}, [tuned]) == "it does not record reading solver-x.json"
    assert pieces._inputs_differ({}, []) is None  # a composite of built-ins reads nothing
    extra = {"inputs": {"solver-x.json": sha, "net.pt": "1" * 64}}
    assert pieces._inputs_differ(extra, [tuned]) == "it was made reading net.pt, which this policy does not read"
    tuned.write_text('{"a": 22}')  # the file edited since: its new bytes are read, not a stale hash
    assert pieces._inputs_differ(ok, [tuned]) == "solver-x.json differs from the one it was made with"


def test_a_policy_s_input_files_are_what_its_pieces_record_reading():
    from wfbench.reproduce import provenance

    for name in ("mpc-ma-tuned-train", "rollout-solver-tuned", "search-scalefree-general", "heuristic"):
        now = provenance.policy_inputs(name)
        assert {p.relative_to(pieces.ROOT).as_posix() for p in registry.input_files(name)} == set(now)
    assert len(registry.input_files("mpc-ma-tuned-train")) == 2  # its own tuned file and its base's
    assert registry.input_files("heuristic") == []


def test_replaying_oracle__a_piece_made_with_another_tuned_file_fails_in_one_line_naming_it(tiny_suite):
    name = "rollout-solver-tuned-1ms"
    (tuned,) = registry.input_files(name)
    rel = tuned.relative_to(pieces.ROOT).as_posix()
    path = _piece(tiny_suite, name, SEEDS, np.zeros(3), inputs={rel: "0" * 64})
    with pytest.raises(pieces.PieceMismatch) as err:
        _episode(_oracle(("heuristic", name)))
    assert str(err.value) == (f"oracle-test: the piece {path} of {name!r} was not made by this code ({rel} differs "
                              f"from the one it was made with); recompute it (wfbench reproduce suite) or leave its "
                              f"folder out of ${pieces.ENV}")


def test_replaying_oracle__reads_a_network_s_piece_only_where_it_played_this_very_batch(tiny_suite):
    """A network's totals can change in the last bit with its batch: another batch's piece is not taken."""
    name = "ppo-joint"
    low = np.zeros(3)  # below the heuristic on every seed: taken as totals, never chosen (nothing to replay)
    _piece(tiny_suite, name, SEEDS, low, batches=[SEEDS])
    oracle = _oracle(("heuristic", name))
    assert _episode(oracle).tolist() == _nsw("heuristic").tolist()
    assert oracle.sources[name] == {"episodes": 0, "pieces": 3, "cache": 0, "played": 0}
    for i, other in enumerate(([SEEDS[::-1]], [SEEDS[:2], SEEDS[2:]], None)):  # another order, batches, none
        _piece(tiny_suite, name, SEEDS, low, batches=other)
        episodes.clear_memory()
        oracle = _oracle(("heuristic", name))
        _episode(oracle)
        # played the first time (and its episodes recorded), read from those episodes after: never from the piece
        assert oracle.sources[name] == {"episodes": 3 * (i > 0), "pieces": 0, "cache": 0, "played": 3 * (i == 0)}


def test_a_suite_piece_records_the_batches_it_was_played_in(tmp_path):
    from wfbench.harness.backends import Execution
    from wfbench.reproduce import pieces as suite_pieces
    from wfbench.scenarios import get_suite

    sc = next(s for s in get_suite("suite-v1").scenarios if s.id == "small-v1")
    run = Execution(backend="serial", chunk_size=2)
    df = suite_pieces.obtain([tmp_path], tmp_path, "heuristic", sc, [4, 2, 7], run)
    meta = json.loads(suite_pieces.piece_path(tmp_path, "heuristic", sc).with_suffix(".json").read_text())
    assert meta["batches"] == [[4, 2], [7]] and df["seed"].tolist() == [4, 2, 7]
    suite_pieces.obtain([tmp_path], tmp_path, "heuristic", sc, [4, 2, 7, 9], run)  # extended: a part per run
    meta = json.loads(suite_pieces.piece_path(tmp_path, "heuristic", sc).with_suffix(".json").read_text())
    assert [p.get("batches") for p in meta["parts"]] == [[[4, 2], [7]], [[9]]]
