"""Drawing the world like the paper's Figure 1: facilities as squares, personnel as circles,
assignments as lines. Returns an RGB array; ``save_gif`` writes frames to a GIF."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wfbench.state import EMPTY, K_AFD, K_NSW, K_PUR, K_WC, ONBOARDING, SERVICING, TO_FACILITY

LEVEL_COLORS = ("#6baed6", "#2171b5", "#08306b")


def render_rgb(sim, b: int = 0, size_px: int = 480) -> np.ndarray:
    """The state of environment ``b`` of ``sim`` as an (H, W, 3) uint8 image."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    S, c = sim.state, sim.config
    dpi = 100
    fig = Figure(figsize=(size_px / dpi, size_px / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.02, 0.02, 0.96, 0.9))
    ax.set_xlim(-1, c.grid_width)
    ax.set_ylim(-1, c.grid_height)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    active = np.flatnonzero(S.fac_active[b])
    for p in np.flatnonzero(S.per_status[b] != EMPTY):
        f = S.per_target[b, p]
        if f >= 0 and S.per_status[b, p] in (TO_FACILITY, SERVICING):
            ax.plot([S.per_x[b, p], S.fac_x[b, f]], [S.per_y[b, p], S.fac_y[b, f]], color="#999999", lw=0.8, zorder=1)
    colors = np.where(S.fac_down[b, active], np.where(S.fac_assigned[b, active] >= 0, "#fd8d3c", "#e31a1c"), "#31a354")
    ax.scatter(S.fac_x[b, active], S.fac_y[b, active], marker="s", s=40, c=list(colors), edgecolors="black",
               linewidths=0.5, zorder=2)
    for p in np.flatnonzero(S.per_status[b] != EMPTY):
        onboarding = S.per_status[b, p] == ONBOARDING
        color = LEVEL_COLORS[S.per_level[b, p]]
        ax.scatter([S.per_x[b, p]], [S.per_y[b, p]], marker="o", s=28, zorder=3,
                   facecolors="none" if onboarding else color, edgecolors=color,
                   linewidths=1.2 if S.per_leave[b, p] < 0 else 2.5)
    last = S.last[b]
    fig.suptitle(f"t={int(S.t[b])}  WC={last[K_WC]:.1f}  PUR={last[K_PUR]:.2f}  AFD={last[K_AFD]:.2f}  "
                 f"NSW={last[K_NSW]:.3f}", fontsize=9)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def save_gif(frames: list[np.ndarray], path: str | Path, fps: int = 8) -> None:
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
