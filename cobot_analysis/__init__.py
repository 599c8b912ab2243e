"""cobot-analysis: reproducible analysis of the CoBot motion-capture studies.

Data flows one way: io -> preprocess -> kinematics -> metrics / stats / models -> reports.
The functions of the public API (``cobot_analysis.api``: ``import_markers``, ``preprocess``,
``average``, ``compare``, ``statistics``, ``reconstruct``, ``generate``, ``fit_ioc``, ``predict``,
``localise``, ...) are available here too, imported on first use:

    >>> import cobot_analysis as ca
    >>> ca.average.__module__
    'cobot_analysis.api.analysis'

The scientific reference for every method and name is docs/methods.md (see docs/); the API is
documented in docs/api.md.
"""

from importlib.metadata import PackageNotFoundError, version
from typing import Any

try:
    __version__ = version("cobot-analysis")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    from importlib import import_module

    api = import_module("cobot_analysis.api")
    if name in api.EXPORTS:
        return getattr(api, name)
    raise AttributeError(f"module 'cobot_analysis' has no attribute {name!r}")
