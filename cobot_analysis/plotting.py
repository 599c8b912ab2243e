"""matplotlib with the project's one figure style (Agg backend: files only, no screen).

Every figure of the package (reports, models, localisation, prediction) is drawn through
``pyplot()``, so that the style and the non-interactive backend are set in one place, and saved through
``save()``, which lays it out once for all its formats.
"""

from __future__ import annotations

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


def save(fig, paths, dpi: float = 150) -> None:
    """Write ``fig`` to each of ``paths`` (format from the suffix) at ``dpi``, cropped to its tight bounding box.

    The layout (constrained or tight) and the bounding box (padded by ``savefig.pad_inches``) are computed once,
    at ``dpi`` with the PNG renderer (what ``savefig(bbox_inches="tight")`` does before each format), and then
    fixed: every format draws the same layout once. The figure's layout engine is left off.
    """
    import matplotlib as mpl

    original_dpi = fig.dpi
    fig.set_dpi(dpi)
    try:
        fig.draw_without_rendering()  # runs the layout engine, as savefig's first pass does
        box = fig.get_tightbbox().padded(mpl.rcParams["savefig.pad_inches"])
    finally:
        fig.set_dpi(original_dpi)
    fig.set_layout_engine("none")
    for path in paths:
        fig.savefig(path, dpi=dpi, bbox_inches=box)
