"""wavetomo/_lib.py: finding and loading libwavetomo.so, and the ctypes prototypes of its public C API
(include/wavetomo/*.h; docs/c-api.md). No compiler is involved: ctypes reads the shared library as built
or installed. python/tests/test_prototypes.py checks every prototype here against the headers.

The library is loaded at the first call that needs it (load()), not at import: `import wavetomo`, the
readers and the command runs work without it. Where it is looked for, first found wins:
  1. $WAVETOMO_LIB (a path to libwavetomo.so.N; when set, nothing else is tried)
  2. the build tree the package sits in: python/wavetomo/../../build/libwavetomo.so.N
  3. an installed tree: LIBDIR/pythonX.Y/dist-packages/wavetomo/../../../libwavetomo.so.N (make install)
  4. the loader's own search (LD_LIBRARY_PATH, the ldconfig cache): libwavetomo.so.N
N is the major version of the C library this package was written for (_version.VERSION), the soname's.
"""
import ctypes
import os
import pathlib
import threading
from typing import Any, Dict, List, Optional, Tuple

from ._version import VERSION
from .errors import LoadError

ABI_MAJOR = int(VERSION.split(".")[0])
SONAME = "libwavetomo.so.%d" % ABI_MAJOR
_HERE = pathlib.Path(__file__).resolve().parent


def candidates() -> List[str]:
    """Where the library is looked for, in order (see the module's comment)."""
    env = os.environ.get("WAVETOMO_LIB")
    if env:
        return [env]
    return [str(_HERE.parent.parent / "build" / SONAME), str(_HERE.parent.parent.parent / SONAME), SONAME]


class Sensor_c(ctypes.Structure):
    """struct wt_rtc_sensor (wavetomo/rtc.h)"""
    _fields_ = [("name", ctypes.c_char * 16), ("kind", ctypes.c_int), ("nsub", ctypes.c_int),
                ("offset", ctypes.c_int64), ("theta_x", ctypes.c_double), ("theta_y", ctypes.c_double),
                ("altitude", ctypes.c_double)]


class DM_c(ctypes.Structure):
    """struct wt_rtc_dm (wavetomo/rtc.h)"""
    _fields_ = [("altitude", ctypes.c_double), ("pitch", ctypes.c_double), ("nactive", ctypes.c_int),
                ("offset", ctypes.c_int64), ("nx", ctypes.c_int), ("ny", ctypes.c_int), ("x0", ctypes.c_double),
                ("y0", ctypes.c_double)]


_P = ctypes.c_void_p       # an opaque handle or a buffer's address
_S = ctypes.c_char_p
_I = ctypes.c_int
_I64 = ctypes.c_int64
_D = ctypes.c_double
_SETS = ctypes.POINTER(ctypes.c_char_p)

# name: (restype, argtypes), exactly the declarations of the public headers
_PROTOTYPES: Dict[str, Tuple[Any, List[Any]]] = {
    "wt_version": (_S, []),
    "wt_version_number": (_I, []),
    "wt_strerror": (_S, [_I]),
    "wt_context_alloc": (_P, []),
    "wt_context_free": (None, [_P]),
    "wt_context_set_threads": (None, [_P, _I]),
    "wt_context_threads": (_I, [_P]),
    "wt_error_message": (_S, [_P]),
    "wt_error_status": (_I, [_P]),
    "wt_error_clear": (None, [_P]),
    "wt_rtc_open": (_I, [_P, _S, _S, _I, _SETS, ctypes.POINTER(_P)]),
    "wt_rtc_open_text": (_I, [_P, _S, _S, _I, _SETS, ctypes.POINTER(_P)]),
    "wt_rtc_open_mvm": (_I, [_P, _S, _S, _I, _SETS, ctypes.POINTER(_P)]),
    "wt_rtc_share": (_I, [_P, _P, ctypes.POINTER(_P)]),
    "wt_rtc_close": (None, [_P]),
    "wt_rtc_frame": (_I, [_P, _P, _I64, _P, ctypes.c_uint, _P, _I64]),
    "wt_rtc_frame_f32": (_I, [_P, _P, _I64, _P, ctypes.c_uint, _P, _I64]),
    "wt_rtc_reset": (None, [_P]),
    "wt_rtc_interaction": (_I, [_P, _P, _I64, _P, _I64]),
    "wt_rtc_interaction_t": (_I, [_P, _P, _I64, _P, _I64]),
    "wt_rtc_config": (_S, [_P]),
    "wt_rtc_nslopes": (_I64, [_P]),
    "wt_rtc_nactuators": (_I64, [_P]),
    "wt_rtc_nsensors": (_I, [_P]),
    "wt_rtc_ndms": (_I, [_P]),
    "wt_rtc_recon": (_S, [_P]),
    "wt_rtc_delay": (_I, [_P]),
    "wt_rtc_gain": (_D, [_P]),
    "wt_rtc_rate": (_D, [_P]),
    "wt_rtc_frames": (_I64, [_P]),
    "wt_rtc_frame_time": (_D, [_P]),
    "wt_rtc_sensor_info": (_I, [_P, _I, ctypes.POINTER(Sensor_c)]),
    "wt_rtc_subapertures": (_I, [_P, _I, _P]),
    "wt_rtc_dm_info": (_I, [_P, _I, ctypes.POINTER(DM_c)]),
    "wt_rtc_actuators": (_I, [_P, _P, _P]),
}

# frame flags (wavetomo/rtc.h)
WT_RTC_RAW = 1
WT_RTC_SLOPES_OL = 2
WT_RTC_LGS = 0
WT_RTC_NGS = 1


_lock = threading.Lock()
_loaded: Optional[Tuple[ctypes.CDLL, str]] = None


def _open() -> Tuple[ctypes.CDLL, str]:
    tried = []
    for c in candidates():
        if os.sep in c and not os.path.exists(c):
            tried.append("%s (no such file)" % c)
            continue
        try:
            lib = ctypes.CDLL(c)  # CDLL: the GIL is released during every call
        except OSError as e:
            tried.append("%s (%s)" % (c, e))
            continue
        for name, (res, args) in _PROTOTYPES.items():
            try:
                f = getattr(lib, name)
            except AttributeError:
                raise LoadError("wavetomo: %s lacks %s (a library older than this package; rebuild it)" % (c, name))
            f.restype, f.argtypes = res, args
        major = lib.wt_version_number() // 10000
        if major != ABI_MAJOR:
            raise LoadError("wavetomo: %s is version %s, this package (%s) needs major version %d"
                            % (c, lib.wt_version().decode(), VERSION, ABI_MAJOR))
        return lib, c
    raise LoadError("wavetomo: cannot load the C library %s; tried:\n  %s\nBuild it with `make` in the source "
                    "tree, install it with `make install`, or set WAVETOMO_LIB to the path of %s."
                    % (SONAME, "\n  ".join(tried), SONAME))


def load() -> ctypes.CDLL:
    """The C library, loaded at the first call (then the same object). Raises LoadError, naming every
    place it looked, when it is missing, lacks a function or has another major version."""
    global _loaded
    if _loaded is None:
        with _lock:
            if _loaded is None:
                _loaded = _open()
    return _loaded[0]


def path() -> str:
    """The name the library was loaded by (a path, or the soname the loader resolved)."""
    load()
    assert _loaded is not None
    return _loaded[1]
