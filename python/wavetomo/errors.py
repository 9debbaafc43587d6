"""wavetomo/errors.py: the exceptions of the Python package.

Every failure of the library becomes an Error subclass carrying the library's own message (the file, key,
frame or index at fault, as `wt_error_message` says it) and its status code (include/wavetomo/context.h).
The subclasses also derive from the matching built-in exception, so `except ValueError` catches a bad
argument or configuration and `except OSError` a missing file.
"""

from typing import List, Optional

__all__ = ["Error", "LoadError", "NoMemoryError", "InvalidError", "ConfigError", "FileError", "LibraryError",
           "NumericError", "FormatError", "InterruptedRun", "CommandError", "SolverWarning"]

# status codes of include/wavetomo/context.h
WT_OK = 0
WT_WARN_MAXITER = 1
WT_WARN_BREAKDOWN = 2
WT_ERR_NOMEM = -1
WT_ERR_INVALID = -2
WT_ERR_CONFIG = -3
WT_ERR_IO = -4
WT_ERR_LIBRARY = -5
WT_ERR_NUMERIC = -6
WT_ERR_FORMAT = -7
WT_ERR_INTERRUPTED = -8


class Error(Exception):
    """A wavetomo failure: `message` is the library's text, `status` its status code (< 0)."""

    def __init__(self, message: str, status: Optional[int] = None) -> None:
        super().__init__(message)
        self.message = message
        self.status = status

    def __str__(self) -> str:
        return self.message


class LoadError(Error, ImportError):
    """The C library could not be loaded (missing, lacking a function, or of another major version): raised
    by the first call that needs it, not by `import wavetomo`; the message names every place looked in."""


class NoMemoryError(Error, MemoryError):
    """WT_ERR_NOMEM: an allocation failed."""


class InvalidError(Error, ValueError):
    """WT_ERR_INVALID: a bad argument or inconsistent sizes."""


class ConfigError(Error, ValueError):
    """WT_ERR_CONFIG: a configuration file or override is malformed or out of range."""


class FileError(Error, OSError):
    """WT_ERR_IO: a file could not be read or written."""


class LibraryError(Error, RuntimeError):
    """WT_ERR_LIBRARY: an external library (HDF5, CHOLMOD, FFTW, LAPACK) reported a failure."""


class NumericError(Error, ArithmeticError):
    """WT_ERR_NUMERIC: NaN or Inf input, a breakdown, a loss of positive definiteness."""


class FormatError(Error, ValueError):
    """WT_ERR_FORMAT: a file has the wrong shape, type or provenance (or is incomplete)."""


class InterruptedRun(Error):
    """WT_ERR_INTERRUPTED: a run stopped by a signal."""


class CommandError(Error):
    """A `wavetomo` command (sim, compare, budget, build, run) failed: `message` is its error text,
    `returncode` its exit status (1: refused or failed, 2: bad usage, 128 + N: signal N), `stderr` all it
    wrote there, `command` the argument list."""

    def __init__(self, message: str, returncode: int, stderr: str, command: List[str]) -> None:
        super().__init__(message, None)
        self.returncode = returncode
        self.stderr = stderr
        self.command = command


class SolverWarning(UserWarning):
    """A warning status (> 0) of a frame: an iterative solver stopped early; the commands are usable."""


_BY_STATUS = {WT_ERR_NOMEM: NoMemoryError, WT_ERR_INVALID: InvalidError, WT_ERR_CONFIG: ConfigError,
              WT_ERR_IO: FileError, WT_ERR_LIBRARY: LibraryError, WT_ERR_NUMERIC: NumericError,
              WT_ERR_FORMAT: FormatError, WT_ERR_INTERRUPTED: InterruptedRun}


def error_for(status: int, message: str) -> Error:
    """The exception of a negative status code with its message."""
    return _BY_STATUS.get(status, Error)(message, status)
