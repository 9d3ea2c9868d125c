"""The ``wfbench`` command line: one module per command, each adding its subparser and holding its handler.

A command module has ``add_parser(subparsers)`` and ``run(args) -> int``, and imports what its
handler needs inside ``run`` so that ``wfbench --help`` stays fast. A command is a shell over the
Python function of the same name (:func:`wfbench.evaluate`, :func:`wfbench.compare`,
:func:`wfbench.simulate`, :func:`wfbench.train.fit`): it parses the flags, calls it, prints what
it returns and turns its refusals into one line. User mistakes exit 2 with one line (closest
names, the missing extra), a failing policy exits 1, a closed stdout 141; ``module:attr`` is
looked up in the current folder first. The shared argument types and :class:`UsageError`:
:mod:`wfbench.cli.common`. ``docs/getting-started.md``.
"""

from __future__ import annotations

import os
import sys

import wfbench.cli.bench as bench
import wfbench.cli.compare as compare
import wfbench.cli.evaluate as evaluate
import wfbench.cli.leaderboard as leaderboard
import wfbench.cli.policies as policies
import wfbench.cli.reproduce as reproduce
import wfbench.cli.scenarios as scenarios
import wfbench.cli.serve as serve
import wfbench.cli.simulate as simulate
import wfbench.cli.suite as suite
import wfbench.cli.train as train
import wfbench.cli.tune as tune
import wfbench.cli.worker as worker
from wfbench.cli.common import EXIT_POLICY_FAILED, EXIT_USAGE, Parser, UsageError, missing_extra, with_suggestion

# the commands in the order --help lists them
COMMANDS = {"evaluate": evaluate, "compare": compare, "leaderboard": leaderboard, "reproduce": reproduce,
            "tune": tune, "scenarios": scenarios, "suite": suite, "policies": policies, "simulate": simulate,
            "bench": bench, "train": train, "serve": serve, "worker": worker}

__all__ = ["COMMANDS", "EXIT_POLICY_FAILED", "EXIT_USAGE", "UsageError", "build_parser", "main"]


def build_parser() -> Parser:
    p = Parser(prog="wfbench", description="A benchmark suite for service workforce optimization.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in COMMANDS.values():
        module.add_parser(sub)
    return p


def _search_current_folder() -> None:
    """Put the current folder first on ``sys.path``, as ``python -m`` does.

    The ``wfbench`` script's own folder is what Python puts there, so without this a
    ``--policy mypkg.mod:MyPolicy`` next to the user would not be found. The absolute
    path: worker processes inherit ``sys.path`` and may start elsewhere.
    """
    cwd = os.getcwd()
    if cwd not in sys.path:
        sys.path.insert(0, cwd)


def _command(args) -> str:
    """``wfbench COMMAND [SUBCOMMAND]`` of parsed ``args``, for messages."""
    words = ["wfbench", getattr(args, "command", None)]
    words += [getattr(args, a, None) for a in ("lb_command", "serve_command")]
    return " ".join(w for w in words if w)


def _format_warning(message, category, filename, lineno, line=None, _default=None) -> str:
    """A warning of wfbench's own classes as one line, ``wfbench: warning: ...`` (no file or source line)."""
    if category.__module__.startswith("wfbench."):
        return f"wfbench: warning: {message}\n"
    return _default(message, category, filename, lineno, line)


def _one_line_warnings() -> None:
    """Install :func:`_format_warning` as ``warnings.formatwarning``, once (recorded warnings are not formatted)."""
    import functools
    import warnings

    if isinstance(warnings.formatwarning, functools.partial) and warnings.formatwarning.func is _format_warning:
        return
    warnings.formatwarning = functools.partial(_format_warning, _default=warnings.formatwarning)


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``) and return its exit status."""
    from wfbench.harness.guard import PolicyError

    args = None
    try:
        _one_line_warnings()
        _search_current_folder()
        args = build_parser().parse_args(argv)
        args.argv = list(sys.argv[1:] if argv is None else argv)  # recorded by commands that write provenance
        status = COMMANDS[args.command].run(args)
        sys.stdout.flush()  # here, where a closed pipe is handled, not at interpreter exit
        return status
    except UsageError as exc:
        print(f"wfbench: error: {with_suggestion(str(exc))}", file=sys.stderr)
        return EXIT_USAGE
    except ModuleNotFoundError as exc:  # an optional extra that is not installed: one line naming it
        message = missing_extra(exc, _command(args))
        if message is None:
            raise
        print(f"wfbench: error: {message}", file=sys.stderr)
        return EXIT_USAGE
    except PolicyError as exc:
        if getattr(args, "traceback", False):
            print(exc.trace or "(no trace)", end="" if exc.trace.endswith("\n") else "\n", file=sys.stderr)
            hint = ""
        else:
            hint = " (--traceback prints the whole trace)"
        print(f"wfbench: error: {exc}{hint}", file=sys.stderr)
        return EXIT_POLICY_FAILED
    except KeyboardInterrupt:
        print("wfbench: interrupted", file=sys.stderr)
        return 130
    except RuntimeError as exc:
        from wfbench.harness.backends import (
            ClusterError,  # here, so that a command that never fails does not load joblib
        )

        if not isinstance(exc, ClusterError):
            raise
        print(f"wfbench: error: {exc}", file=sys.stderr)  # a Ray address that cannot be joined: one line
        return EXIT_USAGE
    except BrokenPipeError:
        # the reader of stdout went away (``wfbench policies | head``): stop quietly, as the signal
        # module's "Note on SIGPIPE" recommends; stdout goes to devnull so that flushing it at exit
        # does not raise a second BrokenPipeError
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, what a shell reports for a command stopped by a closed pipe

