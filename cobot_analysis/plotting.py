"""matplotlib with the project's one figure style (Agg backend: files only, no screen).

Every figure of the package (reports, models, localisation, prediction) is drawn through
``pyplot()``, so that the style and the non-interactive backend are set in one place, and saved through
``save()``, which lays it out once for all its formats.
"""

from __future__ import annotations

import numpy as np

STYLE = {
    "figure.dpi": 100, "font.size": 9, "axes.titlesize": 9, "axes.labelsize": 9, "legend.fontsize": 8,
    "axes.spines.top": False, "axes.spines.right": False, "axes.grid": True, "grid.alpha": 0.3,
    "savefig.bbox": "tight",
}

# one colour per predictor in every figure of a report (overlays, horizon sweep)
PREDICTOR_COLOURS = {"oc": "tab:blue", "cv": "tab:orange", "ctrv": "tab:green", "goal": "tab:red",
                     "goal-inferred": "tab:purple"}


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend with ``STYLE`` applied."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update(STYLE)
    return plt


LAYOUT_PASSES = 3  # a layout still moving after them is drawn as the last pass left it
SETTLED_PX = 0.01  # pixels: axes that move less than this in a pass have stopped (round-off moves them 1e-13 px)


def settle_layout(fig) -> None:
    """Draw ``fig`` (without rendering) until its layout engine stops moving the axes (no edge moves by
    ``SETTLED_PX`` pixels or more), at most ``LAYOUT_PASSES`` times: a draw places texts (titles above their tick
    labels) that the next pass makes room for. The layout ``save`` writes, and the one
    ``reports.figures.check_figure`` checks."""
    fig.draw_without_rendering()  # runs the layout engine, as savefig's first pass does
    for _ in range(LAYOUT_PASSES - 1 if fig.get_layout_engine() is not None else 0):
        before = [ax.get_position().bounds for ax in fig.axes]
        fig.draw_without_rendering()
        after = [ax.get_position().bounds for ax in fig.axes]
        if len(after) == len(before):
            pixels = np.tile(fig.get_size_inches() * fig.dpi, 2)  # (x0, y0, width, height) as fractions -> pixels
            moved = np.abs(np.reshape(after, (-1, 4)) - np.reshape(before, (-1, 4))) * pixels
            if moved.max(initial=0.0) < SETTLED_PX:
                break


def save(fig, paths, dpi: float = 150) -> None:
    """Write ``fig`` to each of ``paths`` (format from the suffix) at ``dpi``, cropped to its tight bounding box.

    The layout (constrained or tight) and the bounding box (padded by ``savefig.pad_inches``) are computed once,
    at ``dpi`` with the PNG renderer, and then fixed: every format draws the same layout once. The layout engine
    runs until the axes stop moving, at most ``LAYOUT_PASSES`` times: a draw places texts that the next pass makes
    room for (after one pass, in a grid of equal-aspect panels, a panel's title sat on the tick labels of the panel
    above it; ``savefig(bbox_inches="tight")`` lays out twice). The figure's layout engine is left off.
    """
    import matplotlib as mpl

    original_dpi = fig.dpi
    fig.set_dpi(dpi)
    try:
        settle_layout(fig)
        box = fig.get_tightbbox().padded(mpl.rcParams["savefig.pad_inches"])
    finally:
        fig.set_dpi(original_dpi)
    fig.set_layout_engine("none")
    for path in paths:
        fig.savefig(path, dpi=dpi, bbox_inches=box)
