"""Errors that the command line turns into one clear line and an exit code.

Exit-code convention of every command:
  0  success (or stage skipped because it is up to date)
  1  internal failure (a bug, or a numerical failure that is not the user's input)
  2  bad usage or bad input (``InputError``): the message names the file and the remedy
  3  done, but some trials were refused and left out (``import``, ``preprocess``; ``refusals``)
  130 / 143  interrupted by Ctrl-C / SIGTERM (``interrupt.py``): nothing partial kept
"""

from __future__ import annotations

from os import PathLike


class InputError(Exception):
    """Bad input: the one-line message names the offending file (when there is one) and what to do.

    >>> str(InputError("marker LASI missing", path="t1.c3d", remedy="map it with --marker-map"))
    't1.c3d: marker LASI missing; map it with --marker-map'
    >>> str(InputError("no mean trajectory", path=""))   # a table given in memory: no file to name
    'no mean trajectory'
    """

    exit_code = 2

    def __init__(self, message: str, *, path: str | PathLike | None = None, remedy: str | None = None):
        self.path = None if path is None or str(path) == "" else str(path)  # "": no file to name
        self.remedy = remedy
        self.detail = message
        text = message if self.path is None else f"{self.path}: {message}"
        if remedy:
            text = f"{text}; {remedy}"
        super().__init__(" ".join(text.split()))  # always a single line


class SolverError(Exception):
    """A numerical solve that did not converge where a result was required (exit code 2 on the CLI
    when it is caused by the given inputs, e.g. an unreachable goal)."""

    exit_code = 2
