"""Issue #42: in the test phase a failure's reason is a fixed vocabulary, so it cannot carry what a policy saw.

The attack, in the real sandbox: a policy raises an exception whose text is built from its observations. During
the test phase nothing a reader of the board gets (the submission's JSON and page, its owner's list, the board as
JSON and HTML) holds that text: only the word "raised". The board's administrator sees the whole reason, and
everyone does once the test phase has ended (when no test submission is taken any more).
"""

from __future__ import annotations

import textwrap

import pytest
from fastapi.testclient import TestClient
from wfbench.leaderboard.board.db import FAILURE_KINDS, Board
from wfbench.leaderboard.board.worker import Worker
from wfbench.leaderboard.server.app import create_app

from tests.leaderboard.test_server import make_package, post
from tests.leaderboard.test_worker import TINY
from wfbench.harness.isolation.package import pack

LEAKY = textwrap.dedent("""
    import numpy as np


    class Leaky:
        decisions = ("dispatch", "workforce", "positioning")

        def reset(self, keys):
            pass

        def act(self, obs):
            seen = np.asarray(obs["dispatch_mask"]).reshape(-1)[:40].astype(int)
            raise ValueError("LEAK" + "".join(str(v) for v in seen))
""")


@pytest.fixture
def leaky(tmp_path) -> bytes:
    (tmp_path / "leakypkg").mkdir()
    (tmp_path / "leakypkg" / "__init__.py").write_text(LEAKY)
    return pack("leakypkg:Leaky", root=tmp_path)


def test_a_policy_cannot_get_observation_text_out_through_its_test_phase_reason(tmp_path, bwrap, leaky):
    board = Board(tmp_path / "b.sqlite", tracks={"tiny": TINY})
    board.create()
    owner, admin = board.add_account("mallory"), board.add_account("root", admin=True)
    with TestClient(create_app(board)) as client:
        form = {"track": "tiny"}
        sub = client.post("/api/submissions", headers={"Authorization": f"Bearer {owner}"},
                          data={**form, "phase": "test"}, files={"package": ("p.zip", leaky, "application/zip")})
        assert sub.status_code == 201, sub.text
        sid = sub.json()["id"]
        assert Worker(board, "w", chunk_size=3, say=lambda line: None).run_one() == "failed"
        stored = board.submission(sid)
        assert "LEAK" in stored.reason and stored.kind == "raised", "the board keeps the whole reason"

        seen = {
            "json": client.get(f"/api/submissions/{sid}").text,
            "json as owner": client.get(f"/api/submissions/{sid}", headers={"Authorization": f"Bearer {owner}"}).text,
            "owner's list": client.get("/api/submissions", headers={"Authorization": f"Bearer {owner}"}).text,
            "page": client.get(f"/submissions/{sid}").text,
            "board json": client.get("/api/board/tiny?phase=test").text,
            "board html": client.get("/board/tiny?phase=test").text,
        }
        for where, text in seen.items():
            assert "LEAK" not in text, f"the policy's text reached the {where}"
        assert client.get(f"/api/submissions/{sid}").json()["reason"] == "raised"
        assert "raised" in seen["page"] and "raised" in seen["board html"]

        as_admin = client.get(f"/api/submissions/{sid}", headers={"Authorization": f"Bearer {admin}"}).json()
        assert "LEAK" in as_admin["reason"], "the administrator sees the whole reason"

        board.end_test_phase("tiny")
        assert "LEAK" in client.get(f"/api/submissions/{sid}").json()["reason"], "shown once the phase ended"
        late = post(client, owner, make_package("late"), phase="test", track="tiny")
        assert late.status_code == 400
        assert late.json()["detail"].startswith("the test phase of track tiny ended at ")
    board.close()


def test_the_vocabulary_is_fixed():
    assert FAILURE_KINDS == ("raised", "timed out", "out of memory", "bad action", "package refused", "board fault")
