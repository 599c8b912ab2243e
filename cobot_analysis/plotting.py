"""matplotlib with the project's one figure style (Agg backend: files only, no screen).

Every figure of the package (reports, models, localisation, prediction) is drawn through
``pyplot()``, so that the style and the non-interactive backend are set in one place.
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
