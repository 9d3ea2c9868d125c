"""Frames of the world like the paper's Figure 1, with a legend and the step's KPIs.

Facilities are squares, personnel circles, assignments lines. ``save_gif`` writes
frames to a GIF.

:class:`Renderer` builds the figure, its legend and the background once and redraws only
what changes (the markers, the lines, the KPI line) for each frame, by blitting onto the
saved background; ``render_rgb`` keeps one renderer per simulator, so environments that
render every step get the same speed. :class:`HumanWindow` shows frames in a matplotlib
window (the environments' ``render_mode="human"``); :class:`Rendering` is the ``render``,
``close`` and human window that the Gymnasium and PettingZoo environments share.
"""

from __future__ import annotations

import weakref
from pathlib import Path

import numpy as np

from wfbench.core.state import EMPTY, K_AFD, K_NSW, K_PUR, K_WC, ONBOARDING, SERVICING, TO_FACILITY

LEVEL_COLORS = ("#6baed6", "#2171b5", "#08306b")  # novice, mid, expert
FACILITY_COLORS = {"operational": "#31a354", "down, nobody assigned": "#e31a1c", "down, a person assigned": "#fd8d3c"}
HOME_COLOR = "#7f7f7f"
NOTICE_EDGE = "black"  # the edge of a person under notice
LINE_COLOR = "#999999"
KPI_HELP = ("WC  workforce cost (salaries)", "PUR personnel utilization", "AFD facility downtime",
            "NSW welfare, higher is better")
DPI = 100
LEGEND_SHARE = 0.42  # width of the legend panel, as a share of the map's side
RENDER_MODES = ("rgb_array", "human")


def check_render_mode(render_mode: str | None) -> None:
    """A one-line ValueError unless ``render_mode`` is None or one of :data:`RENDER_MODES`."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode {render_mode!r} is not supported; allowed: None, "
                         f"{', '.join(map(repr, RENDER_MODES))}")


class HumanWindow:
    """A matplotlib window that shows each frame for ``1 / fps`` seconds (``render_mode="human"``).

    On a non-interactive backend (a machine without a display, matplotlib's Agg) nothing can
    be shown and frames are dropped, without a word, so that checkers (Gymnasium's
    ``check_env``, PettingZoo's ``render_test``) run headless; ``shown`` counts the frames shown.
    """

    def __init__(self, fps: int):
        self.fps = fps
        self._image = None
        self._headless: bool | None = None
        self.shown = 0

    def show(self, frame: np.ndarray) -> None:
        import matplotlib.pyplot as plt
        from matplotlib.backends import BackendFilter, backend_registry

        if self._headless is None:
            backend = plt.get_backend()
            interactive = {b.lower() for b in backend_registry.list_builtin(BackendFilter.INTERACTIVE)}
            self._headless = backend.lower() not in interactive
        if self._headless:
            return
        if self._image is None:
            fig = plt.figure("wfbench")
            ax = fig.add_axes((0, 0, 1, 1))
            ax.set_axis_off()
            self._image = ax.imshow(frame)
            plt.show(block=False)
        else:
            self._image.set_data(frame)
        plt.pause(1 / self.fps)
        self.shown += 1

    def close(self) -> None:
        if self._image is not None:
            import matplotlib.pyplot as plt

            plt.close(self._image.figure)
            self._image = None


class Renderer:
    """Frames of simulators of one scenario: :meth:`frame` draws an environment's current state.

    A frame is ``size_px`` high and ``(1 + LEGEND_SHARE) * size_px`` wide: the grid on the
    left, the legend and the meaning of the KPIs on the right. ``legend_labels`` lists the
    legend's entries.
    """

    def __init__(self, config, size_px: int = 480):
        # The frame has its own Agg canvas: pyplot's backend, which a "human" window uses, is left alone.
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import LineCollection
        from matplotlib.colors import to_rgba
        from matplotlib.figure import Figure
        from matplotlib.lines import Line2D

        c = config
        width = size_px * (1.0 + LEGEND_SHARE)
        self.fig = Figure(figsize=(width / DPI, size_px / DPI), dpi=DPI)
        self.canvas = FigureCanvasAgg(self.fig)
        map_w = 0.96 * size_px / width
        ax = self.ax = self.fig.add_axes((0.01, 0.02, map_w, 0.9))
        ax.set_xlim(-1, c.grid_width)
        ax.set_ylim(-1, c.grid_height)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        # text and markers scale with the frame (sizes chosen at 480 px) and markers with the cells
        # (a 64x64 grid gets the sizes of the paper-64 frames)
        k = size_px / 480.0
        area = k * k * min(64.0 / max(c.grid_width, c.grid_height, 1), 4.0)
        self.s_fac, self.s_per, self.s_home = 40 * area, 28 * area, 18 * area
        empty = np.empty((0, 2))
        self.lines = LineCollection([], colors=LINE_COLOR, linewidths=0.8, zorder=1, animated=True)
        ax.add_collection(self.lines)
        self.homes = ax.scatter(empty[:, 0], empty[:, 1], marker="+", s=self.s_home, c=HOME_COLOR, linewidths=0.8,
                                zorder=1.5, animated=True)
        self.facilities = ax.scatter(empty[:, 0], empty[:, 1], marker="s", s=self.s_fac, edgecolors="black",
                                     linewidths=0.5, zorder=2, animated=True)
        self.people = ax.scatter(empty[:, 0], empty[:, 1], marker="o", s=self.s_per, zorder=3, animated=True)
        self.title = self.fig.text(0.01 + map_w / 2, 0.965, "", ha="center", va="center", fontsize=9 * k,
                                   animated=True)

        def square(color):
            return Line2D([], [], ls="", marker="s", markersize=7 * k, markerfacecolor=color,
                          markeredgecolor="black", markeredgewidth=0.5)

        def circle(face, edge, width=1.2):
            return Line2D([], [], ls="", marker="o", markersize=6 * k, markerfacecolor=face, markeredgecolor=edge,
                          markeredgewidth=width * k)

        mid = LEVEL_COLORS[1]
        entries = [(square(color), f"facility: {state}") for state, color in FACILITY_COLORS.items()]
        entries += [(circle(color, color), f"person: {name}")
                    for name, color in zip(("novice", "mid", "expert"), LEVEL_COLORS, strict=True)]
        entries += [
            (circle("none", mid), "person: onboarding (hollow)"),
            (circle(mid, NOTICE_EDGE, 1.8), "person: under notice (black edge)"),
            (Line2D([], [], ls="", marker="+", markersize=7 * k, color=HOME_COLOR), "home of a person"),
            (Line2D([], [], color=LINE_COLOR, lw=1.2), "person on the way to / at a job"),
        ]
        handles = [handle for handle, _ in entries]
        self.legend_labels = [label for _, label in entries]
        left = 0.01 + map_w + 0.01
        self.legend = self.fig.legend(handles, self.legend_labels, loc="upper left", bbox_to_anchor=(left, 0.92),
                                      fontsize=7.5 * k, frameon=False, handlelength=1.2, borderaxespad=0.0)
        # the KPI help under the legend, wherever the legend ends at this size
        below = self.legend.get_window_extent(self.canvas.get_renderer()).y0 / self.fig.bbox.height - 0.04
        self.kpi_help = self.fig.text(left + 0.005, below, "top line:\n" + "\n".join(KPI_HELP), ha="left", va="top",
                                      fontsize=7.5 * k, family="monospace")
        self.canvas.draw()  # everything static: the frame of the map, the legend, the KPI help
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)
        self._level_rgba = np.array([to_rgba(x) for x in LEVEL_COLORS])
        self._fac_rgba = np.array([to_rgba(x) for x in FACILITY_COLORS.values()])
        self._notice_rgba = to_rgba(NOTICE_EDGE)

    def update(self, sim, b: int = 0) -> None:
        """Move the markers, lines and KPI line to the state of environment ``b`` of ``sim`` (no drawing)."""
        S = sim.state
        active = np.flatnonzero(S.fac_active[b])
        down = S.fac_down[b, active]
        state = np.where(down, np.where(S.fac_assigned[b, active] >= 0, 2, 1), 0)
        self.facilities.set_offsets(np.column_stack([S.fac_x[b, active], S.fac_y[b, active]]))
        self.facilities.set_facecolors(self._fac_rgba[state])
        status = S.per_status[b]
        employed = np.flatnonzero(status != EMPTY)
        rgba = self._level_rgba[S.per_level[b, employed]]
        face = rgba.copy()
        face[status[employed] == ONBOARDING] = 0.0  # hollow
        notice = S.per_leave[b, employed] >= 0
        edge = rgba.copy()
        edge[notice] = self._notice_rgba
        self.people.set_offsets(np.column_stack([S.per_x[b, employed], S.per_y[b, employed]]))
        self.people.set_facecolors(face)
        self.people.set_edgecolors(edge)
        self.people.set_linewidths(np.where(notice, 1.8, 1.2))
        self.homes.set_offsets(np.column_stack([S.per_hx[b, employed], S.per_hy[b, employed]]))
        on_job = employed[((status[employed] == TO_FACILITY) | (status[employed] == SERVICING))
                          & (S.per_target[b, employed] >= 0)]
        f = S.per_target[b, on_job]
        self.lines.set_segments(np.stack([np.column_stack([S.per_x[b, on_job], S.per_y[b, on_job]]),
                                          np.column_stack([S.fac_x[b, f], S.fac_y[b, f]])], axis=1))
        last = S.last[b]
        self.title.set_text(f"t={int(S.t[b])}  WC={last[K_WC]:.1f}  PUR={last[K_PUR]:.2f}  AFD={last[K_AFD]:.2f}  "
                            f"NSW={last[K_NSW]:.3f}")

    def frame(self, sim, b: int = 0) -> np.ndarray:
        """The current state of environment ``b`` of ``sim`` as an (H, W, 3) uint8 image."""
        self.update(sim, b)
        self.canvas.restore_region(self.background)
        for artist in (self.lines, self.homes, self.facilities, self.people):
            self.ax.draw_artist(artist)
        self.fig.draw_artist(self.title)
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()


_RENDERERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # sim -> {size_px: Renderer}


def render_rgb(sim, b: int = 0, size_px: int = 480) -> np.ndarray:
    """The state of environment ``b`` of ``sim`` as an (H, W, 3) uint8 image (see :class:`Renderer`)."""
    mine = _RENDERERS.setdefault(sim, {})
    renderer = mine.get(size_px)
    if renderer is None:
        renderer = mine[size_px] = Renderer(sim.config, size_px)
    return renderer.frame(sim, b)


class Rendering:
    """``render``, ``close`` and the human window of an environment over a core whose ``sim`` is drawn.

    The Gymnasium and PettingZoo environments mix it in; they set ``render_mode``, ``metadata``
    (with ``render_fps``), ``core`` and ``_window = None``, and call ``_show`` after every reset and step.
    """

    def _show(self) -> None:
        """In ``render_mode="human"``, draw the current state in the window (every reset and step)."""
        if self.render_mode == "human":
            self._window = self._window or HumanWindow(self.metadata["render_fps"])
            self._window.show(render_rgb(self.core.sim))

    def render(self):
        """The current frame (``"rgb_array"``); None in ``"human"`` mode, which draws at every step."""
        if self.render_mode != "rgb_array" or self.core.sim is None:
            return None
        return render_rgb(self.core.sim)

    def close(self) -> None:
        if self._window is not None:
            self._window.close()
            self._window = None


def save_gif(frames: list[np.ndarray], path: str | Path, fps: int = 8) -> None:
    """Write RGB frames as a looping GIF.

    Every frame is mapped onto one 256-colour palette, taken from the first, middle and last
    frames (a renderer's frames show every marker colour in their legend); a palette of its
    own per frame cost 40 ms a frame and doubled the file.
    """
    from PIL import Image

    sample = np.concatenate([frames[0], frames[len(frames) // 2], frames[-1]])
    palette = Image.fromarray(sample).quantize(colors=256, method=Image.Quantize.FASTOCTREE)
    images = [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
