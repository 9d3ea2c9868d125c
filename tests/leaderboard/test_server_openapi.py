"""The hosted server's OpenAPI document describes every answer: each JSON route's success answer has a response
model, each refusal the one-line ``{"detail"}`` model, each page its HTML, and the token routes their bearer scheme.
"""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from wfbench.leaderboard.server.app import create_app

from tests.leaderboard.test_server import TRACK, make_package, new_board, post


@pytest.fixture
def board(tmp_path):
    b = new_board(tmp_path / "board.sqlite")
    yield b
    b.close()


@pytest.fixture
def app(board):
    return create_app(board)


def operations(doc):
    for path, methods in doc["paths"].items():
        for method, op in methods.items():
            yield path, method, op


def schema_of(doc, ref_or_schema):
    ref = ref_or_schema.get("$ref", "")
    return doc["components"]["schemas"][ref.rsplit("/", 1)[-1]] if ref else ref_or_schema


def test_every_route_is_in_the_document(app):
    routes = {("/api/submissions", "post"), ("/api/submissions", "get"), ("/api/submissions/{sub_id}", "get"),
              ("/api/submissions/{sub_id}", "delete"), ("/api/tracks", "get"), ("/api/board/{track}", "get"),
              ("/", "get"), ("/submit", "post"), ("/board/{track}", "get"), ("/submissions/{sub_id}", "get")}
    assert {(p, m) for p, m, _ in operations(app.openapi())} == routes


def test_every_json_answer_has_a_model_with_its_fields(app):
    doc = app.openapi()
    for path, method, op in operations(doc):
        if not path.startswith("/api/"):
            continue
        success = {code: r for code, r in op["responses"].items() if code.startswith("2")}
        assert success, f"{method} {path}: no success answer"
        for code, r in success.items():
            schema = r["content"]["application/json"]["schema"]
            assert "$ref" in schema, f"{method} {path} {code}: an answer without a model"
            model = schema_of(doc, schema)
            assert model["type"] == "object" and model["properties"] and model["required"], (method, path, code)
        for code, r in op["responses"].items():
            if code[0] == "4" and code != "422":
                assert r["content"]["application/json"]["schema"] == {"$ref": "#/components/schemas/Problem"}, (
                    method, path, code)


def test_pages_answer_html_and_the_form_redirects(app):
    doc = app.openapi()
    for path, method, op in operations(doc):
        if path.startswith("/api/"):
            continue
        if (path, method) == ("/submit", "post"):
            assert set(op["responses"]) >= {"303"} and "multipart/form-data" in op["requestBody"]["content"]
            continue
        assert op["responses"]["200"]["content"]["text/html"]["schema"] == {"type": "string"}, (method, path)


def test_the_documented_answers_name_what_the_routes_return(app):
    doc = app.openapi()
    answers = {(p, m): op["responses"] for p, m, op in operations(doc)}
    ref = "#/components/schemas/{}".format
    assert answers["/api/submissions", "post"]["201"]["content"]["application/json"]["schema"]["$ref"] == ref("Created")
    assert {"401", "400", "413", "429", "200"} <= set(answers["/api/submissions", "post"])
    assert answers["/api/submissions/{sub_id}", "get"]["200"]["content"]["application/json"]["schema"]["$ref"] \
        == ref("SubmissionDetail")
    assert answers["/api/board/{track}", "get"]["200"]["content"]["application/json"]["schema"]["$ref"] \
        == ref("BoardRanking")
    detail = doc["components"]["schemas"]["SubmissionDetail"]
    assert {"progress", "result", "log", "rows"} <= set(detail["properties"])
    assert "log" not in detail["required"] and "rows" not in detail["required"], "the test phase leaves them out"
    upload = doc["paths"]["/api/submissions"]["post"]["requestBody"]["content"]["multipart/form-data"]["schema"]
    assert set(upload["properties"]) == {"package", "track", "phase", "name", "entry"}
    bearer = [name for name, s in doc["components"]["securitySchemes"].items() if s["scheme"] == "bearer"]
    for path, method in (("/api/submissions", "post"), ("/api/submissions", "get"),
                         ("/api/submissions/{sub_id}", "delete")):
        assert doc["paths"][path][method]["security"] == [{bearer[0]: []}], (method, path)


def test_the_answers_match_their_models(app, board):
    """What the routes answer has exactly the fields the document names (no more, and for dev all of them)."""
    doc = app.openapi()
    props = {name: set(s.get("properties", ())) for name, s in doc["components"]["schemas"].items()}
    token = board.add_account("alice")
    with TestClient(app) as client:
        made = post(client, token, make_package("one"))
        assert made.status_code == 201 and set(made.json()) == props["Created"]
        sub = client.get(f"/api/submissions/{made.json()['id']}").json()
        assert set(sub) == props["SubmissionDetail"] and set(sub["progress"]) == props["Progress"]
        mine = client.get("/api/submissions", headers={"Authorization": f"Bearer {token}"}).json()
        assert set(mine) == props["Submissions"] and set(mine["submissions"][0]) == props["SubmissionSummary"]
        tracks = client.get("/api/tracks").json()["tracks"]
        assert [set(t) for t in tracks] == [props["TrackInfo"]] and tracks[0]["name"] == TRACK.name
        assert set(client.get(f"/api/board/{TRACK.name}").json()) == props["BoardRanking"]
