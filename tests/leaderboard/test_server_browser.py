"""The hosted board's pages in a real headless Chromium, served by uvicorn on 127.0.0.1 with a worker running.

The worker is the board's own (:class:`wfbench.leaderboard.board.worker.Worker`: claim, fenced writes,
heartbeats, finish) in a thread, with an in-process evaluator that makes rows from a number in the package
(``nsw.txt``) instead of running the sandbox, so the boards' order is known; the sandbox itself is tested in
tests/harness/test_sandbox.py and end to end in tests/leaderboard/test_hosted_security.py.
"""

from __future__ import annotations

import re
import subprocess
import time
from collections.abc import Iterator

import httpx
import pytest
from wfbench.leaderboard.server.pages import board_ranking

from tests.leaderboard.test_server import TRACK, package, serve_board

pytestmark = [pytest.mark.slow, pytest.mark.needs_browser]


@pytest.fixture
def served(tmp_path) -> Iterator[tuple]:
    with serve_board(tmp_path / "board.sqlite") as live:
        yield live.board, live.url, live.token, live.start_worker


def dom(browser: str, url: str) -> str:
    """The page's DOM after its scripts ran, as headless Chromium sees it."""
    out = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=1000",
                          "--dump-dom", url], capture_output=True, text=True, timeout=120)
    assert "<html" in out.stdout, out.stderr[-2000:]
    return out.stdout


def upload(url: str, token: str, data: bytes, phase: str = "dev", name: str | None = None) -> int:
    r = httpx.post(f"{url}/api/submissions", headers={"Authorization": f"Bearer {token}"},
                   data={"track": TRACK.name, "phase": phase, **({"name": name} if name else {})},
                   files={"package": ("p.zip", data, "application/zip")})
    assert r.status_code == 201, r.text
    return r.json()["id"]


def wait_final(board, ids: list[int], timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if all(board.submission(i).state in ("done", "failed") for i in ids):
            return
        time.sleep(0.1)
    raise AssertionError(f"not finished in {timeout_s:g} s: {[(i, board.submission(i).state) for i in ids]}")


def names_in(page: str, table: str = "ranking") -> list[str]:
    """The Name column of a board table in the DOM, top to bottom."""
    body = re.search(rf'<table id="{table}">.*?<tbody>(.*?)</tbody>', page, re.S)
    assert body, f"no table {table!r} on the page"
    return [re.findall(r"<td>(.*?)</td>", row)[1] for row in re.findall(r"<tr>(.*?)</tr>", body.group(1), re.S)]


def test_home_page__tracks_the_client_command_and_the_upload_form(served, browser):
    board, url, token, _ = served
    page = dom(browser, f"{url}/")
    assert f"wfbench leaderboard upload --server {url} --token TOKEN --policy mypkg.policy:MyPolicy" in page
    form = re.search(r'<form id="upload".*?</form>', page, re.S).group(0)
    assert 'action="/submit"' in form and 'enctype="multipart/form-data"' in form
    for field in ("token", "package", "track", "phase", "name", "entry"):
        assert f'name="{field}"' in form, field
    assert f'<option value="{TRACK.name}">' in form
    assert board.hidden_commitment(TRACK.name).commitment in page


def test_submission_page__the_state_moves_to_done_with_a_worker_running(served, browser):
    board, url, token, start_worker = served
    posted = httpx.post(f"{url}/submit", data={"token": token, "track": TRACK.name, "phase": "dev"},
                        files={"package": ("p.zip", package(0.4), "application/zip")})  # the home page's form
    assert posted.status_code == 303
    page_url = url + posted.headers["location"]
    sub_id = int(posted.headers["location"].rsplit("/", 1)[1])
    queued = dom(browser, page_url)
    assert 'data-state="queued"' in queued and 'http-equiv="refresh"' in queued
    start_worker()
    wait_final(board, [sub_id])
    done = dom(browser, page_url)
    assert 'data-state="done"' in done and 'http-equiv="refresh"' not in done
    assert '<span id="progress">3/3</span>' in done
    assert names_in(done.replace('id="rows"', 'id="ranking"'))  # the dev phase's per-seed rows are listed
    assert "<td>1000</td>" in done and "ran 3 episodes of pol:Policy" in done  # public seeds and the log
    bad = httpx.post(f"{url}/submit", data={"token": "wrong", "track": TRACK.name},
                     files={"package": ("p.zip", package(0.4), "application/zip")})
    assert bad.status_code == 401 and "the token is not valid" in bad.text


def test_boards__order_is_the_database_ranking_and_the_test_phase_shows_no_per_seed_rows(served, browser):
    board, url, token, start_worker = served
    others = [board.add_account(f"user{i}") for i in range(3)]
    ids = [upload(url, token, package(nsw), name=f"dev-{nsw}") for nsw in (0.2, 0.6, 0.4)]
    ids += [upload(url, t, package(nsw), phase="test", name=f"test-{nsw}")
            for t, nsw in zip([token, *others], (0.5, 0.3, 0.7, 0.1), strict=True)]
    start_worker()
    wait_final(board, ids)
    dev = dom(browser, f"{url}/board/{TRACK.name}?phase=dev")
    assert names_in(dev) == ["dev-0.6", "dev-0.4", "dev-0.2"]
    assert names_in(dev) == board_ranking(board, TRACK.name, "dev").table["name"].tolist()
    test = dom(browser, f"{url}/board/{TRACK.name}?phase=test")
    assert names_in(test) == ["test-0.7", "test-0.5", "test-0.3", "test-0.1"]
    assert names_in(test) == board_ranking(board, TRACK.name, "test").table["name"].tolist()
    # the IQM chart only (no entry is the baseline "heuristic" to pair with), and no per-seed KPI figure
    assert 'data-images-decoded="1"' in test and "per-seed KPIs" not in test
    assert board.hidden_commitment(TRACK.name).commitment in test
    hidden = board.ensure_hidden_seeds(TRACK.name).seeds
    pages = [test, dom(browser, f"{url}/submissions/{ids[3]}")]
    pages += [httpx.get(f"{url}{path}/{i}").text for i in ids[3:] for path in ("/submissions", "/api/submissions")]
    pages.append(httpx.get(f"{url}/api/board/{TRACK.name}?phase=test").text)
    for text in pages:
        assert not [s for s in hidden if str(s) in text], "a hidden seed left the server"
        assert not re.search(r"""id=["'](rows|log)["']|"rows":""", text), "per-seed rows or a log of the test phase"
    assert 'data-state="done"' in pages[1] and "only its aggregate" in pages[1]
