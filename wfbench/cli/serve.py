"""``wfbench serve``: the hosted board's web server; ``account add NAME``: an account; ``baselines``: the built-ins.

The server stores uploads and queues them; ``wfbench worker`` evaluates them. Both read
the same database: a SQLite file (the default, nothing else to start) or a PostgreSQL
URL for workers on other hosts (docs/leaderboard.md, "The hosted leaderboard").
"""

from __future__ import annotations

import argparse
import importlib.util
import os

from wfbench.cli.common import Parser, UsageError, int_at_least, require_extra

DB_ENV = "WFBENCH_SERVER_DB"
DB_HELP = (f"the board's database: a SQLite file path or sqlite:/// URL, or a postgresql+psycopg:// URL (default: "
           f"${DB_ENV}, else server.sqlite in the user data folder)")


def port(text: str) -> int:
    """An argparse type: a TCP port, 1..65535."""
    v = int_at_least(1)(text)
    if v > 65535:
        raise argparse.ArgumentTypeError(f"{v} is not allowed; allowed: a port 1..65535")
    return v


def add_parser(sub) -> None:
    p = sub.add_parser("serve", help="run the hosted leaderboard's web server (uploads, boards, submissions)")
    p.add_argument("--db", default=None, help=DB_HELP)
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=port, default=8000, help="port (default 8000)")
    p.add_argument("--tracks", default=None, help="comma-separated track names the board offers (default: all; "
                                                  "see 'wfbench leaderboard tracks')")
    ssub = p.add_subparsers(dest="serve_command", required=False, parser_class=Parser)
    acc = ssub.add_parser("account", help="manage the accounts that may upload")
    asub = acc.add_subparsers(dest="account_command", required=True, parser_class=Parser)
    add = asub.add_parser("add", help="make an account and print its token (shown once, stored hashed)")
    add.add_argument("name", help="the account's name")
    add.add_argument("--admin", action="store_true", help="an admin account")
    add.add_argument("--db", default=argparse.SUPPRESS, help=DB_HELP)  # after the subcommand too
    seed = ssub.add_parser("baselines",
                           help="enter the built-in policies (the baselines the reports compare with) as "
                                "submissions of the admin account 'wfbench'; entering them again adds nothing")
    seed.add_argument("--tracks", default=argparse.SUPPRESS,
                      help="comma-separated tracks to enter them on (default: all the board's)")
    seed.add_argument("--phase", choices=("dev", "test", "both"), default="both",
                      help="the phase(s) to enter them in (default both)")
    seed.add_argument("--db", default=argparse.SUPPRESS, help=DB_HELP)
    end = ssub.add_parser("end-test", help="end a track's test phase: no test submission is taken any more, and "
                                           "everyone sees its failures' whole reasons (until then: one word each)")
    end.add_argument("track", help="the track whose test phase ends")
    end.add_argument("--db", default=argparse.SUPPRESS, help=DB_HELP)


def default_db() -> str:
    """``$WFBENCH_SERVER_DB``, else ``server.sqlite`` in wfbench's user data folder (made if missing)."""
    env = os.environ.get(DB_ENV)
    if env:
        return env
    import platformdirs

    folder = platformdirs.user_data_dir("wfbench", appauthor=False)
    os.makedirs(folder, exist_ok=True)
    return os.path.join(folder, "server.sqlite")


def track_names(text: str | None) -> dict | None:
    """The tracks ``--tracks`` names, by name, each checked (a usage error names the allowed ones); None for all."""
    if text is None:
        return None
    from wfbench.leaderboard.tracks import TRACKS

    names = [n.strip() for n in text.split(",") if n.strip()]
    for n in names:
        if n not in TRACKS:
            raise UsageError(f"--tracks: unknown track {n!r}; allowed: {', '.join(TRACKS)}")
    if not names:
        raise UsageError(f"--tracks {text!r} names no track; allowed: a comma-separated list of {', '.join(TRACKS)}")
    return {n: TRACKS[n] for n in names}


def open_board(db: str | None, tracks: dict | None):
    """The board at ``db`` (made if new); its refusal of the URL is a usage error."""
    from wfbench.leaderboard.board.db import Board, BoardError

    try:
        board = Board(db or default_db(), tracks=tracks)
        board.create()
    except (BoardError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    return board


def worker_command(board) -> str:
    """The command that starts a worker on ``board``'s database (a PostgreSQL password shown as ***)."""
    url = board.engine.url
    where = url.database if url.get_backend_name() == "sqlite" else url.render_as_string(hide_password=True)
    return f"wfbench worker --server {where}"


def seed(board, phase: str) -> int:
    """``wfbench serve baselines``: one line per built-in, track and phase; what to start next."""
    from wfbench.leaderboard.board.db import BoardError
    from wfbench.leaderboard.board.seed import ACCOUNT, PHASES
    from wfbench.leaderboard.board.seed import seed as seed_builtins

    try:
        done = seed_builtins(board, phases=PHASES[phase])
    except BoardError as exc:
        raise UsageError(str(exc)) from None
    for s in done:
        print(s.line())
    new = sum(s.created for s in done)
    print(f"{new} new submission{'s' if new != 1 else ''} of account {ACCOUNT!r}; start '{worker_command(board)}' "
          "to evaluate them")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.serve_command is None:  # the web server: all of the server extra, before the database is made
        require_extra("wfbench serve", "sqlalchemy", "fastapi", "uvicorn")
        if importlib.util.find_spec("python_multipart") is None and importlib.util.find_spec("multipart") is None:
            require_extra("wfbench serve", "python_multipart")  # the uploads' parser (older releases: multipart)
    board = open_board(args.db, track_names(args.tracks))
    if args.serve_command == "account":
        from wfbench.leaderboard.board.db import BoardError

        try:
            token = board.add_account(args.name, admin=args.admin)
        except (BoardError, ValueError) as exc:
            raise UsageError(str(exc)) from None
        print(f"account {args.name!r}{' (admin)' if args.admin else ''} made; its token, shown only now:")
        print(token)
        return 0
    if args.serve_command == "baselines":
        return seed(board, args.phase)
    if args.serve_command == "end-test":
        import time

        from wfbench.leaderboard.board.db import BoardError

        try:
            ended = board.end_test_phase(args.track)
        except BoardError as exc:
            raise UsageError(str(exc)) from None
        print(f"the test phase of track {args.track} ended at "
              f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(ended))}: no test submission is taken any more, and "
              "its failures' whole reasons are shown")
        return 0
    import uvicorn

    from wfbench.leaderboard.server.app import create_app

    where = board.engine.url.render_as_string(hide_password=True)
    print(f"wfbench leaderboard on http://{args.host}:{args.port} (database {where}); start '{worker_command(board)}' "
          "to evaluate the submissions", flush=True)
    uvicorn.run(create_app(board), host=args.host, port=args.port, log_level="info")
    return 0
