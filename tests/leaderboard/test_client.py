"""The hosted board's client (``wfbench leaderboard upload``): what it packs, what it refuses before sending,
and an upload followed to its end against a real server with the board's worker running (done, failed, refused)."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest
from wfbench.leaderboard.server.client import UploadError, load_package, upload

from tests.leaderboard.test_server import TRACK, Live, make_package, package, serve_board
from wfbench.cli import main
from wfbench.harness.isolation.package import content_hash

POLICY = "class Policy:\n    decisions = ()\n\n    def reset(self, keys):\n        pass\n\n    def act(self, obs):\n" \
         "        return {}\n"


@pytest.fixture
def live(tmp_path) -> Iterator[Live]:
    with serve_board(tmp_path / "board.sqlite") as served:
        yield served


def test_load_package__an_entry_point_is_packed_the_same_every_time(tmp_path):
    (tmp_path / "mypol.py").write_text(POLICY)
    first = load_package("mypol:Policy", root=tmp_path)
    assert first.entry == "mypol:Policy" and first.filename == "mypol.zip"
    assert content_hash(load_package("mypol:Policy", root=tmp_path).data) == content_hash(first.data)


def test_load_package__a_folder_with_a_manifest_and_a_zip_are_sent_as_packages(tmp_path):
    folder = tmp_path / "pkg"
    folder.mkdir()
    (folder / "mypol.py").write_text(POLICY)
    (folder / "wfbench-policy.json").write_text(json.dumps({"entry": "mypol:Policy", "format": 1}))
    assert load_package(str(folder)).entry == "mypol:Policy"
    archive = tmp_path / "p.zip"
    archive.write_bytes(make_package())
    got = load_package(str(archive))
    assert got.entry == "pol:Policy" and got.data == archive.read_bytes() and got.filename == "p.zip"


@pytest.mark.parametrize(("make", "message"), [
    (lambda p: p / "missing", "--policy '{p}/missing': no such file or folder, and not a module:attr entry point"),
    (lambda p: p, "--policy '{p}' is a folder without wfbench-policy.json; allowed: a folder with"),
    (lambda p: (p / "notes.txt").write_text("x") and p / "notes.txt", "--policy '{p}/notes.txt' is a file but not a "
                                                                      ".zip or .whl"),
    (lambda p: (p / "bad.zip").write_bytes(make_package(extra={"../x.py": b"x"})) and p / "bad.zip",
     "the package is refused: zip-slip: member '../x.py' would land outside the package"),
])
def test_load_package__what_cannot_be_sent_is_refused_with_one_line(tmp_path, make, message):
    with pytest.raises(UploadError) as err:
        load_package(str(make(tmp_path)))
    assert str(err.value).startswith(message.format(p=tmp_path)) and "\n" not in str(err.value)


def test_upload__follows_the_submission_to_done(live):
    live.start_worker()
    sub = upload(live.url, live.token, _zip(live, 0.6), TRACK.name, progress=False, poll_s=0.05)
    assert sub["state"] == "done" and sub["progress"] == {"done": 3, "total": 3}
    assert sub["result"]["kpis"]["nsw"]["mean"] == pytest.approx(0.601, abs=1e-3)


def _zip(live: Live, nsw: float | str) -> str:
    path = live.board.url.replace("board.sqlite", f"p{nsw}.zip")
    with open(path, "wb") as f:
        f.write(package(nsw))
    return path


@pytest.mark.slow
def test_cli_upload__prints_the_result_or_the_reason_with_status_1(live, capsys):
    live.start_worker()
    common = ["leaderboard", "upload", "--server", live.url, "--track", TRACK.name, "--no-progress"]
    assert main([*common, "--token", live.token, "--policy", _zip(live, 0.5), "--name", "mine"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"submission 1 (mine on {TRACK.name}, dev phase): done"
    assert out[1] == f"  page: {live.url}/submissions/1" and out[2] == "  episodes: 3"
    assert any(line.startswith("  nsw: 0.50") for line in out)
    assert main([*common, "--token", live.token, "--policy", _zip(live, "fail: the policy raised KeyError")]) == 1
    assert capsys.readouterr().err == (f"wfbench: error: submission 2 failed: the policy raised KeyError (see "
                                       f"{live.url}/submissions/2)\n")
    assert main([*common, "--token", "wrong", "--policy", _zip(live, 0.5)]) == 1
    assert capsys.readouterr().err == ("wfbench: error: the upload refused by the server (401): the token is not "
                                       "valid; ask the board's admin for one; check --token (an admin makes one with "
                                       "'wfbench serve account add NAME')\n")


def test_cli_upload__no_token_or_no_server_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("WFBENCH_TOKEN", raising=False)
    archive = tmp_path / "p.zip"
    archive.write_bytes(make_package())
    common = ["leaderboard", "upload", "--track", TRACK.name, "--policy", str(archive)]
    assert main([*common, "--server", "http://127.0.0.1:9"]) == 2
    assert capsys.readouterr().err == ("wfbench: error: no token: pass --token or set $WFBENCH_TOKEN (the board's "
                                       "admin makes one)\n")
    assert main([*common, "--server", "http://127.0.0.1:9", "--token", "t"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("wfbench: error: cannot reach the server at http://127.0.0.1:9: ") and err.count("\n") == 1
    assert main([*common, "--server", "127.0.0.1:9", "--token", "t"]) == 1
    assert capsys.readouterr().err == ("wfbench: error: --server '127.0.0.1:9' is not allowed; allowed: an http:// "
                                       "or https:// URL\n")
    assert main([*common, "--server", "http://127.0.0.1:9", "--token", "t", "--phase", "final"]) == 1
    assert capsys.readouterr().err == "wfbench: error: --phase 'final' is not allowed; allowed: dev, test\n"


def test_cli_serve_account_add__prints_the_token_once_and_it_opens_the_board(tmp_path, capsys):
    from wfbench.leaderboard.board.db import Board

    db = tmp_path / "b.sqlite"
    assert main(["serve", "--db", str(db), "account", "add", "bob"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "account 'bob' made; its token, shown only now:"
    board = Board(db)
    assert board.account(out[1]).name == "bob" and not board.account(out[1]).admin
    assert main(["serve", "account", "add", "carol", "--admin", "--db", str(db)]) == 0
    assert board.account(capsys.readouterr().out.splitlines()[1]).admin
    assert main(["serve", "--db", str(db), "account", "add", "bob"]) == 2
    assert capsys.readouterr().err == "wfbench: error: account name 'bob' is taken; choose another\n"
    assert main(["serve", "--db", "mysql://x/y", "account", "add", "dan"]) == 2
    assert "wfbench: error: database 'mysql://x/y' is not allowed; allowed: a file path" in capsys.readouterr().err
    assert main(["serve", "--tracks", "nope", "--db", str(db)]) == 2
    assert capsys.readouterr().err.startswith("wfbench: error: --tracks: unknown track 'nope'; allowed: paper-64, ")
    board.close()


def test_cli_serve__runs_uvicorn_on_the_address_asked_without_printing_a_password(tmp_path, capsys, monkeypatch):
    import uvicorn

    seen = {}
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: seen.update(app=app, **kw))
    assert main(["serve", "--db", str(tmp_path / "b.sqlite"), "--port", "8123", "--tracks", "paper-64"]) == 0
    assert seen["host"] == "127.0.0.1" and seen["port"] == 8123
    # the routes are APIRouter modules: FastAPI (0.165) includes a router as one entry of app.routes, so the
    # served paths are read from the app's OpenAPI document
    assert "/api/submissions" in seen["app"].openapi()["paths"]
    assert seen["app"].state.board.tracks.keys() == {"paper-64"}
    assert capsys.readouterr().out == (f"wfbench leaderboard on http://127.0.0.1:8123 (database sqlite:///{tmp_path}/"
                                       f"b.sqlite); start 'wfbench worker --server {tmp_path}/b.sqlite' to evaluate "
                                       "the submissions\n")
    assert main(["serve", "--port", "70000"]) == 2
    assert capsys.readouterr().err == ("wfbench: error: argument --port: 70000 is not allowed; allowed: a port "
                                       "1..65535\n")
