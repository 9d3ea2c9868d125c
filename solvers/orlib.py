"""Readers for J.E. Beasley's OR-Library formats (uncapacitated facility location, p-median, assignment).

Every file is read as a stream of whitespace-separated tokens: line breaks carry no
meaning (rows are wrapped). A file that does not match its format raises
:class:`OrlibFormatError` naming the file, what was expected and what was found.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path


class OrlibFormatError(ValueError):
    """A file is not in the OR-Library format it was read as."""


class UFLInstance(NamedTuple):
    fixed_cost: np.ndarray  # (m,) opening cost of each potential facility
    cost: np.ndarray  # (m, n) cost of serving all of customer j's demand from facility i
    demand: np.ndarray  # (n,) reported, not used by the uncapacitated objective
    capacity: np.ndarray  # (m,) NaN where the file says "capacity"; ignored by UFL


class PMedianInstance(NamedTuple):
    dist: np.ndarray  # (n, n) all-pairs shortest-path distances
    p: int


def _tokens(path: str | os.PathLike) -> tuple[Path, list[str]]:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise OrlibFormatError(f"cannot read {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise OrlibFormatError(f"{path}: not a text file") from None
    return path, text.split()


class _Stream:
    def __init__(self, path: Path, tokens: list[str], fmt: str):
        self.path, self.tokens, self.fmt, self.pos = path, tokens, fmt, 0

    def error(self, what: str) -> OrlibFormatError:
        return OrlibFormatError(f"{self.path}: not an OR-Library {self.fmt} file: {what} (token {self.pos + 1})")

    def number(self, what: str, *, integer: bool = False, allow: tuple[str, ...] = ()) -> float:
        if self.pos >= len(self.tokens):
            raise self.error(f"file ends where {what} was expected")
        tok = self.tokens[self.pos]
        self.pos += 1
        if tok in allow:
            return float("nan")
        try:
            v = float(tok)
        except ValueError:
            raise self.error(f"expected {what}, found {tok!r}") from None
        if not np.isfinite(v):
            raise self.error(f"{what} is {tok!r}; it must be finite")
        if integer and v != int(v):
            raise self.error(f"expected an integer {what}, found {tok!r}")
        return v

    def block(self, count: int, what: str) -> np.ndarray:
        end = self.pos + count
        if end > len(self.tokens):
            raise self.error(f"file ends after {len(self.tokens) - self.pos} of {count} {what}")
        try:
            arr = np.array(self.tokens[self.pos:end], dtype=np.float64)
        except ValueError:
            bad = next(t for t in self.tokens[self.pos:end] if not _is_number(t))
            raise self.error(f"expected {count} numbers ({what}), found {bad!r}") from None
        if not np.isfinite(arr).all():
            raise self.error(f"{what} contain a non-finite value")
        self.pos = end
        return arr

    def done(self) -> None:
        if self.pos != len(self.tokens):
            raise self.error(f"{len(self.tokens) - self.pos} unexpected token(s) after the data")


def _is_number(t: str) -> bool:
    try:
        float(t)
    except ValueError:
        return False
    return True


def _positive_int(s: _Stream, what: str) -> int:
    v = s.number(what, integer=True)
    if v < 1:
        raise s.error(f"{what} = {int(v)}; it must be >= 1")
    return int(v)


def read_uflp(path: str | os.PathLike) -> UFLInstance:
    """An uncapacitated facility location instance (cap71..134, capa/b/c)."""
    s = _Stream(*_tokens(path), "uncapacitated facility location")
    m = _positive_int(s, "the number of facilities m")
    n = _positive_int(s, "the number of customers n")
    capacity = np.empty(m)
    fixed = np.empty(m)
    for i in range(m):
        capacity[i] = s.number(f"facility {i + 1}'s capacity", allow=("capacity",))
        fixed[i] = s.number(f"facility {i + 1}'s fixed cost")
    demand = np.empty(n)
    cost = np.empty((m, n))
    for j in range(n):
        demand[j] = s.number(f"customer {j + 1}'s demand")
        cost[:, j] = s.block(m, f"costs of customer {j + 1}")
    s.done()
    if (fixed < 0).any() or (cost < 0).any():
        raise s.error("negative fixed or service costs")
    return UFLInstance(fixed, cost, demand, capacity)


def read_p_median(path: str | os.PathLike) -> PMedianInstance:
    """A p-median instance (pmed1..40): the shortest-path distance matrix and p.

    Edges are undirected; when an edge appears more than once the last occurrence
    counts (as in the instances whose optima were published).
    """
    s = _Stream(*_tokens(path), "p-median")
    n = _positive_int(s, "the number of vertices")
    e = int(s.number("the number of edges", integer=True))
    if e < 0:
        raise s.error(f"the number of edges is {e}")
    p = _positive_int(s, "p")
    if p > n:
        raise s.error(f"p = {p} exceeds the number of vertices {n}")
    edges = s.block(3 * e, f"{e} edges (i j cost)").reshape(e, 3)
    s.done()
    ij = edges[:, :2]
    if (ij != np.round(ij)).any() or (ij < 1).any() or (ij > n).any():
        raise s.error(f"an edge endpoint is not a vertex number in 1..{n}")
    if (edges[:, 2] < 0).any():
        raise s.error("an edge has a negative cost")
    a = ij[:, 0].astype(np.int64) - 1
    b = ij[:, 1].astype(np.int64) - 1
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    # an edge listed more than once (in either direction) keeps its last cost
    _, first_in_reversed = np.unique((lo * n + hi)[::-1], return_index=True)
    last = e - 1 - first_in_reversed
    W = np.full((n, n), np.inf)
    W[lo[last], hi[last]] = edges[last, 2]
    W[hi[last], lo[last]] = edges[last, 2]
    np.fill_diagonal(W, 0.0)
    finite = np.isfinite(W)
    # stored entries are edges, zero-cost ones included
    graph = csr_matrix((W[finite], np.nonzero(finite)), shape=(n, n))
    dist = shortest_path(graph, method="D", directed=False)
    if not np.isfinite(dist).all():
        raise s.error("the graph is not connected, so some vertices cannot reach a median")
    return PMedianInstance(dist, p)


def read_assignment(path: str | os.PathLike) -> np.ndarray:
    """A square linear assignment instance (assign100..800): the (n, n) cost matrix."""
    s = _Stream(*_tokens(path), "assignment")
    n = _positive_int(s, "n")
    C = s.block(n * n, f"{n}x{n} costs").reshape(n, n)
    s.done()
    return C
