"""The replaying oracle's reset: totals from the totals cache, recorded episodes and committed pieces; play the rest.

:func:`reset_replaying` is :meth:`BestInHindsight.reset` for ``replay=True`` (the references of
:data:`wfbench.policies.oracle.references.REPLAYING`). Per candidate, in order:

- compiled: as the first reference (the totals cache, else played compiled; replayed live);
- any other: each seed's total from its recorded episode (:mod:`wfbench.policies.oracle.episodes`),
  else from a committed suite piece made by this code (:mod:`wfbench.policies.oracle.pieces`;
  a network's only where the piece played this very batch, since its totals depend on it),
  else (a network) from the totals cache; the seeds still without one are played, recorded
  and stored (a candidate without a network only on those seeds, one with a network on the
  whole batch, which keys it).

Then, per seed, the best score (mean NSW, the first candidate on a tie). A winner whose seed has
no recorded episode is played on the seeds it wins, its episode stored, and its total must
equal the one it was chosen by, bit for bit: else the piece (or cache) is named in one line.
``act`` replays the episodes. ``oracle.sources`` says, per candidate, how many seeds came from
each place; ``oracle.skipped`` the pieces passed over as made by other code, with why.
``docs/hindsight.md``, "Replayed, not played again".
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from wfbench.policies.oracle import cache as totals_cache
from wfbench.policies.oracle import episodes, pieces
from wfbench.policies.oracle.episodes import Episode

from wfbench.core.actions import validate_actions


class Replay:
    """Per batch row, a recorded :class:`Episode` to replay; ``actions`` as :class:`episodes.Recording`'s."""

    def __init__(self, M: int, N: int, chosen: dict[int, Episode]):
        self.M, self.N = M, N
        self.rows: dict[int, tuple[Episode, dict[int, tuple[np.ndarray, np.ndarray]], dict[int, np.ndarray]]] = {}
        for row, ep in chosen.items():
            by_t: dict[int, tuple[list[int], list[int]]] = {}
            for t, f, v in zip(ep.disp_t.tolist(), ep.disp_f.tolist(), ep.disp_v.tolist(), strict=True):
                by_t.setdefault(t, ([], []))[0].append(f)
                by_t[t][1].append(v)
            disp = {t: (np.array(f, dtype=np.int64), np.array(v, dtype=np.int64)) for t, (f, v) in by_t.items()}
            pos = {int(t): ep.pos[i] for i, t in enumerate(ep.pos_t.tolist())}
            self.rows[int(row)] = (ep, disp, pos)

    def actions(self, t: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The recorded actions of step ``t`` for the batch rows ``rows`` (in that order)."""
        n = rows.size
        d = np.full((n, self.M), self.N, dtype=np.int64)
        w = np.zeros(n, dtype=np.int64)
        p = np.zeros((n, 2, self.M), dtype=np.float64)
        for i, row in enumerate(rows.tolist()):
            ep, disp, pos = self.rows[row]
            w[i] = ep.workforce[t]
            if t in disp:
                d[i, disp[t][0]] = disp[t][1]
            if w[i]:
                p[i, 0 if w[i] <= 3 else 1] = pos[t]
        return d, w, p


def episode_of(rec: Any, row: int, total: float) -> Episode:
    """Row ``row`` of a finished :class:`episodes.Recording` as an :class:`Episode`."""
    ts, fs, vs = [], [], []
    for t in sorted(rec.dispatch):
        b, f, v = rec.dispatch[t]
        sel = b == row
        ts += [t] * int(sel.sum())
        fs += f[sel].tolist()
        vs += v[sel].tolist()
    pos_t = sorted(t for (t, r) in rec._positioning if r == row)
    pos = np.array([rec._positioning[t, row] for t in pos_t], dtype=np.float64).reshape(len(pos_t), rec.M)
    return Episode(float(total), rec.workforce[:, row].copy(), np.array(ts, dtype=np.int32),
                   np.array(fs, dtype=np.int32), np.array(vs, dtype=np.int32), np.array(pos_t, dtype=np.int32), pos)


class Recorder:
    """A registry candidate's episodes recorded as the evaluation runner plays them, then stored (issue #53).

    The suite plays each candidate of a replaying reference once for its piece; recorded there,
    under the key the oracle looks them up by (:func:`episodes.candidate_key` of a fresh copy,
    the entries per seed or, with a network, per seed and batch), the oracle neither plays nor
    replays them again on this machine's store.

    Args:
        config: the scenario the batch plays.
        name: the candidate's registry name.
        fresh: a fresh copy of the policy (``wfbench.policies.get(name)``), as the oracle resolves
            it: the key reads its settings, which a played copy has added to.
        seeds: the batch, in its order.
        M: the world's facility slots.
        N: the world's personnel slots.
    """

    def __init__(self, config: Any, name: str, fresh: Any, seeds: Any, M: int, N: int):
        self.key, per_seed = episodes.candidate_key(config, name, fresh)
        self.seeds = np.asarray(seeds, dtype=np.int64)
        self.entry = episodes.entry_keys(self.seeds, per_seed)
        self.B, self.M, self.N = self.seeds.size, M, N
        self.rec = episodes.Recording(self.B, M, N, config.horizon)

    def add(self, t: int, action: dict) -> None:
        """Record step ``t``'s actions (as the simulator will read them)."""
        self.rec.add(t, *validate_actions(action, self.B, self.M, self.N))

    def store(self, totals: np.ndarray) -> None:
        """Store each seed's finished episode with its NSW total (``sim.state.totals``' NSW column)."""
        self.rec.finish()
        for i, s in enumerate(self.seeds.tolist()):
            episodes.store(self.key, s, self.entry[i], episode_of(self.rec, i, float(totals[i])))


class _Candidate:
    """What the replaying reset knows of one non-compiled candidate: its key, episodes, and where each total is from."""

    def __init__(self, name: str, policy: Any, key: str, per_seed: bool, entry: np.ndarray):
        self.name, self.policy, self.key, self.per_seed, self.entry = name, policy, key, per_seed, entry
        self.episodes: dict[int, Episode] = {}
        self.piece: dict[int, Any] = {}  # row -> the piece its total came from
        self.cached: set[int] = set()  # rows whose total came from the totals cache (a network)


def _play(oracle: Any, cand: _Candidate, seeds: np.ndarray, rows: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Play ``cand`` on ``seeds[rows]`` (recorded, pruned against ``bound`` totals); store what finished; totals."""
    total, rec = oracle._play_recorded(oracle.resolve(cand.name), seeds[rows], bound, world=True)
    if np.isnan(total).any():
        return total
    for i, row in enumerate(rows.tolist()):
        ep = episode_of(rec, i, total[i])
        cand.episodes[row] = ep
        episodes.store(cand.key, int(seeds[row]), cand.entry[row], ep)
    if not cand.per_seed and (played := totals_cache.played_key(oracle.config, cand.policy)) is not None:
        totals_cache.store(played, seeds[rows], totals_cache.batch_keys(seeds[rows]), total)
    return total


def reset_replaying(oracle: Any, seeds: np.ndarray) -> None:
    """:meth:`BestInHindsight.reset` of a replaying reference (module docstring)."""
    c = oracle.config
    B, T = seeds.size, c.horizon
    oracle.seeds = seeds
    oracle.scores = np.full((B, len(oracle.candidates)), np.nan)
    oracle.timing, oracle.cached, oracle.sources, oracle.skipped = {}, {}, {}, []
    best_score = np.full(B, -np.inf)
    best = np.full(B, -1, dtype=np.int64)
    found: dict[int, Any] = {}  # candidate index -> its policy (compiled) or _Candidate
    fresh = oracle._resolved()
    for k, name in enumerate(oracle.candidates):
        start = time.perf_counter()
        policy = fresh.pop(name) if name in fresh else oracle.resolve(name)
        if getattr(policy, "compiled", False):
            total, oracle.cached[name] = oracle._play_compiled(policy, seeds)
            score = total / T
            oracle.sources[name] = {"cache": oracle.cached[name], "played": B - oracle.cached[name]}
            found[k] = policy
        else:
            key, per_seed = episodes.candidate_key(c, name, policy)
            cand = found[k] = _Candidate(name, policy, key, per_seed, episodes.entry_keys(seeds, per_seed))
            cand.episodes = episodes.lookup(key, seeds, cand.entry)
            score = np.full(B, np.nan)
            for row, ep in cand.episodes.items():
                score[row] = ep.total / T
            # committed pieces: any, where a seed's total does not depend on its batch; else (a network) only a
            # piece that played this very batch
            committed, where, skipped = pieces.scores(name, c, seeds, episodes.decisive_files(policy),
                                                      who=oracle.name, batch=not per_seed,
                                                      inputs=oracle.inputs(name) if oracle.inputs else [])
            oracle.skipped += [(name, str(path), why) for path, why in skipped]
            for row, path in where.items():
                if row in cand.episodes and committed[row] != score[row]:
                    raise pieces.PieceMismatch(
                        f"{oracle.name}: the piece {path} of {name!r} says seed {int(seeds[row])} scores "
                        f"{committed[row]!r}, its recorded episode {score[row]!r}: recompute the piece")
                if row not in cand.episodes:
                    score[row], cand.piece[row] = committed[row], path
            if not per_seed and (played := totals_cache.played_key(c, policy)) is not None:
                total, hit = totals_cache.lookup(played, seeds, totals_cache.batch_keys(seeds))
                for row in np.flatnonzero(hit & np.isnan(score)):
                    score[row] = total[row] / T
                    cand.cached.add(int(row))
            recorded, missing = len(cand.episodes), np.flatnonzero(np.isnan(score))
            if missing.size:
                rows = missing if per_seed else np.arange(B)
                total = _play(oracle, cand, seeds, rows, best_score[rows] * T)
                done = ~np.isnan(total)
                score[rows[done]] = total[done] / T
                recorded = recorded if per_seed else 0  # a network is played on the whole batch
                cand.piece = {r: p for r, p in cand.piece.items() if r not in cand.episodes}
                cand.cached -= set(cand.episodes)
            oracle.sources[name] = {"episodes": max(recorded, 0), "pieces": len(cand.piece), "cache": len(cand.cached),
                                    "played": int(missing.size if per_seed or not missing.size else B)}
            oracle.cached[name] = B - oracle.sources[name]["played"]
        oracle.timing[name] = time.perf_counter() - start
        done = ~np.isnan(score)
        oracle.scores[done, k] = score[done]
        better = done & (score > best_score)
        best_score[better] = score[better]
        best[better] = k
    oracle.choice = [oracle.candidates[j] for j in best]
    oracle._groups = []
    for j in np.unique(best).tolist():
        rows = np.flatnonzero(best == j)
        obj = found[j]
        if not isinstance(obj, _Candidate):  # compiled: a fresh copy acts live on its rows
            live = oracle.resolve(oracle.candidates[j])
            live.reset(seeds[rows])
            oracle._groups.append(("live", live, rows))
            continue
        need = np.array([r for r in rows.tolist() if r not in obj.episodes], dtype=np.int64)
        if need.size:  # chosen by a piece's or the cache's total: play it for its actions, and check that total
            start = time.perf_counter()
            play = need if obj.per_seed else np.arange(B)
            total = _play(oracle, obj, seeds, play, np.full(play.size, -np.inf))
            oracle.timing[obj.name] += time.perf_counter() - start
            for i, row in enumerate(play.tolist()):
                if row in need and total[i] / T != best_score[row]:
                    where = (f"the piece {obj.piece[row]}" if row in obj.piece else
                             f"the oracle's totals cache ({totals_cache.directory()})")
                    raise pieces.PieceMismatch(
                        f"{oracle.name}: {where} says {obj.name!r} scores {best_score[row]!r} on seed "
                        f"{int(seeds[row])}, playing it now gives {total[i] / T!r}: recompute it")
        oracle._groups.append(("recorded", Replay(c.max_facilities, c.max_personnel,
                                                  {r: obj.episodes[r] for r in rows.tolist()}), rows))


__all__ = ["Recorder", "Replay", "episode_of", "reset_replaying"]
