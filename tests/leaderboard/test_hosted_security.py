"""The hosted board end to end: uvicorn on 127.0.0.1, workers in their own processes, every policy in bubblewrap.

What issue #34 asks of the whole (each piece has its own tests: tests/harness/test_sandbox.py
for the sandbox alone, test_queue.py and test_worker.py for the queue, test_server.py for the
API):

- hostile packages, uploaded over HTTP beside a clean one, each end ``failed`` with the right
  reason while the clean job's rows equal a direct evaluation bit for bit, the server answers
  throughout, and no process of theirs is left;
- a zip-slip and a zip bomb are refused at the door with their reason, and fail with the same
  reason if one reaches the queue anyway;
- a spy on the test phase searches what it can reach for the hidden seeds and reports through
  its actions: its rows equal those of the same rule that finds nothing;
- a policy that rebuilds the hindsight oracle from the only numbers it is handed (its opaque
  keys) scores no better than the rule it falls back on, while the same oracle on the true
  hidden seeds would have.
"""

from __future__ import annotations

import hashlib
import importlib.util
import io
import json
import os
import socket
import subprocess
import sys
import textwrap
import threading
import time
import zipfile
from pathlib import Path

import httpx
import numpy as np
import pytest
from wfbench.leaderboard.board.db import Board
from wfbench.leaderboard.server.app import create_app
from wfbench.leaderboard.store import KPI_COLUMNS

from tests.harness.test_sandbox import RULE as SANDBOX_RULE
from tests.leaderboard.live_server import LiveServer
from tests.leaderboard.test_server import TRACK
from wfbench.harness.evaluation import evaluate
from wfbench.harness.isolation.package import pack

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
SECRET_ENV = "WFBENCH_TEST_WORKER_SECRET"
SECRET_VALUE = "hunter2-is-not-a-seed"

# a worker process as an operator starts it (wfbench worker), on the tests' small track, with tight limits
WORKER = """
import sys
from tests.harness.test_sandbox import RULE as SANDBOX_RULE
from tests.leaderboard.test_server import TRACK
from wfbench.harness.isolation.sandbox import Limits
from wfbench.leaderboard.board.worker import run_worker
sys.exit(run_worker(sys.argv[1], worker_id=sys.argv[2], once=True, poll_s=0.1, chunk_size=3,
                    tracks={TRACK.name: TRACK},
                    limits=Limits(act_timeout_s=float(sys.argv[3]), memory_mb=1024, wall_time_s=120, tmp_mb=32,
                                  start_timeout_s=60, warmup_s=float(sys.argv[3]))))
"""

RULE = SANDBOX_RULE.replace("class Rule", "class Policy")  # a deterministic rule: its rows do not depend on keys

HOSTILE = '''
import os, socket, sys, time
import numpy as np


class Policy:
    decisions = ("dispatch",)

    def reset(self, keys):
        pass

    def act(self, obs):
{body}
        raise RuntimeError("the hostile act should not get here")
'''


def _source(body: str) -> str:
    return HOSTILE.format(body=textwrap.indent(textwrap.dedent(body).strip(), " " * 8))


def _pack(tmp_path: Path, module: str, source: str) -> bytes:
    src = tmp_path / "src" / module
    src.mkdir(parents=True)
    (src / f"{module}.py").write_text(source)
    return pack(f"{module}:Policy", src)


def _load(source: str, name: str):
    """The policy class of ``source``, imported here, outside any sandbox (the reference run)."""
    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"{name}_{os.getpid()}.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.Policy


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buf.getvalue()


MANIFEST = json.dumps({"entry": "pol:Policy", "format": 1}).encode()


def hostile_cases(tmp_path: Path, db: Path, seed_file: Path, listener_port: int) -> dict[str, tuple[str, str]]:
    """name -> (the act's body, what the failure's one-line reason must contain)."""
    return {
        "fork-bomb": ("while True:\n    os.fork()", "BlockingIOError: [Errno 11] Resource temporarily unavailable"),
        "allocate-100gb": ("np.ones(100 * 2**30 // 8)", "(memory limit 1024 MB)"),
        "fill-the-disk": ("for i in range(100):\n    open(f'/tmp/f{i}', 'wb').write(bytes(8 << 20))",
                          "No space left on device"),
        "stdout-flood": ("while True:\n    print('x' * 4096)",
                         "wrote more than 1 MiB to stdout/stderr (the log limit)"),
        "endless-python": ("while True:\n    pass", "act took longer than 3 s (the act time limit)"),
        "endless-compiled": ("from numba import njit\n\n@njit\ndef spin(x):\n    while x >= 0.0:\n        x += 1.0\n"
                             "    return x\n\nspin(1.0)", "act took longer than 3 s (the act time limit)"),
        "tcp-connect": (f"socket.create_connection(('127.0.0.1', {listener_port}), timeout=2)",
                        "ConnectionRefusedError"),
        "dns-lookup": ("socket.getaddrinfo('example.com', 443)", "gaierror"),
        "read-database": (f"open({str(db)!r}, 'rb').read()", f"FileNotFoundError: [Errno 2] No such file or "
                                                              f"directory: '{db}'"),
        "read-seed-list": (f"open({str(seed_file)!r}).read()", f"FileNotFoundError: [Errno 2] No such file or "
                                                               f"directory: '{seed_file}'"),
        "read-environments": ("""
            seen = []
            for pid in [p for p in os.listdir('/proc') if p.isdigit()]:
                try:
                    seen.append(open(f'/proc/{pid}/environ', 'rb').read().decode(errors='replace'))
                except OSError as exc:
                    seen.append(type(exc).__name__)
            raise RuntimeError('environments: ' + ' | '.join(seen).replace(chr(0), ' '))
            """, "RuntimeError: environments: "),
        "read-server-memory": (f"open('/proc/{os.getpid()}/mem', 'rb').read(1)",
                               f"FileNotFoundError: [Errno 2] No such file or directory: '/proc/{os.getpid()}/mem'"),
    }


def _start_worker(db: Path, name: str, act_timeout_s: float, tmp: Path) -> subprocess.Popen:
    tmp.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, SECRET_ENV: SECRET_VALUE, "TMPDIR": str(tmp)}
    return subprocess.Popen([sys.executable, "-c", WORKER, str(db), name, str(act_timeout_s)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


class Poller(threading.Thread):
    """Asks the server for its tracks every 0.2 s while the workers run; every answer must come, and be 200."""

    def __init__(self, url: str):
        super().__init__(daemon=True)
        self.url, self.stop, self.failures, self.latencies = url, threading.Event(), [], []

    def run(self) -> None:
        with httpx.Client(timeout=15) as client:
            while not self.stop.is_set():
                t0 = time.perf_counter()
                try:
                    r = client.get(f"{self.url}/api/tracks")
                    if r.status_code != 200:
                        self.failures.append(f"HTTP {r.status_code}")
                except httpx.HTTPError as exc:
                    self.failures.append(repr(exc))
                self.latencies.append(time.perf_counter() - t0)
                self.stop.wait(0.2)


def _left_running(marker: str) -> list[str]:
    """Live processes whose command line names ``marker`` (a worker's temporary folder: its sandboxes')."""
    left = []
    for pid in [p for p in os.listdir("/proc") if p.isdigit()]:
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if marker in cmd and state != "Z":
            left.append(f"{pid}: {cmd[:200]}")
    return left


def _finish(workers: list[subprocess.Popen], timeout_s: float) -> list[str]:
    errs = []
    for w in workers:
        try:
            _, err = w.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            w.kill()
            _, err = w.communicate()
            raise AssertionError(f"a worker did not finish in {timeout_s:g} s: {err[-3000:]}") from None
        assert w.returncode == 0, err[-3000:]
        errs.append(err)
    return errs


def _kpis(frame) -> np.ndarray:
    return frame[list(KPI_COLUMNS)].to_numpy()


def _post(url: str, token: str, data: bytes, name: str, phase: str = "dev") -> httpx.Response:
    return httpx.post(f"{url}/api/submissions", headers={"Authorization": f"Bearer {token}"}, timeout=60,
                      data={"track": TRACK.name, "phase": phase, "name": name},
                      files={"package": (f"{name}.zip", data, "application/zip")})


@pytest.fixture
def hosted(tmp_path, bwrap):
    db = tmp_path / "server" / "board.sqlite"
    db.parent.mkdir()
    board = Board(db, tracks={TRACK.name: TRACK}, dev_concurrent=100, dev_daily_quota=100)
    board.create()
    board.ensure_hidden_seeds(TRACK.name, n=3)
    with LiveServer(create_app(board)) as url:
        yield board, url, db
    board.close()


def test_hostile_packages_fail_with_their_reason_beside_a_clean_job(hosted, tmp_path):
    board, url, db = hosted
    token = board.add_account("mallory")
    seed_file = db.parent / "hidden-seeds.json"  # an operator's copy of the hidden seeds, beside the database
    seed_file.write_text(json.dumps(list(board.ensure_hidden_seeds(TRACK.name).seeds)))
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        listener.setblocking(False)
        cases = hostile_cases(tmp_path, db, seed_file, listener.getsockname()[1])

        # at the door: what a package's archive says is checked before anything is stored
        slip = _zip({"wfbench-policy.json": MANIFEST, "pol.py": b"", "../../escaped.py": b"print('out')"})
        bomb = _zip({"wfbench-policy.json": MANIFEST, "pol.py": b"", "zeros.bin": bytes(300 << 20)})
        for data, expected in ((slip, "zip-slip"), (bomb, "zip bomb")):
            r = _post(url, token, data, "refused")
            assert r.status_code == 400 and expected in r.json()["detail"], r.text
            assert "\n" not in r.json()["detail"]
        # and if one reaches the queue anyway (an older server let it in), the worker's unpack refuses it the same
        account = board.account(token)
        smuggled = {}
        for name, data in (("zip-slip", slip), ("zip-bomb", bomb)):
            smuggled[name] = board.submit(account, TRACK.name, "dev", board.put_package(data), "pol:Policy", name)[0].id

        ids = {}
        names = list(cases)
        for i, name in enumerate(names):
            if i == len(names) // 2:  # the clean job in the middle of the queue, beside the hostile ones
                r = _post(url, token, _pack(tmp_path, "cleanrule", RULE), "clean")
                assert r.status_code == 201, r.text
                ids["clean"] = r.json()["id"]
            r = _post(url, token, _pack(tmp_path, name.replace("-", "_"), _source(cases[name][0])), name)
            assert r.status_code == 201, r.text
            ids[name] = r.json()["id"]

        marker = str(tmp_path / "worker-tmp")
        poller = Poller(url)
        poller.start()
        workers = [_start_worker(db, f"w{k}", 3.0, Path(marker) / f"w{k}") for k in range(2)]
        try:
            _finish(workers, timeout_s=600)
        finally:
            poller.stop.set()
            poller.join()
        with pytest.raises(BlockingIOError):
            listener.accept()  # nobody connected

    assert poller.failures == [], poller.failures  # the server answered throughout
    assert len(poller.latencies) >= 5 and max(poller.latencies) < 10, max(poller.latencies)
    assert _left_running(marker) == [], "a sandbox outlived its job"

    for name, (_, expected) in cases.items():
        sub = board.submission(ids[name])
        assert sub.state == "failed", (name, sub.state, sub.reason)
        assert expected in sub.reason and "\n" not in sub.reason, (name, sub.reason)
        assert SECRET_VALUE not in sub.reason + sub.log, f"{name}: the worker's environment leaked"
        assert str(seed_file.read_text()) not in sub.reason + sub.log
    for name, expected in (("zip-slip", "zip-slip"), ("zip-bomb", "zip bomb")):
        sub = board.submission(smuggled[name])
        assert sub.state == "failed" and expected in sub.reason, (name, sub.reason)

    clean = board.submission(ids["clean"])
    assert clean.state == "done", clean.reason
    rows = board.rows(clean.id).sort_values("seed_index")
    direct = evaluate(_load(RULE, "clean_reference")(), TRACK.config, list(TRACK.public_seeds))
    assert np.array_equal(_kpis(rows), _kpis(direct)), "the clean job's rows differ from a clean run"


SPY = RULE.replace('''    def reset(self, keys):
        self.keys = [int(k) for k in keys]
''', '''    def reset(self, keys):
        """Search everything reachable for the hidden seeds; hire every step if any is found (the report)."""
        import hashlib, os, re

        wanted = WANTED
        found, reachable = set(), []

        def look(data):
            for token in re.findall(rb"\\d{6,20}", data):
                if hashlib.sha256(token).hexdigest() in wanted:
                    found.add(token)

        look(" ".join(str(int(k)) for k in keys).encode())
        look(" ".join(f"{k}={v}" for k, v in os.environ.items()).encode())
        system = ("/usr", "/lib", "/lib64", "/bin", "/sbin", "/etc", "/proc", "/sys", "/dev")
        for top in ([] if found else os.listdir("/")):  # handed a seed (the check outside): no need to search
            for folder, dirs, files in os.walk("/" + top):
                look(folder.encode())
                for f in files:
                    path = os.path.join(folder, f)
                    look(path.encode())
                    reachable.append(path)
                    if not path.startswith(system) and "site-packages" not in path and "/lib/python" not in path:
                        try:
                            with open(path, "rb") as fh:
                                look(fh.read(1 << 20))
                        except OSError:
                            pass
        for pid in [p for p in os.listdir("/proc") if p.isdigit()]:
            for what in ("environ", "cmdline", "maps"):
                try:
                    look(open(f"/proc/{pid}/{what}", "rb").read())
                except OSError:
                    pass
        self.hire = 1 if found else 0
        self.keys = [int(k) for k in keys]
''')


def test_a_spy_finds_no_hidden_seed_and_reports_so_through_its_actions(hosted, tmp_path):
    board, url, db = hosted
    seeds = list(board.ensure_hidden_seeds(TRACK.name).seeds)
    (db.parent / "hidden-seeds.json").write_text(json.dumps(seeds))  # planted where an operator might keep them
    wanted = {hashlib.sha256(str(s).encode()).hexdigest() for s in seeds}
    spy = SPY.replace("WANTED", repr(wanted))
    # the spy's search works: handed the hidden seeds, it reports them by hiring (its rows differ from the rule's)
    Spy, Rule = _load(spy, "spy_reference"), _load(RULE, "rule_reference")
    told = evaluate(Spy(), TRACK.config, seeds)
    honest = evaluate(Rule(), TRACK.config, seeds)
    assert not np.array_equal(_kpis(told), _kpis(honest)), "the spy's report must show in its rows"

    token = board.add_account("eve")
    r = _post(url, token, _pack(tmp_path, "spy", spy), "spy", phase="test")
    assert r.status_code == 201, r.text
    workers = [_start_worker(db, "spy-worker", 120.0, tmp_path / "worker-tmp")]
    _finish(workers, timeout_s=600)
    sub = board.submission(r.json()["id"])
    assert sub.state == "done", sub.reason
    rows = board.rows(sub.id).sort_values("seed_index")
    assert "seed" not in rows.columns  # a test phase's rows never carry their seed out of the database
    assert np.array_equal(_kpis(rows), _kpis(honest)), "the spy found a hidden seed"


def test_an_oracle_rebuilt_from_what_a_policy_is_handed_scores_no_better(hosted):
    """The 8-line wrapper that topped the local board: the hindsight oracle attached by the policy itself.

    In the sandbox it finds no seed (the spy above), so the only numbers it can plug in
    are its opaque keys: the board's own keys for the test phase (the worker's secret and
    context), given here as the sandbox gives them. It plans on a future that is not the
    one played, and scores below the plain heuristic on the hidden seeds, while the same
    wrapper handed the true seeds would beat every deployable built-in.
    """
    from wfbench.leaderboard.board import hidden
    from wfbench.policies import get
    from wfbench.policies.registry import LINEUPS

    from wfbench.harness.isolation.sandbox import opaque_keys

    board, _, _ = hosted
    seeds = list(board.ensure_hidden_seeds(TRACK.name).seeds)
    secret, context = board.key_secret(), hidden.key_context(TRACK.name, "test")

    class Cheater:
        def __init__(self, handed):
            self.oracle, self.handed = get("oracle"), handed
            self.oracle.attach(TRACK.config)
            self.decisions = self.oracle.decisions

        def reset(self, seeds):
            self.oracle.reset(self.handed(seeds))

        def act(self, obs):
            return self.oracle.act(obs)

    keyed = evaluate(Cheater(lambda s: opaque_keys(s, secret, context)), TRACK.config, seeds)
    leaked = evaluate(Cheater(lambda s: s), TRACK.config, seeds)
    deployable = {name: evaluate(name, TRACK.config, seeds)["nsw"].to_numpy()
                  for name in LINEUPS["suite"]}
    best = np.max(np.stack(list(deployable.values())), axis=0)
    assert keyed["nsw"].mean() < deployable["heuristic"].mean(), (keyed["nsw"].tolist(), deployable["heuristic"])
    assert leaked["nsw"].mean() > best.mean(), "with the true seeds the wrapper is the oracle: the test's premise"
