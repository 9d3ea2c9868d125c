"""`wfbench scenarios` (wfbench/cli/scenarios.py): one row per preset, with its facility layout."""

from wfbench.cli import main
from wfbench.core.config import PRESETS


def _rows(capsys) -> tuple[list[str], dict[str, str]]:
    assert main(["scenarios"]) == 0
    header, *lines = capsys.readouterr().out.splitlines()
    return header.split(), {line.split()[0]: line for line in lines}


def test_listing_has_every_preset_once_with_the_columns_named_in_its_header(capsys):
    header, rows = _rows(capsys)
    assert header == ["name", "grid", "facilities", "personnel", "horizon", "layout"]
    assert list(rows) == list(PRESETS)
    assert rows["city"].split()[1:5] == ["576x576", "500/1000", "500/1000", "800"]


def test_layout_column_names_the_kind_and_the_fields_it_reads(capsys):
    _, rows = _rows(capsys)
    assert rows["paper-64"].endswith("  uniform")
    assert rows["clustered-64"].endswith("  clustered (4 towns, spread 4)")
    n = len(PRESETS["real-nyc"].layout.sites)
    assert rows["real-nyc"].endswith(f"  sites ({n} sites, jitter 1)")
    kinds = {name: c.layout.kind for name, c in PRESETS.items()}
    assert all(row.split("  ")[-1].split()[0] == kinds[name] for name, row in rows.items())
