"""The client of a hosted board (``wfbench leaderboard upload``): pack, upload, follow the state, print the result.

A ``module:attr`` entry point is packed from the current folder
(:func:`~wfbench.harness.isolation.package.pack`: the same code gives the same bytes, so an
upload again is a dedupe hit), a folder with ``wfbench-policy.json`` as it is, a ``.zip`` or
``.whl`` sent as it is; each is checked with :func:`~wfbench.harness.isolation.package.inspect`
before it leaves. The client then polls the submission until ``done`` or ``failed`` on a tqdm
bar. :meth:`Client.mine` and :meth:`Client.withdraw` serve ``wfbench leaderboard mine`` and
``withdraw``. Every refusal is a one-line :class:`UploadError`. ``docs/leaderboard.md``, "The
hosted leaderboard".
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx

MANIFEST = "wfbench-policy.json"
FINAL_STATES = ("done", "failed")
POLL_S = 1.0
HTTP_TIMEOUT_S = 120.0  # one request; an upload of a large package over a slow link needs the time


class UploadError(Exception):
    """The upload or the evaluation did not succeed: one line saying what and, where it can, what to do."""


@dataclass(frozen=True)
class Package:
    """What is uploaded: the archive's bytes and a name for it (the file name the server records)."""

    data: bytes
    filename: str
    entry: str  # the manifest's entry point


def load_package(policy: str, root: str | Path = ".") -> Package:
    """The package that ``--policy`` names, checked as the server will check it.

    Args:
        policy: a ``.zip``/``.whl`` file, a folder with ``wfbench-policy.json``, or a
            ``module:attr`` entry point found under ``root``.
        root: where an entry point's module is looked up (the current folder).

    Raises:
        UploadError: nothing of that name, or a package :func:`~wfbench.harness.isolation.package.inspect` refuses.
    """
    from wfbench.harness.isolation.package import PackageError, inspect, pack, pack_folder

    path = Path(policy)
    try:
        if path.is_file():
            if path.suffix not in (".zip", ".whl"):
                raise UploadError(f"--policy {policy!r} is a file but not a .zip or .whl; allowed: a .zip or .whl "
                                  f"policy package, a folder with {MANIFEST}, or a module:attr entry point")
            data, filename = path.read_bytes(), path.name
        elif path.is_dir():
            if not (path / MANIFEST).is_file():
                raise UploadError(f"--policy {policy!r} is a folder without {MANIFEST}; allowed: a folder with "
                                  f"{MANIFEST}, a .zip or .whl package, or a module:attr entry point")
            data, filename = pack_folder(path), f"{path.resolve().name}.zip"
        elif ":" in policy:
            data, filename = pack(policy, root=str(root)), f"{policy.partition(':')[0]}.zip"
        else:
            raise UploadError(f"--policy {policy!r}: no such file or folder, and not a module:attr entry point; "
                              f"allowed: a .zip or .whl package, a folder with {MANIFEST}, or module:attr")
        manifest = inspect(data)
    except PackageError as exc:
        raise UploadError(f"the package is refused: {exc}") from None
    except OSError as exc:
        raise UploadError(f"cannot read --policy {policy!r}: {exc.strerror or exc}") from None
    return Package(data, filename, manifest.entry)


def _detail(response: httpx.Response) -> str:
    """The server's one-line reason (FastAPI's ``{"detail": ...}``), else the start of the body."""
    try:
        detail = response.json().get("detail")
    except (ValueError, AttributeError):
        detail = None
    text = detail if isinstance(detail, str) else response.text[:200]
    return " ".join(text.split()) or response.reason_phrase


HINTS = {401: "check --token (an admin makes one with 'wfbench serve account add NAME')",
         413: "make the package smaller (leave out data the policy does not load)",
         429: "wait for your queued or running jobs of that phase, or until the daily quota frees up"}


def _check(response: httpx.Response, what: str) -> dict[str, Any]:
    """The JSON of a successful answer; an :class:`UploadError` naming the status and the server's reason else."""
    if response.is_success:
        return response.json()
    hint = HINTS.get(response.status_code)
    raise UploadError(f"{what} refused by the server ({response.status_code}): {_detail(response)}"
                      + (f"; {hint}" if hint else ""))


class Client:
    """A hosted board's JSON API over HTTP with an account's token."""

    def __init__(self, server: str, token: str | None = None, timeout_s: float = HTTP_TIMEOUT_S,
                 transport: httpx.BaseTransport | None = None) -> None:
        if not server.startswith(("http://", "https://")):
            raise UploadError(f"--server {server!r} is not allowed; allowed: an http:// or https:// URL")
        self.server = server.rstrip("/")
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        self.http = httpx.Client(base_url=self.server, headers=headers, timeout=timeout_s, transport=transport)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.http.close()

    def _request(self, method: str, url: str, what: str, **kw: Any) -> dict[str, Any]:
        try:
            response = self.http.request(method, url, **kw)
        except httpx.TransportError as exc:
            raise UploadError(f"cannot reach the server at {self.server}: {exc or type(exc).__name__}") from None
        return _check(response, what)

    def submit(self, package: Package, track: str, phase: str = "dev", name: str | None = None,
               entry: str | None = None) -> dict[str, Any]:
        """Upload ``package``; the server's answer: ``id``, ``state``, ``url``, ``created`` (False: a dedupe hit)."""
        fields = {"track": track, "phase": phase}
        if name:
            fields["name"] = name
        if entry:
            fields["entry"] = entry
        files = {"package": (package.filename, package.data, "application/zip")}
        return self._request("POST", "/api/submissions", "the upload", data=fields, files=files)

    def submission(self, sub_id: int) -> dict[str, Any]:
        return self._request("GET", f"/api/submissions/{sub_id}", f"reading submission {sub_id}")

    def mine(self) -> list[dict[str, Any]]:
        """The token's account's submissions, oldest first (``GET /api/submissions``)."""
        return self._request("GET", "/api/submissions", "listing your submissions")["submissions"]

    def withdraw(self, sub_id: int) -> dict[str, Any]:
        """Withdraw submission ``sub_id`` (``DELETE /api/submissions/ID``): off the board, its queued job cancelled."""
        return self._request("DELETE", f"/api/submissions/{sub_id}", f"withdrawing submission {sub_id}")

    def tracks(self) -> list[dict[str, Any]]:
        return self._request("GET", "/api/tracks", "the track list")["tracks"]

    def follow(self, sub_id: int, progress: bool = True, poll_s: float = POLL_S, wait_s: float | None = None,
               sleep: Callable[[float], None] = time.sleep) -> dict[str, Any]:
        """Poll submission ``sub_id`` until it is done or failed (or ``wait_s`` passed); its last JSON.

        The bar counts the episodes stored (``progress.done`` of ``progress.total``) and
        shows the state; a submission that stays queued says so in the bar's text.
        """
        bar = None
        start = time.monotonic()
        try:
            while True:
                sub = self.submission(sub_id)
                done, total = sub["progress"]["done"], sub["progress"]["total"]
                if progress:
                    if bar is None:
                        from tqdm.auto import tqdm

                        bar = tqdm(total=total, desc=f"submission {sub_id}", unit="episode", leave=True)
                    bar.n = done
                    bar.set_postfix_str(sub["state"], refresh=True)
                if sub["state"] in FINAL_STATES:
                    return sub
                if wait_s is not None and time.monotonic() - start > wait_s:
                    raise UploadError(f"submission {sub_id} is still {sub['state']} after {wait_s:g} s; follow it at "
                                      f"{sub['url']}")
                sleep(poll_s)
        finally:
            if bar is not None:
                bar.close()


def result_lines(sub: dict[str, Any]) -> list[str]:
    """What the command prints of a finished submission: its state, page and aggregate KPIs."""
    head = (f"submission {sub['id']} ({sub['name']} on {sub['track']}, {sub['phase']} phase): {sub['state']}"
            + (f": {sub['reason']}" if sub.get("reason") else ""))
    lines = [head, f"  page: {sub['url']}"]
    result = sub.get("result") or {}
    if result:
        lines.append(f"  episodes: {result.get('episodes')}")
    for key, q in (result.get("kpis") or {}).items():
        lines.append(f"  {key}: {_num(q.get('mean'))} (25%-75%: {_num(q.get('q25'))}-{_num(q.get('q75'))})")
    return lines


MINE_HEADER = ("id", "track", "phase", "state", "name", "reason")


def mine_lines(subs: list[dict[str, Any]]) -> list[str]:
    """What ``wfbench leaderboard mine`` prints: a header, then one line per submission (its reason, or its note)."""
    cells = [list(MINE_HEADER)] + [[str(s["id"]), s["track"], s["phase"], s["state"], s["name"],
                                    s.get("reason") or s.get("note") or ""] for s in subs]
    widths = [max(len(row[i]) for row in cells) for i in range(len(MINE_HEADER) - 1)]
    return ["  ".join([*(c.ljust(w) for c, w in zip(row[:-1], widths, strict=True)), row[-1]]).rstrip()
            for row in cells]


def _num(value: Any) -> str:
    return f"{value:.4f}" if isinstance(value, float) else str(value)


def upload(server: str, token: str, policy: str, track: str, phase: str = "dev", name: str | None = None,
           entry: str | None = None, wait: bool = True, progress: bool = True, poll_s: float = POLL_S,
           root: str | Path = ".", transport: httpx.BaseTransport | None = None) -> dict[str, Any]:
    """Pack ``policy``, upload it to ``track``'s ``phase`` and (``wait``) follow it to its end.

    Returns:
        The submission's last JSON (``state`` ``done`` or, with ``wait=False``, whatever it is now).

    Raises:
        UploadError: the package is refused (here or by the server), the server cannot be
            reached or refuses the upload, or the evaluation failed (its reason).
    """
    from wfbench.leaderboard.board.hidden import PHASES  # the board's, checked here before packing

    if phase not in PHASES:
        raise UploadError(f"--phase {phase!r} is not allowed; allowed: {', '.join(PHASES)}")
    package = load_package(policy, root)
    with Client(server, token, transport=transport) as client:
        posted = client.submit(package, track, phase, name=name, entry=entry)
        if not wait:
            return client.submission(posted["id"])
        sub = client.follow(posted["id"], progress=progress, poll_s=poll_s)
    if sub["state"] == "failed":
        raise UploadError(f"submission {sub['id']} failed: {sub['reason']} (see {sub['url']})")
    return sub
