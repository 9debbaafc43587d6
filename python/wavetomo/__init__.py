"""wavetomo: wavelet MAP tomography for MCAO, from Python (docs/python-api.md).

    import wavetomo
    rec = wavetomo.Reconstructor("data/presets/demo.cfg", "pcg3")   # or cg9, or matrix="M.h5"
    a = rec(s)                      # one frame: slopes [rad] -> DM commands [m], POLC inside
    res = wavetomo.sim("data/presets/demo.cfg", "cg9", frames=50)   # `wavetomo sim`, read back
    res["eval/strehl_le"].reshape(5, 5)

The per-frame objects (System, Reconstructor) call libwavetomo.so through ctypes; the runs (sim, compare,
budget, build, run) call the `wavetomo` executable; the readers use h5py. The library is loaded at the first
call that needs it: `import wavetomo` works without it, and that call raises LoadError saying where it looked
($WAVETOMO_LIB points to it).
"""
import os

from . import _lib
from ._version import VERSION
from .commands import budget, build, compare, executable, run, sim
from .config import overrides, parse as parse_config
from .errors import (CommandError, ConfigError, Error, FileError, FormatError, InterruptedRun, InvalidError,
                     LibraryError, LoadError, NoMemoryError, NumericError, SolverWarning)
from .files import (MatrixResult, Result, read, read_budget, read_commands, read_compare, read_matrix, read_run,
                    read_telemetry)
from .layout import ARCSEC, DM, Layout, Sensor
from .rtc import Reconstructor, System

__version__ = VERSION  # this package's: the C header's it was built from (version() is the loaded library's)


def version() -> str:
    """The version of the C library loaded ("0.1.0"); __version__ is this package's, the same when they fit."""
    return _lib.load().wt_version().decode()


def library_path() -> str:
    """The file of the C library loaded."""
    path = _lib.path()
    if os.sep in path:
        return os.path.realpath(path)
    with open("/proc/self/maps") as f:  # found by the loader's search
        for line in f:
            if "libwavetomo.so" in line:
                return os.path.realpath(line.split(None, 5)[-1].strip())
    return path


__all__ = ["System", "Reconstructor", "Sensor", "DM", "Layout", "ARCSEC", "sim", "compare", "budget", "build", "run",
           "executable", "read", "read_run", "read_telemetry", "read_matrix", "read_commands", "read_compare",
           "read_budget", "Result", "MatrixResult", "overrides", "parse_config", "version", "library_path", "Error",
           "LoadError", "NoMemoryError", "InvalidError", "ConfigError", "FileError", "LibraryError", "NumericError",
           "FormatError", "InterruptedRun", "CommandError", "SolverWarning"]
