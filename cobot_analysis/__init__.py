"""cobot-analysis: reproducible analysis of the CoBot motion-capture studies.

Data flows one way: io -> preprocess -> kinematics -> distances / stats / models -> reports.
The public API is ``cobot_analysis.api`` (docs/api.md): every stage as a function on tables,

    >>> import cobot_analysis.api as ca
    >>> ca.average.__module__
    'cobot_analysis.api.analysis'

The scientific reference for every method and name is docs/methods.md (see docs/).
"""


def __getattr__(name: str):
    """``__version__``, read from the installed package's metadata when first asked for (importing
    importlib.metadata is 0.01 s of a command's start, and a command refused at its first check needs none)."""
    if name != "__version__":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version as installed

    try:
        version = installed("cobot-analysis")
    except PackageNotFoundError:  # running from a source tree that is not installed
        version = "0.1.0"
    globals()["__version__"] = version
    return version
