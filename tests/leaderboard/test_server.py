"""The hosted board's web server: uploads answered 201/200/400/401/413/429, what a submission shows per phase,
and 32 concurrent uploads over HTTP on SQLite and PostgreSQL (each stored once, quotas 429, no job lost or doubled).

The server never runs a policy; where a test needs a finished submission, :func:`run_jobs` plays the worker
through the queue's own API (claim, fenced write_rows, finish) with made-up rows.
"""

from __future__ import annotations

import contextlib
import json
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import numpy as np
import pandas as pd
import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from wfbench.leaderboard.board import queue
from wfbench.leaderboard.board.db import Board, jobs, packages, submissions
from wfbench.leaderboard.board.worker import Worker, aggregate
from wfbench.leaderboard.server.app import create_app
from wfbench.leaderboard.tracks import scenario_track

from tests.leaderboard.live_server import LiveServer
from wfbench.core.config import ScenarioConfig
from wfbench.harness.guard import PolicyError
from wfbench.harness.isolation.package import archive

TRACK = scenario_track(name="tiny-hosted",
                       config=ScenarioConfig.preset("small").replace(name="tiny-hosted", horizon=60),
                       public_seeds=(1000, 1001, 1002), test_seeds=(0, 1, 2),
                       description="a small hosted track for the tests",
                       references={"tiny-hosted": (0.0, 1.0)})  # no published constants: normalized = NSW
POLICY = """\
import numpy as np

class Policy:  # {tag}
    decisions = ()

    def reset(self, keys):
        pass

    def act(self, obs):
        return {{}}
"""


def make_package(tag: str = "a", entry: str = "pol:Policy", extra: dict[str, bytes] | None = None) -> bytes:
    """A small policy package (a zip with the manifest); another ``tag`` gives other bytes, so another hash."""
    members = {"wfbench-policy.json": json.dumps({"entry": entry, "format": 1}).encode(),
               "pol.py": POLICY.format(tag=tag).encode(), **(extra or {})}
    return archive(list(members.items()))


def fake_row(scenario: str, index: int, seed: int, nsw: float) -> dict:
    return {"scenario": scenario, "seed_index": index, "seed": seed, "workforce_cost": 10.0 + index,
            "utilization": 0.6, "downtime": 0.1, "nsw": nsw + 0.001 * (index % 7), "episode_length": 60,
            "invalid_actions": 0, "decision_ms_p50": 0.1, "decision_ms_p99": 0.2, "cpu_s": 0.01,
            "machine": "test machine"}


def nsw_evaluator(package_dir, entry, config, seeds, limits, key_secret, key_context, chunk_size=None):
    """The worker's evaluator for the tests: rows whose NSW is the package's ``nsw.txt`` (``fail: REASON`` fails)."""
    text = (Path(package_dir) / "nsw.txt").read_text()
    if text.startswith("fail: "):
        raise PolicyError(text.removeprefix("fail: "))
    frame = pd.DataFrame([fake_row("", i, s, float(text)) for i, s in enumerate(seeds)]).drop(
        columns=["scenario", "seed_index", "machine"])
    frame.attrs["log"] = f"ran {len(seeds)} episodes of {entry}\n"
    return frame


def package(nsw: float | str) -> bytes:
    """A package the tests' evaluator scores ``nsw`` (or fails with the reason of ``"fail: REASON"``)."""
    return make_package(f"nsw{nsw}", extra={"nsw.txt": str(nsw).encode()})


def run_jobs(board: Board, nsw: Callable[[str], float] = lambda name: 0.5, fail: Callable[[str], str] = lambda n: "",
             limit: int | None = None) -> list[int]:
    """Play the worker for every queued job (or ``limit`` of them): made-up rows, then done (or failed)."""
    finished = []
    while limit is None or len(finished) < limit:
        c = queue.claim(board.engine, "test-worker", lease_s=60)
        if c is None:
            break
        sub = board.submission(c.submission_id)
        reason = fail(sub.name)
        if reason:
            queue.finish(c, "failed", reason=reason, log="the policy's log\n")
        else:
            rows = [fake_row(sc, i, seed, nsw(sub.name)) for sc, i, seed in board.units(sub)]
            queue.write_rows(c, rows)
            queue.finish(c, "done", result=aggregate(board.rows(sub.id)), log=f"evaluated {sub.name}\n")
        finished.append(c.submission_id)
    return finished


def new_board(url) -> Board:
    # the development phase's quota is tested in test_hosted_owners; these tests upload more than it allows
    board = Board(url, tracks={TRACK.name: TRACK}, dev_concurrent=100, dev_daily_quota=100)
    board.create()
    return board


@dataclass
class Live:
    """A board served on 127.0.0.1 (:func:`serve_board`): its URL, an account's token, and its worker's switch."""

    board: Board
    url: str
    token: str
    start_worker: Callable[[], None]


@contextlib.contextmanager
def serve_board(db) -> Iterator[Live]:
    """A new board at ``db`` served by uvicorn; ``start_worker()`` runs the board's worker in a thread
    (:class:`wfbench.leaderboard.board.worker.Worker` with :func:`nsw_evaluator`) until the block ends."""
    board = new_board(db)
    stop = threading.Event()
    threads = []

    def start_worker() -> None:
        worker = Worker(board, "test-worker", lease_s=30, evaluator=nsw_evaluator, say=lambda line: None)
        t = threading.Thread(target=worker.run, kwargs={"poll_s": 0.1, "stop": stop}, daemon=True)
        t.start()
        threads.append(t)

    try:
        with LiveServer(create_app(board)) as url:
            yield Live(board, url, board.add_account("alice"), start_worker)
    finally:
        stop.set()
        for t in threads:
            t.join(timeout=30)
        board.close()


@pytest.fixture
def board(tmp_path) -> Iterator[Board]:
    b = new_board(tmp_path / "board.sqlite")
    yield b
    b.close()


@pytest.fixture
def client(board) -> Iterator[TestClient]:
    with TestClient(create_app(board, max_package_bytes=100_000)) as c:
        yield c


@pytest.fixture
def token(board) -> str:
    return board.add_account("alice")


def post(client, token: str | None, data: bytes, phase: str = "dev", **fields) -> httpx.Response:
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    form = {"track": TRACK.name, "phase": phase, **fields}
    return client.post("/api/submissions", headers=headers, data=form,
                       files={"package": ("pkg.zip", data, "application/zip")})


def count(board: Board, table: sa.Table) -> int:
    with board.engine.begin() as conn:
        return conn.execute(sa.select(sa.func.count()).select_from(table)).scalar_one()


def test_upload__a_new_package_is_201_and_the_same_again_is_200_with_the_same_submission(client, board, token):
    first = post(client, token, make_package())
    assert first.status_code == 201, first.text
    body = first.json()
    assert body["state"] == "queued" and body["created"] is True
    assert body["url"].endswith(f"/submissions/{body['id']}")
    again = post(client, token, make_package())
    assert again.status_code == 200 and again.json()["id"] == body["id"] and again.json()["created"] is False
    assert count(board, submissions) == 1 and count(board, jobs) == 1 and count(board, packages) == 1
    assert board.submission(body["id"]).entry == "pol:Policy"  # from the manifest
    other = post(client, token, make_package(), name="mine", entry="pol:Other")  # another entry: another submission
    assert other.status_code == 201 and board.submission(other.json()["id"]).name == "mine"


def test_upload__without_or_with_a_wrong_token_is_401_before_anything_is_stored(client, board):
    none = post(client, None, make_package())
    assert none.status_code == 401 and none.headers["www-authenticate"] == "Bearer"
    assert none.json()["detail"].startswith("no token: send the header 'Authorization: Bearer TOKEN'")
    wrong = post(client, "not-a-token", make_package())
    assert wrong.status_code == 401
    assert wrong.json()["detail"] == "the token is not valid; ask the board's admin for one"
    assert count(board, packages) == 0 and count(board, submissions) == 0


def test_upload__a_declared_size_over_the_limit_is_413_before_the_body_is_read(client, board, token):
    big = make_package(extra={"weights.bin": np.random.default_rng(0).bytes(256_000)})  # incompressible: ~256 kB
    r = post(client, token, big)
    assert r.status_code == 413
    assert r.json()["detail"] == ("the upload is larger than the package limit of 0.0953674 MiB (100000 bytes); "
                                  "allowed: a package of at most that size")
    assert count(board, packages) == 0


def multipart_chunks(total: int, pulled: list[int], chunk: int = 64 * 1024) -> Iterator[bytes]:
    """A multipart body with a ``total``-byte package, streamed (no Content-Length); counts what was sent."""
    yield (b"--B\r\nContent-Disposition: form-data; name=\"track\"\r\n\r\n" + TRACK.name.encode() + b"\r\n"
           b"--B\r\nContent-Disposition: form-data; name=\"package\"; filename=\"p.zip\"\r\n"
           b"Content-Type: application/zip\r\n\r\n")
    for _ in range(total // chunk):
        pulled[0] += chunk
        yield b"x" * chunk
    yield b"\r\n--B--\r\n"


def test_upload__a_streamed_body_is_cut_off_at_the_limit_with_413(board, token):
    pulled = [0]
    total = 64 * 2**20
    with LiveServer(create_app(board, max_package_bytes=100_000)) as url:
        r = httpx.post(f"{url}/api/submissions", content=multipart_chunks(total, pulled), timeout=60,
                       headers={"Authorization": f"Bearer {token}", "Content-Type": "multipart/form-data; boundary=B"})
    assert r.status_code == 413 and "larger than the package limit" in r.json()["detail"]
    assert pulled[0] < total // 4, f"the server read {pulled[0]} bytes of a body it refused at 100 kB"
    assert count(board, packages) == 0


@pytest.mark.parametrize(("data", "reason"), [
    (b"this is not a zip", "the package is refused: "),
    (make_package(extra={"../evil.py": b"x"}), "'../evil.py'"),
])
def test_upload__a_bad_package_is_400_with_a_one_line_reason(client, board, token, data, reason):
    r = post(client, token, data)
    assert r.status_code == 400
    detail = r.json()["detail"]
    assert detail.startswith("the package is refused: ") and reason in detail and "\n" not in detail
    assert count(board, submissions) == 0


@pytest.mark.parametrize(("fields", "detail"), [
    ({"track": "nope"}, "unknown track 'nope'; allowed: tiny-hosted"),
    ({"phase": "final"}, "unknown phase 'final'; allowed: dev, test"),
    ({"entry": "not an entry"}, "entry point 'not an entry' is not allowed; allowed: module:attr (dotted Python "
                                "names, for example mypolicy:Policy)"),
    ({"name": "\u00e9vil<script>"}, "name '\u00e9vil<script>' is not allowed; allowed: 1-64 letters, digits, spaces "
                                    "and ._+#@-, starting with a letter or digit"),
    ({"color": "red"}, "unknown form field 'color'; allowed: package, track, phase, name, entry"),
])
def test_upload__a_bad_field_is_400_naming_what_is_allowed(client, token, fields, detail):
    r = post(client, token, make_package(), **fields)
    assert r.status_code == 400 and r.json()["detail"] == detail


def test_upload__no_package_file_is_400(client, token):
    headers = {"Authorization": f"Bearer {token}"}
    r = client.post("/api/submissions", headers=headers, data={"track": TRACK.name},
                    files={"package": (None, "not a file")})  # a text field, not a file
    assert r.status_code == 400
    assert r.json()["detail"].startswith("the upload has no 'package' file; allowed: a form with the fields package")
    r = client.post("/api/submissions", headers=headers, data={"track": TRACK.name, "package": "x"})
    assert r.status_code == 400
    assert r.json()["detail"].startswith("the upload is not a multipart/form-data form; allowed: a form with")


def test_test_phase__a_second_job_while_one_is_queued_is_429_and_a_dedupe_hit_is_not_counted(client, board, token):
    first = post(client, token, make_package("t1"), phase="test")
    assert first.status_code == 201
    assert post(client, token, make_package("t1"), phase="test").status_code == 200  # the same: not a new job
    second = post(client, token, make_package("t2"), phase="test")
    assert second.status_code == 429
    assert second.json()["detail"] == (f"one test-phase job at a time per account: submission {first.json()['id']} is "
                                       "still queued; submit again once it is done or failed")
    assert post(client, token, make_package("t2"), phase="dev").status_code == 201  # the dev phase has no quota
    run_jobs(board)
    assert post(client, token, make_package("t2"), phase="test").status_code == 201  # the first one is done


def test_submission__dev_shows_rows_and_log_and_test_only_its_aggregate(client, board, token):
    dev = post(client, token, make_package("d")).json()["id"]
    test = post(client, token, make_package("t"), phase="test").json()["id"]
    queued = client.get(f"/api/submissions/{dev}").json()
    assert queued["state"] == "queued" and queued["progress"] == {"done": 0, "total": 3} and queued["rows"] == []
    run_jobs(board)
    d = client.get(f"/api/submissions/{dev}").json()
    assert d["state"] == "done" and d["reason"] == "" and d["progress"] == {"done": 3, "total": 3}
    assert [r["seed"] for r in d["rows"]] == [1000, 1001, 1002] and d["log"] == "evaluated pol:Policy\n"
    assert d["result"]["episodes"] == 3 and d["result"]["kpis"]["nsw"]["mean"] > 0.5
    t = client.get(f"/api/submissions/{test}")
    body = t.json()
    assert body["state"] == "done" and body["progress"] == {"done": 50, "total": 50}
    assert body["result"]["episodes"] == 50 and set(body["result"]["kpis"]) == {"workforce_cost", "utilization",
                                                                                 "downtime", "nsw"}
    assert "rows" not in body and "log" not in body
    hidden = board.ensure_hidden_seeds(TRACK.name).seeds
    assert not [s for s in hidden if str(s) in t.text], "a hidden seed is in the test submission's JSON"
    assert client.get("/api/submissions/999").json() == {"detail": "no submission 999"}
    assert client.get("/api/submissions/abc").json() == {
        "detail": "sub_id 'abc' is not allowed: Input should be a valid integer, unable to parse string as an integer"}
    assert client.get("/nowhere").status_code == 404 and "<p id='detail'>Not Found</p>" in client.get("/nowhere").text


def test_submission_page__what_a_policy_wrote_is_escaped(client, board, token):
    sub = post(client, token, make_package()).json()["id"]
    run_jobs(board, fail=lambda name: "the policy raised <script>alert(1)</script>")
    page = client.get(f"/submissions/{sub}")
    assert page.status_code == 200 and "<script>alert(1)" not in page.text
    assert "the policy raised &lt;script&gt;alert(1)&lt;/script&gt;" in page.text


def test_tracks_and_board_json__the_test_phase_publishes_only_its_commitment(client, board, token):
    tracks = client.get("/api/tracks").json()["tracks"]
    published = board.hidden_commitment(TRACK.name)
    assert tracks == [{"name": TRACK.name, "hash": TRACK.hash, "description": TRACK.description,
                       "scenarios": 1, "dev": {"seeds": "1000..1002", "count": 3},
                       "test": {"hidden": True, "count": 50, "version": 1, "commitment": published.commitment}}]
    for tag in ("lo", "hi"):
        post(client, token, make_package(tag), name=f"entry-{tag}")
    run_jobs(board, nsw=lambda name: {"entry-lo": 0.3, "entry-hi": 0.7}[name])
    dev = client.get(f"/api/board/{TRACK.name}", params={"phase": "dev"}).json()
    assert [e["name"] for e in dev["entries"]] == ["entry-hi", "entry-lo"] and dev["commitment"] is None
    assert [e["rank"] for e in dev["entries"]] == [1, 2]
    test = client.get(f"/api/board/{TRACK.name}", params={"phase": "test"}).json()
    assert test["entries"] == [] and test["commitment"] == published.commitment
    assert client.get(f"/api/board/{TRACK.name}", params={"phase": "x"}).json()["detail"] == \
        "unknown phase 'x'; allowed: dev, test"
    assert client.get("/api/board/nope").status_code == 404


# -- 32 concurrent uploads over HTTP, on SQLite and PostgreSQL --------------------------------------------------

@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request, tmp_path) -> str:
    if request.param == "sqlite":
        return str(tmp_path / "board.sqlite")
    return request.getfixturevalue("postgres_url")


@pytest.mark.slow
def test_32_concurrent_uploads__each_stored_once_quotas_429_no_job_lost_or_doubled(db_url):
    board = new_board(db_url)
    try:
        tokens = [board.add_account(f"user{i}") for i in range(4)]
        # 16 dev uploads: 8 packages, each sent by two accounts at once; 16 test uploads: 4 packages per account
        plan = [(tokens[i % 4], make_package(f"dev{i % 8}"), "dev") for i in range(16)]
        plan += [(tokens[i % 4], make_package(f"test{i}"), "test") for i in range(16)]
        answers: list[tuple[int, dict, str, bytes]] = [None] * len(plan)  # type: ignore[list-item]
        start = threading.Barrier(len(plan))
        with LiveServer(create_app(board)) as url:
            def send(i: int) -> None:
                token, data, phase = plan[i]
                start.wait()
                r = httpx.post(f"{url}/api/submissions", headers={"Authorization": f"Bearer {token}"},
                               data={"track": TRACK.name, "phase": phase},
                               files={"package": ("p.zip", data, "application/zip")}, timeout=120)
                answers[i] = (r.status_code, r.json(), phase, data)

            threads = [threading.Thread(target=send, args=(i,)) for i in range(len(plan))]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
        dev = [a for a in answers if a[2] == "dev"]
        assert Counter(code for code, *_ in dev) == {201: 8, 200: 8}, [a[:2] for a in dev]
        ids_by_package: dict[bytes, set[int]] = {}
        for _, body, _, data in dev:
            ids_by_package.setdefault(data, set()).add(body["id"])
        assert all(len(ids) == 1 for ids in ids_by_package.values()), "a package got two submissions"
        test = [a for a in answers if a[2] == "test"]
        assert Counter(code for code, *_ in test) == {201: 4, 429: 12}, [a[:2] for a in test]
        per_account = Counter(plan[i][0] for i, a in enumerate(answers) if a[2] == "test" and a[0] == 201)
        assert sorted(per_account.values()) == [1, 1, 1, 1], "one test job per account"
        assert all("one test-phase job at a time per account" in body["detail"] for code, body, *_ in test
                   if code == 429)
        assert count(board, submissions) == 12 and count(board, jobs) == 12
        claimed = []
        while (c := queue.claim(board.engine, "counter", lease_s=60)) is not None:
            claimed.append(c.submission_id)
        created = {body["id"] for code, body, *_ in answers if code == 201}
        assert sorted(claimed) == sorted(created), "every job claimed exactly once"
    finally:
        board.close()
