"""cobot-analysis: reproducible analysis of the CoBot motion-capture studies.

Data flows one way: io -> preprocess -> kinematics -> distances / stats / models -> reports.
The public API is ``cobot_analysis.api`` (docs/api.md): every stage as a function on tables,

    >>> import cobot_analysis.api as ca
    >>> ca.average.__module__
    'cobot_analysis.api.analysis'

The scientific reference for every method and name is docs/methods.md (see docs/).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cobot-analysis")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.1.0"
