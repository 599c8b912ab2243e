"""Heavy libraries imported on first use, so that a command checks its options and finds its inputs before it
pays for them (issue 22: pandas with pyarrow is about 0.3 s of a command's start-up; docs/benchmarks.md).

    from cobot_analysis.lazy import pandas as pd    # instead of: import pandas as pd

``pd`` is a stand-in module: the first attribute looked up on it (``pd.DataFrame``) imports pandas and copies
its names into the stand-in, so later look-ups cost what a module's do. ``sys.modules`` holds pandas only once
it is imported, so ``"pandas" in sys.modules`` still tells whether a command paid for it
(tests/test_cli_startup.py).

    >>> from cobot_analysis.lazy import pandas as pd
    >>> int(pd.DataFrame({"x": [1, 2]})["x"].sum())
    3
"""

from __future__ import annotations

import importlib
import types
from typing import Any


class LazyModule(types.ModuleType):
    """A module imported when one of its names is first looked up."""

    def __getattr__(self, name: str) -> Any:  # called only for names the stand-in does not hold yet
        module = importlib.import_module(self.__name__)
        self.__dict__.update(module.__dict__)
        return getattr(module, name)


pandas: Any = LazyModule("pandas")
