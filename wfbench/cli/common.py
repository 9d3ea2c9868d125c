"""What the commands share: the one-line usage error, argument types, and the checks of names and paths.

A command module adds its subparser with these types and raises :class:`UsageError` for
a user's mistake; :func:`wfbench.cli.main` prints it as one line and exits with
:data:`EXIT_USAGE`.
"""

from __future__ import annotations

import argparse
import difflib
import importlib.util
import math
import re
from pathlib import Path

from wfbench.core.seeds import resolve_seeds

EXIT_POLICY_FAILED = 1
EXIT_USAGE = 2
# what every --scenario takes (wfbench.scenarios.resolve; docs/scenarios.md, "Naming a scenario")
SCENARIO_HELP = "a preset name, a suite's scenario id such as paper-64-v1, or a .toml/.json config file"


class UsageError(Exception):
    """A mistake in the command line: printed as one line, exit status 2."""


# The optional extras (pyproject.toml, [project.optional-dependencies]) by the top-level modules that commands import
# when they run: one that is not installed is a one-line usage error naming its extra (missing_extra).
EXTRAS = {"torch": "rl", "stable_baselines3": "rl", "sb3_contrib": "rl", "tensorboard": "rl", "ray": "ray",
          "fastapi": "server", "starlette": "server", "uvicorn": "server", "sqlalchemy": "server",
          "psycopg": "server", "python_multipart": "server", "multipart": "server", "httpx": "server"}


def extra_message(command: str, module: str) -> str:
    """The one line for ``command`` needing ``module`` of an optional extra that is not installed."""
    extra = EXTRAS[module]
    return (f"{command} needs {module}, which is not installed; install the {extra} extra: "
            f"pip install 'wfbench[{extra}]'")


def missing_extra(exc: BaseException, command: str) -> str | None:
    """:func:`extra_message` when ``exc`` is the import of a module of an optional extra failing; None otherwise."""
    if not isinstance(exc, ModuleNotFoundError) or not exc.name:
        return None
    module = exc.name.partition(".")[0]
    return extra_message(command, module) if module in EXTRAS else None


def require_extra(command: str, *modules: str) -> None:
    """A usage error naming the extra when one of ``modules`` is not installed: checked before any work starts."""
    for module in modules:
        if importlib.util.find_spec(module) is None:
            raise UsageError(extra_message(command, module))


def _names_of(kind: str) -> list[str] | None:
    """Every allowed name of a kind whose message does not list them all (policies, scenarios); None for others."""
    if kind == "policy":
        from wfbench.policies import names

        return list(names())
    if kind == "seeds":  # a mistyped set name among the forms of a seed spec
        from wfbench.core.seeds import SEED_SETS

        return list(SEED_SETS)
    if kind == "scenario":
        from wfbench.core.config import PRESETS
        from wfbench.scenarios import SUITES

        return [*PRESETS, *(i for s in SUITES.values() for i in s.ids())]
    return None


def _listed(text: str) -> list[str]:
    """The names a message lists after ``allowed:`` or ``available:`` (up to ``;`` or `` (``)."""
    m = re.search(r"(?:allowed|available): (.*)", text)
    if not m:
        return []
    items = re.split(r";| \(", m.group(1))[0]
    return [x.strip().strip("'") for x in items.split(",") if x.strip()]


def did_you_mean(name: str, allowed) -> str:
    """`` (did you mean 'a' or 'b'?)`` with difflib's closest of ``allowed`` to ``name``; empty when none is close."""
    close = [c for c in difflib.get_close_matches(name, list(allowed), n=3) if c != name]
    if not close:
        return ""
    quoted = [repr(n) for n in close]
    return f" (did you mean {quoted[0] if len(quoted) == 1 else ', '.join(quoted[:-1]) + ' or ' + quoted[-1]}?)"


def with_suggestion(message: str) -> str:
    """``message`` ending in ``; did you mean ...?``: difflib's closest allowed names to the unknown one it refuses.

    The one place where every refused name (policy, scenario, suite, split, track, target,
    algorithm, backend, seed set, an argparse choice or command) gets its suggestion, after
    the message (whose text, list included, stays as it was); the message is left as it is
    when it names no unknown name or nothing allowed is close.
    """
    if "; did you mean " in message:  # the registry's own (wfbench.policies.registry.unknown_message)
        return message
    choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
    if choice:
        hint = did_you_mean(choice.group(1), re.findall(r"'([^']*)'", choice.group(2)))
        return f"{message}; {hint[2:-1]}" if hint else message
    m = (re.search(r"unknown ([a-zA-Z][a-zA-Z ]*?) '([^']*)'", message)
         or re.search(r"([a-zA-Z]+) '([^']*)' (?:is not (?:known|allowed)|not understood)", message))
    if not m:
        return message
    kind, name = m.groups()
    hint = did_you_mean(name, _names_of(kind) or _listed(message[m.end():]))
    return f"{message}; {hint[2:-1]}" if hint else message


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, no usage dump
        raise UsageError(message)


def int_at_least(lo: int):
    """An argparse type: an integer >= ``lo``, with a one-line message otherwise."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{v} is not allowed; allowed: an integer >= {lo}")
        return v

    return parse


positive = int_at_least(1)


def seconds(text: str) -> float:
    """An argparse type: a number of seconds > 0, with a one-line message otherwise."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{text} is not allowed; allowed: a number of seconds > 0")
    return v

nonneg = int_at_least(0)


def seeds_spec(text: str) -> str:
    """An argparse type: anything :func:`wfbench.core.seeds.resolve_seeds` takes, checked now."""
    try:
        resolve_seeds(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def seed_list(args: argparse.Namespace) -> list[int]:
    """The seeds of ``--seeds`` (a count starts at ``--seed-start``)."""
    if args.seeds.strip().isdigit():
        return list(range(args.seed_start, args.seed_start + int(args.seeds)))
    if args.seed_start:
        raise UsageError("--seed-start applies to a count of seeds only, not to a set, range or list")
    return resolve_seeds(args.seeds)


def add_backend_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--backend", default="process",
                   help="process (default: a pool over all cores), serial (this process) or ray")
    p.add_argument("--workers", type=positive, default=None, help="processes or Ray tasks (default: all cores)")
    p.add_argument("--address", default=None, help="Ray cluster address for --backend ray (default: start a local one)")


def act_timeout(text: str) -> float | None:
    """An argparse type: seconds > 0, or 0 for no limit."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; allowed: seconds > 0, or 0 for no limit")
    return v or None


def add_policy_run_args(p: argparse.ArgumentParser) -> None:
    """The options of commands that run a user's policy: its act timeout and --traceback."""
    from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S

    p.add_argument("--act-timeout", type=act_timeout, default=DEFAULT_ACT_TIMEOUT_S, metavar="SECONDS",
                   help=f"limit of each reset/act call of a module:attr policy (default {DEFAULT_ACT_TIMEOUT_S:g}; "
                        "0: none)")
    p.add_argument("--traceback", action="store_true", help="when the policy fails, print the whole trace")


def check_backend_args(args: argparse.Namespace, progress: bool = False):
    """The run's :class:`~wfbench.harness.backends.Execution` of ``--backend``, ``--workers`` and ``--address``.

    A bad one is a usage error, found before anything runs.
    """
    from wfbench.harness.backends import Execution

    try:
        return Execution(backend=args.backend, workers=getattr(args, "workers", None), address=args.address,
                         progress=progress)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def resolve_scenario(name: str):
    """The scenario of a name (:func:`wfbench.scenarios.resolve.resolve_scenario`); a bad name is a usage error."""
    from wfbench.scenarios.resolve import resolve_scenario as resolve

    try:
        return resolve(name)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def resolve_policy(spec: str):
    """A fresh policy for ``spec`` (:func:`policies.get`); a bad spec is a usage error."""
    from wfbench.policies import get

    try:
        return get(spec)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def check_writable(path: str, what: str) -> Path:
    """``path`` as a Path if its folder exists; otherwise a usage error naming the option ``what``."""
    out = Path(path)
    if not out.parent.exists() or not out.parent.is_dir():
        raise UsageError(f"{what} {path!r}: folder {str(out.parent)!r} does not exist")
    return out


def add_run_args(p: argparse.ArgumentParser) -> None:
    """The options of commands that run policies over seeds: scenario, seeds, backend, act timeout."""
    from wfbench.core.seeds import SPEC_HELP

    p.add_argument("--scenario", default="paper-64", help=SCENARIO_HELP)
    p.add_argument("--seeds", type=seeds_spec, default="50", help=f"{SPEC_HELP} (default 50: the test set)")
    p.add_argument("--seed-start", type=nonneg, default=0, help="first seed of a count (default 0)")
    add_backend_args(p)
    add_policy_run_args(p)


def check_suite_args(args: argparse.Namespace):
    """The suite of ``--suite`` with ``--split`` checked; one-line usage errors for what does not go together."""
    from wfbench.scenarios import SPLITS, get_suite

    if args.suite is None:
        raise UsageError(f"--split {args.split} applies to --suite only")
    if args.scenario is not None:
        raise UsageError("--scenario and --suite do not go together: a suite names its scenarios (give one of them)")
    try:
        suite = get_suite(args.suite)
    except ValueError as exc:
        raise UsageError(f"--suite: {exc}") from None
    if args.split is not None and args.split not in SPLITS:
        raise UsageError(f"--split: unknown split {args.split!r}; allowed: {', '.join(SPLITS)}")
    return suite
