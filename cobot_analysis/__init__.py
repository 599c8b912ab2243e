"""cobot-analysis: reproducible analysis of the CoBot motion-capture studies.

Data flows one way: io -> preprocess -> kinematics -> metrics / stats / models -> reports.
The scientific reference for every method and name is docs/methods.md (see docs/).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cobot-analysis")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.1.0"
