"""The two conventions of the model stages (docs/methods.md sec. 11): one object that says how the
OC problems are discretised and timed, how paths are compared and how predictions are made.

- ``published``: what the authors' code did, so that the papers' numbers can be reproduced:
  explicit Euler with a fixed step per node, running costs summed per node, psi not wrapped, the
  start moved to the origin, the authors' duration rules, paths compared after arc-length
  resampling, one prediction node per sample at 0.1 s starting at rest, population sd.
- ``continuous``: our own reading of the formulas: integrated costs on an exact-in-time step, the
  duration a decision variable, the goal pose at rest a terminal constraint (the b weights unused),
  psi wrapped and regularised at the goal, time-normalised pointwise distances, predictions at the
  real sampling period from an estimated velocity, sample sd.

Stages take ``--convention NAME`` (``get``), pass the ``Convention`` down, and write its name into
their Parquet metadata, manifest and results (their directories: ``registry.directory``). Mixing outputs of two conventions is refused
(``check_same``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cobot_analysis.errors import InputError

NAMES = ("published", "continuous")
WIDE_T_BOUNDS = (0.1, 10.0)  # the continuous walker rules' free-duration bounds (x T0)


@dataclass(frozen=True)
class OCRule:
    """Discretisation and duration rule of one OC model (docs/methods.md sec. 5, 11)."""

    scheme: str  # "midpoint": exact-in-time step, cost dt * phi, dt = T / N | "euler": explicit Euler, cost summed per node
    duration: str  # "free" (T a decision variable) | "grid" (T0 (1 + 0.05 i)) | "nelder-mead" (J / T) | "last-node" (grid by |phi_N|)
    dt: float | None = None  # fixed node step of "euler" (s)
    psi: str = "wrapped"  # "wrapped" (body-frame bearing in (-pi, pi], regularised at the goal) | "raw" (atan2 - theta)
    heading: str = "raw"  # heading error of the terminal cost: "raw" (thf - theta) | "wrap-once" (+-2 pi once)
    psi_eps: float = 0.05  # m, psi^2 r^2 / (r^2 + eps^2) near the goal
    goal: str = "cost"  # "cost": goal and rest weighted by the terminal cost (b0..b3) | "constraint": X(T) = (goal, at rest)
    T_bounds: tuple[float, float] = (0.4, 2.5)  # "free": T within these multiples of T0 = d / v_nominal + 1 s


@dataclass(frozen=True)
class Comparison:
    """How a path is compared with a measured one (docs/methods.md sec. 3, 11)."""

    resample: str  # "time": pointwise on time-normalised samples | "arclength": splprep (s = 0) resampling first
    both_resampled: bool  # with "arclength": the measured path is resampled too (the authors' final scripts)
    angle_difference: str  # "wrapped": |wrap(a - b)| | "each": |wrap(a) - wrap(b)| (each angle wrapped on its own)
    measured_gamma: str  # gamma of a measured path: "data" (as recorded, when the data hold it) | "path" (from x, y, theta)
    sd_ddof: int  # 1: sample sd | 0: population sd (numpy.std)


@dataclass(frozen=True)
class PredictionRule:
    """How the receding-horizon OC predictor is set up (docs/methods.md sec. 7, 11)."""

    node_dt: float | None  # seconds per node: fixed (one node per sample) or None = the real sampling period
    start: str  # "rest": every window starts at rest | "estimated": velocity estimated from the window's first poses
    warm_start: bool  # each window starts from the previous one's solution (else a cold solve)
    table_weights: str  # weights preset of the table predictor


@dataclass(frozen=True)
class Convention:
    name: str
    summary: str
    oc: dict[str, OCRule] = field(hash=False)
    comparison: Comparison
    prediction: PredictionRule

    def oc_rule(self, model: str, *, option: str = "--convention") -> OCRule:
        """The rule of ``model``; an InputError (before any work) if this convention has none."""
        if model not in self.oc:
            other = [c for c in NAMES if model in CONVENTIONS[c].oc and c != self.name]
            raise InputError(f"the {self.name} convention has no {model} model ({self.why_not.get(model, '')})".replace(" ()", ""),
                             remedy=f"use {option} {other[0]}" if other else f"use one of the models {', '.join(self.oc)}")
        return self.oc[model]

    @property
    def why_not(self) -> dict[str, str]:
        return {"unicycle": "the authors compared no unicycle model", "coupled": "the authors' coupled code is not a published convention here"} \
            if self.name == "published" else {}


PUBLISHED = Convention(
    name="published",
    summary=("the authors' discrete conventions: explicit Euler, running costs summed per node (dt 0.1 s; 0.01 s for "
             "the Mombaur form), psi not wrapped, start moved to the origin, the authors' duration rules, paths "
             "compared after arc-length resampling, prediction one node per sample from rest, population sd"),
    oc={
        "improved": OCRule("euler", "nelder-mead", dt=0.1, psi="raw", heading="wrap-once", psi_eps=1e-3),
        "table": OCRule("euler", "nelder-mead", dt=0.1, psi="raw", heading="wrap-once", psi_eps=1e-3),
        "mombaur": OCRule("euler", "last-node", dt=0.01, psi="raw", heading="fmod-pi", psi_eps=1e-3),
    },
    comparison=Comparison(resample="arclength", both_resampled=True, angle_difference="each", measured_gamma="data", sd_ddof=0),
    prediction=PredictionRule(node_dt=0.1, start="rest", warm_start=False, table_weights="table-prediction-2022"),
)

CONTINUOUS = Convention(
    name="continuous",
    summary=("integrated costs on an exact-in-time step, the duration a decision variable, the goal pose at rest a "
             "terminal constraint, psi wrapped and "
             "regularised at the goal, time-normalised pointwise distances, prediction at the real sampling period "
             "from an estimated velocity, sample sd"),
    oc={
        # the goal a constraint, T -> 0 and T -> inf both cost without bound: the duration's bounds are a guard
        # only, wide enough for the pace of any weights (the table-2022 weights: 6-8 T0), docs/methods.md sec. 5.5
        "unicycle": OCRule("midpoint", "free", goal="constraint", T_bounds=WIDE_T_BOUNDS),
        "improved": OCRule("midpoint", "free", goal="constraint", T_bounds=WIDE_T_BOUNDS),
        "table": OCRule("midpoint", "free", goal="constraint", T_bounds=WIDE_T_BOUNDS),
        "mombaur": OCRule("midpoint", "grid", goal="constraint"),
        "coupled": OCRule("midpoint", "free", goal="constraint"),
    },
    comparison=Comparison(resample="time", both_resampled=False, angle_difference="wrapped", measured_gamma="path", sd_ddof=1),
    prediction=PredictionRule(node_dt=None, start="estimated", warm_start=True, table_weights="table-2022"),
)

CONVENTIONS = {c.name: c for c in (PUBLISHED, CONTINUOUS)}


def get(name: str | Convention, option: str = "--convention") -> Convention:
    """The convention called ``name``; an InputError naming the option and the valid values otherwise."""
    if isinstance(name, Convention):
        return name
    if name not in CONVENTIONS:
        raise InputError(f"{option} {name!r} is not a convention", remedy=f"use one of {', '.join(NAMES)}")
    return CONVENTIONS[name]


def check_same(found: dict[str, str | None], what: str = "these inputs") -> str | None:
    """The one convention of several inputs (path -> convention, None when an input has none);
    an InputError when two differ."""
    named = {p: c for p, c in found.items() if c}
    if len(set(named.values())) > 1:
        listing = "; ".join(f"{p}: {c}" for p, c in named.items())
        raise InputError(f"{what} mix outputs of two conventions ({listing})",
                         remedy="re-run the stages with one --convention, or compare them in separate workspaces")
    return next(iter(named.values()), None)
