"""The hosted board's app under uvicorn in a thread on 127.0.0.1 and a free port, for tests and the benchmark.

A test helper, not part of the server: the server module builds the app
(:func:`wfbench.leaderboard.server.app.create_app`), and ``wfbench serve`` runs it.
"""

from __future__ import annotations

from fastapi import FastAPI


class LiveServer:
    """``app`` under uvicorn in a thread on 127.0.0.1 and a free port.

    ``with LiveServer(app) as url:`` serves until the block ends, then stops the server and
    waits for its thread.
    """

    def __init__(self, app: FastAPI, host: str = "127.0.0.1", port: int = 0, start_timeout_s: float = 30.0) -> None:
        import uvicorn

        self.config = uvicorn.Config(app, host=host, port=port, log_level="warning", access_log=False)
        self.server = uvicorn.Server(self.config)
        self.start_timeout_s = start_timeout_s
        self.thread = None
        self.url = ""

    def __enter__(self) -> str:
        import threading
        import time

        self.thread = threading.Thread(target=self.server.run, name="wfbench-live-server", daemon=True)
        self.thread.start()
        deadline = time.monotonic() + self.start_timeout_s
        while not self.server.started:
            if not self.thread.is_alive() or time.monotonic() > deadline:
                raise RuntimeError(f"the server did not start within {self.start_timeout_s:g} s")
            time.sleep(0.01)
        sock = self.server.servers[0].sockets[0]
        host, port = sock.getsockname()[:2]
        self.url = f"http://{host}:{port}"
        return self.url

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        if self.thread is not None:
            self.thread.join(timeout=30)
