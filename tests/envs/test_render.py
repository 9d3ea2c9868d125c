"""Rendering: a legend that explains every marker, markers that follow the state, progress in the CLI."""

import numpy as np
import pytest
from PIL import Image
from wfbench.policies import get

from wfbench import Simulator
from wfbench.cli import main
from wfbench.core.state import EMPTY, SERVICING, TO_FACILITY
from wfbench.envs.render import FACILITY_COLORS, LEVEL_COLORS, Renderer, render_rgb, save_gif
from wfbench.scenarios.resolve import resolve_scenario


@pytest.fixture(scope="module")
def running():
    """A ``small`` episode 60 steps into the heuristic policy: requests open, people on jobs."""
    sim = Simulator(resolve_scenario("small"), [4])
    obs = sim.reset()
    policy = get("heuristic")
    policy.reset([4])
    for _ in range(60):
        sim.step(policy.act(obs))
        obs = sim.observe()
    return sim


def rgb(hex_color):
    return tuple(int(hex_color[i:i + 2], 16) for i in (1, 3, 5))


def test_render__legend_names_every_marker_and_the_kpis(running):
    r = Renderer(running.config)
    labels = " | ".join(r.legend_labels)
    for words in ("operational", "down, nobody assigned", "down, a person assigned", "novice", "mid", "expert",
                  "onboarding", "under notice", "home", "job"):
        assert words in labels, f"the legend has no entry for {words!r}: {r.legend_labels}"
    assert [t.get_text() for t in r.legend.get_texts()] == r.legend_labels
    help_text = r.kpi_help.get_text()
    for kpi in ("WC", "PUR", "AFD", "NSW"):
        assert kpi in help_text and kpi in r.title.get_text() + help_text, f"{kpi} is not explained: {help_text!r}"


def test_render__legend_is_drawn_in_its_colours_beside_the_map(running):
    r = Renderer(running.config)
    img = r.frame(running)
    H = img.shape[0]
    box = r.legend.get_window_extent()
    area = img[int(H - box.y1):int(H - box.y0), int(box.x0):int(box.x1)].reshape(-1, 3)
    colours = {tuple(c) for c in np.unique(area, axis=0).tolist()}
    for name in (*FACILITY_COLORS.values(), *LEVEL_COLORS):
        assert rgb(name) in colours, f"legend marker colour {name} is not drawn in the legend's area"
    assert box.x0 >= r.ax.get_window_extent().x1, "the legend must not cover the map"


def test_render__markers_follow_the_state(running):
    r = Renderer(running.config)
    r.update(running)
    S, b = running.state, 0
    active = np.flatnonzero(S.fac_active[b])
    employed = np.flatnonzero(S.per_status[b] != EMPTY)
    on_job = [p for p in employed if S.per_status[b, p] in (TO_FACILITY, SERVICING)]
    assert len(on_job) > 0, "the fixture should have someone on a job"
    np.testing.assert_array_equal(r.facilities.get_offsets(), np.column_stack([S.fac_x[b, active], S.fac_y[b, active]]))
    want = [FACILITY_COLORS["operational"] if not S.fac_down[b, f] else
            FACILITY_COLORS["down, a person assigned"] if S.fac_assigned[b, f] >= 0 else
            FACILITY_COLORS["down, nobody assigned"] for f in active]
    got = [tuple(int(round(255 * v)) for v in c[:3]) for c in r.facilities.get_facecolors()]
    assert got == [rgb(w) for w in want], "facility colours must show operational / down / down and assigned"
    people = np.column_stack([S.per_x[b, employed], S.per_y[b, employed]])
    np.testing.assert_array_equal(r.people.get_offsets(), people)
    homes = np.column_stack([S.per_hx[b, employed], S.per_hy[b, employed]])
    np.testing.assert_array_equal(r.homes.get_offsets(), homes)
    assert len(r.lines.get_segments()) == len(on_job), "one assignment line per person travelling to or at a job"
    t = int(S.t[b])
    assert r.title.get_text().startswith(f"t={t} "), r.title.get_text()


def test_render__render_rgb_redraws_the_changing_state(running):
    sim = Simulator(resolve_scenario("small"), [5])
    obs = sim.reset()
    first = render_rgb(sim)
    assert first.dtype == np.uint8 and first.shape[2] == 3 and first.shape[1] > first.shape[0], "map plus legend"
    policy = get("heuristic")
    policy.reset([5])
    for _ in range(30):
        sim.step(policy.act(obs))
        obs = sim.observe()
    later = render_rgb(sim)
    assert later.shape == first.shape and not np.array_equal(later, first), "a later frame must show the new state"
    # the legend side is the same in both frames: only the map and the KPI line change
    r = Renderer(sim.config)
    x0 = int(r.legend.get_window_extent().x0)
    top = int(r.fig.bbox.height * 0.08)  # below the KPI line
    np.testing.assert_array_equal(later[top:, x0:], first[top:, x0:])


@pytest.mark.slow
def test_save_gif__keeps_every_frame_and_its_colours(running, tmp_path):
    r = Renderer(running.config)
    sim = Simulator(resolve_scenario("small"), [6])
    obs = sim.reset()
    policy = get("heuristic")
    policy.reset([6])
    frames = [r.frame(sim)]
    for _ in range(2):
        for _ in range(20):
            sim.step(policy.act(obs))
            obs = sim.observe()
        frames.append(r.frame(sim))
    save_gif(frames, tmp_path / "f.gif")
    with Image.open(tmp_path / "f.gif") as gif:
        assert gif.n_frames == 3
        for i, frame in enumerate(frames):
            gif.seek(i)
            back = np.asarray(gif.convert("RGB")).astype(int)
            assert np.abs(back - frame).mean() < 3, f"frame {i} lost its colours in the GIF's palette"
            colours = np.unique(back.reshape(-1, 3), axis=0)
            for name in (*FACILITY_COLORS.values(), *LEVEL_COLORS):
                nearest = np.abs(colours - rgb(name)).sum(axis=1).min()
                assert nearest <= 12, f"frame {i}: marker colour {name} is off by {nearest} in the GIF"


def test_cli_simulate__shows_progress_and_writes_the_frames(tmp_path, capsys):
    out = tmp_path / "run.gif"
    assert main(["simulate", "--scenario", "small", "--steps", "12", "--every", "4", "--render", str(out)]) == 0
    captured = capsys.readouterr()
    assert "simulate small seed 0" in captured.err and "/12" in captured.err, (
        f"no progress bar over the 12 steps on stderr: {captured.err!r}")
    assert "wrote 4 frames" in captured.out
    with Image.open(out) as gif:
        assert gif.n_frames == 4, "frames at t = 0, 4, 8, 12"
        assert gif.size[0] > gif.size[1], "the frames carry the legend beside the map"


def test_cli_simulate__no_progress_hides_the_bar(capsys):
    assert main(["simulate", "--scenario", "small", "--steps", "5", "--no-progress"]) == 0
    assert "simulate small" not in capsys.readouterr().err
