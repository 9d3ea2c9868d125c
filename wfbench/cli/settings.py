"""``wfbench train``'s settings: its flags plus ``--set KEY=VALUE`` pairs, typed by the config's own defaults."""

from __future__ import annotations

import dataclasses
import json

from wfbench.cli.common import did_you_mean


def coerce(field: dataclasses.Field, pair: str, text: str):
    """``text`` as a value of ``field``: the type of its default (bool, int, float, str), else JSON."""
    default = field.default if field.default is not dataclasses.MISSING else None
    try:
        if isinstance(default, bool):
            if text.lower() not in ("true", "false", "1", "0"):
                raise ValueError
            return text.lower() in ("true", "1")
        if isinstance(default, int | float):
            return type(default)(text)
        if isinstance(default, str):
            return text
        return json.loads(text)
    except ValueError:
        kind = type(default).__name__ if default is not None else "JSON"
        raise ValueError(f"--set {pair!r}: {field.name} takes a {kind} value (its default: {default!r})") from None


def train_settings(config_cls: type, given: dict, algo: str, pairs: list[str]) -> dict:
    """The flags given plus ``--set KEY=VALUE`` pairs, checked against the algorithm's config fields.

    Raises:
        ValueError: a flag the algorithm has no setting for, an unknown KEY or a VALUE of the wrong type.
    """
    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    for name in given:
        if name not in fields:
            raise ValueError(f"--{name.replace('_', '-')} does not apply to --algo {algo}; its settings: "
                             f"{', '.join(fields)} (set any of them with --set KEY=VALUE)")
    out = dict(given)
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or key not in fields:
            hint = did_you_mean(key, fields) if sep else ""
            raise ValueError(f"--set {pair!r}: expected KEY=VALUE with KEY one of the --algo {algo} settings: "
                             f"{', '.join(fields)}{'; ' + hint[2:-1] if hint else ''}")
        out[key] = coerce(fields[key], pair, text)
    return out
