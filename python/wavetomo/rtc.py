"""wavetomo/rtc.py: the system and the per-frame reconstructor, over the C API of wavetomo/rtc.h.

System        a configuration with overrides, validated by the library: sizes, geometry, the effective
              configuration, the interaction Â (commands -> slopes) and its transpose
Reconstructor a System with a reconstructor (pcg3, cg9 or a stored MVM) whose call maps a slope vector to
              DM commands: POLC inside (the integrator and its delay, as `wavetomo sim`'s loop), or the
              raw reconstruction R s_ol (as `wavetomo run`)

numpy in and out: a float32 frame runs the library's float32 entry (the telemetry's type, `wavetomo run`'s
bits) and returns float32; anything else runs in float64. Sizes, NaN and Inf are checked by the library,
whose message the exception carries. Each object owns its C context and instance; a lock lets one thread
at a time run a frame on it (different objects run in parallel: ctypes releases the GIL).
Reconstructor.share() opens another loop on the same plan (system, Â, stored R): several loops, one R.
"""
import ctypes
import os
import threading
import warnings
from typing import Any, Callable, Dict, List, NoReturn, Optional

import numpy as np
import numpy.typing as npt

from . import _lib
from .config import Overrides, overrides, parse
from .errors import Error, SolverWarning, error_for
from .files import PathLike
from .layout import DM, Layout, Sensor

__all__ = ["System", "Reconstructor"]


def _L() -> ctypes.CDLL:
    """The C library (loaded at the first object's set-up: LoadError if missing)."""
    return _lib.load()


def _ptr(a: Optional[np.ndarray]) -> Optional[int]:
    return a.ctypes.data if a is not None else None


def _path(p: Optional[PathLike]) -> Optional[bytes]:
    return os.fsencode(p) if p is not None else None


# wt_rtc_share counts its plan: shares and closes one at a time (wavetomo/rtc.h, "Threads")
_plan_lock = threading.Lock()


class _Context:
    """A C context (wt_context *), freed when the last object holding it goes: an object's own, and the one
    its plan was built with, which every share of the plan holds (wt_rtc_share: it must outlive them)."""

    handle: Optional[int]

    def __init__(self, threads: Optional[int]) -> None:
        self.handle = _L().wt_context_alloc()
        if not self.handle:
            raise MemoryError("wavetomo: no memory for a context")
        if threads is not None:
            _L().wt_context_set_threads(self.handle, int(threads))

    def __del__(self) -> None:
        h, self.handle = getattr(self, "handle", None), None
        if h and _L is not None:  # (_L is None at interpreter shutdown)
            try:
                _L().wt_context_free(h)
            except Exception:
                pass


class System:
    """The system of a configuration file (or text) with overrides, as the library reads it.

    System("data/presets/demo.cfg", set={"loop.gain": 0.4})
    System(text=open("demo.cfg").read())            # relative paths in the text: against the working directory

    Raises ConfigError (a bad key or value, named), FileError (a missing file), InvalidError.
    """

    _kind = "none"
    nslopes: int                  # the length of a slope vector
    nactuators: int               # the length of a command vector
    _rtc: Optional[int]           # the C instance (wt_rtc *), None once closed
    _ctx: Optional[int]           # its context (wt_context *), _context's handle
    _context: Optional[_Context]
    _plan_context: Optional[_Context]  # the context that built the plan (this object's, or a share's source's)
    _layout: Optional[Layout]
    _dms: Optional[List[DM]]

    def __init__(self, config: Optional[PathLike] = None, *, text: Optional[str] = None, set: Overrides = None,
                 threads: Optional[int] = None) -> None:
        self._open(self._kind, config, text, None, set, threads)

    # -- set-up ---------------------------------------------------------------------------------------
    def _open(self, recon: str, config: Optional[PathLike], text: Optional[str], matrix: Optional[PathLike],
              set: Overrides, threads: Optional[int]) -> None:
        self._rtc = None
        self._context = self._plan_context = _Context(threads)
        self._ctx = self._context.handle
        self._lock = threading.Lock()
        sets = [s.encode() for s in overrides(set)]
        arr = (ctypes.c_char_p * max(len(sets), 1))(*sets)
        out = ctypes.c_void_p()
        if matrix is not None:
            if text is not None:
                raise TypeError("a stored MVM takes its configuration from config= (a file) or from the matrix, not text=")
            st = _L().wt_rtc_open_mvm(self._ctx, _path(matrix), _path(config), len(sets), arr, ctypes.byref(out))
        elif (config is None) == (text is None):
            raise TypeError("give a configuration file (config=) or its text (text=), one of the two")
        elif text is not None:
            st = _L().wt_rtc_open_text(self._ctx, recon.encode(), text.encode(), len(sets), arr, ctypes.byref(out))
        else:
            st = _L().wt_rtc_open(self._ctx, recon.encode(), _path(config), len(sets), arr, ctypes.byref(out))
        if st < 0:
            self._raise(st)
        self._opened(out.value)

    def _opened(self, rtc: int) -> None:
        self._rtc = rtc
        self.nslopes = int(_L().wt_rtc_nslopes(self._rtc))
        self.nactuators = int(_L().wt_rtc_nactuators(self._rtc))
        self._layout = self._dms = None

    def _raise(self, st: int) -> NoReturn:
        msg = _L().wt_error_message(self._ctx).decode(errors="replace") or _L().wt_strerror(st).decode()
        _L().wt_error_clear(self._ctx)
        raise error_for(st, msg)

    def _handle(self) -> int:
        if self._rtc is None:
            raise Error("wavetomo: this %s is closed" % type(self).__name__)
        return self._rtc

    def close(self) -> None:
        """Free the C instance and context (also done when the object is collected); the plan (R) stays while
        a share holds it."""
        rtc = getattr(self, "_rtc", None)
        self._rtc = self._ctx = None
        if rtc and _L is not None:  # (_L is None at interpreter shutdown)
            with _plan_lock:
                _L().wt_rtc_close(rtc)
        self._context = self._plan_context = None  # the contexts go with their last holder

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

    def __enter__(self) -> "System":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        if self._rtc is None:
            return "<wavetomo.%s (closed)>" % type(self).__name__
        return "<wavetomo.%s %s: %d slopes, %d commands>" % (type(self).__name__, self.recon, self.nslopes,
                                                             self.nactuators)

    # -- what the system is ---------------------------------------------------------------------------
    @property
    def recon(self) -> str:
        """"none" for a System; "pcg3", "cg9", "mvm-pcg3" or "mvm-cg9" for a Reconstructor."""
        return _L().wt_rtc_recon(self._handle()).decode()

    @property
    def config(self) -> str:
        """The effective configuration (libconfig text after the overrides, every key given): the
        "config" dataset an output file of this system holds."""
        return _L().wt_rtc_config(self._handle()).decode()

    @property
    def settings(self) -> Dict[str, Any]:
        """The effective configuration as {dotted key: value}: settings["loop.gain"]."""
        return parse(self.config)

    @property
    def nsensors(self) -> int:
        return int(_L().wt_rtc_nsensors(self._handle()))

    @property
    def ndms(self) -> int:
        return int(_L().wt_rtc_ndms(self._handle()))

    @property
    def delay(self) -> int:
        """loop.delay_frames d [frames]"""
        return int(_L().wt_rtc_delay(self._handle()))

    @property
    def gain(self) -> float:
        """loop.gain g of the POLC integrator"""
        return float(_L().wt_rtc_gain(self._handle()))

    @property
    def rate(self) -> float:
        """frame rate [Hz]"""
        return float(_L().wt_rtc_rate(self._handle()))

    @property
    def sensors(self) -> List[Sensor]:
        """[Sensor] in slope order: name, kind, nsub, offset, direction [rad], source altitude [m],
        subaperture centres (nsub, 2) [m]."""
        return self.layout.sensors

    @property
    def dms(self) -> List[DM]:
        """[DM] in command order: altitude [m], pitch [m], nactive, offset, grid nx, ny, x0, y0 [m]."""
        if self._dms is None:
            h, out = self._handle(), []
            for k in range(self.ndms):
                d = _lib.DM_c()
                st = _L().wt_rtc_dm_info(h, k, ctypes.byref(d))
                if st < 0:
                    self._raise(st)
                out.append(DM(d.altitude, d.pitch, d.nactive, d.offset, d.nx, d.ny, d.x0, d.y0))
            self._dms = out
        return list(self._dms)

    @property
    def layout(self) -> Layout:
        """The Layout of slopes and commands (the same as an output file's Result.layout)."""
        if self._layout is None:
            h, sensors = self._handle(), []
            for m in range(self.nsensors):
                info = _lib.Sensor_c()
                st = _L().wt_rtc_sensor_info(h, m, ctypes.byref(info))
                if st < 0:
                    self._raise(st)
                xy = np.empty((info.nsub, 2))
                st = _L().wt_rtc_subapertures(h, m, _ptr(xy))
                if st < 0:
                    self._raise(st)
                sensors.append(Sensor(info.name.decode(), "LGS" if info.kind == _lib.WT_RTC_LGS else "NGS",
                                      info.nsub, info.offset, info.theta_x, info.theta_y, info.altitude, xy))
            pos = np.empty((self.nactuators, 2))
            idx = np.empty((self.nactuators, 3), dtype=np.int32)
            st = _L().wt_rtc_actuators(h, _ptr(pos), _ptr(idx))
            if st < 0:
                self._raise(st)
            self._layout = Layout(sensors, idx, pos)
        return self._layout

    # -- the interaction ------------------------------------------------------------------------------
    def _apply(self, fn: Callable[..., int], x: npt.ArrayLike, nin: int, nout: int) -> np.ndarray:
        x = np.asarray(x)
        if not (np.issubdtype(x.dtype, np.floating) or np.issubdtype(x.dtype, np.integer)):
            raise TypeError("expected real numbers, got dtype %s" % x.dtype)
        if x.ndim not in (1, 2):
            raise ValueError("expected a vector or a 2-D array of rows, got shape %s" % (x.shape,))
        rows = np.ascontiguousarray(np.atleast_2d(x), dtype=np.float64)
        out = np.empty((rows.shape[0], nout))
        h = self._handle()
        with self._lock:
            for r in range(rows.shape[0]):
                st = fn(h, _ptr(rows[r]), rows.shape[1], _ptr(out[r]), nout)
                if st < 0:
                    self._raise(st)
        return out[0] if x.ndim == 1 else out

    def interaction(self, commands: npt.ArrayLike) -> np.ndarray:
        """slopes = Â commands: the slopes [rad] the sensors see of DM commands [m] (the POLC term,
        s_ol = s + Â a). commands: (nactuators,) or (frames, nactuators); float64 out."""
        return self._apply(_L().wt_rtc_interaction, commands, self.nactuators, self.nslopes)

    def interaction_t(self, slopes: npt.ArrayLike) -> np.ndarray:
        """commands = Âᵀ slopes, the transpose. slopes: (nslopes,) or (frames, nslopes); float64 out."""
        return self._apply(_L().wt_rtc_interaction_t, slopes, self.nslopes, self.nactuators)


class Reconstructor(System):
    """A reconstructor applied frame by frame.

    Reconstructor("data/presets/demo.cfg", "pcg3", set={"loop.gain": 0.4})   # or "cg9"
    Reconstructor(text=config_text, recon="cg9")
    Reconstructor(matrix="M.h5")                     # a stored MVM with the configuration it was built with
    Reconstructor("demo.cfg", matrix="M.h5")         # ... checked against this configuration

    a = rec(s) maps one frame's measured slopes s [rad] (nslopes,) to the DM commands a [m] (nactuators,)
    to apply, with POLC inside: s_ol = s + Â a_t, r = R s_ol, a_{t+d} = a_{t+d-1} + g (r - a_t), where a_t
    is `applied` or else the commands this object returned d frames earlier. raw=True returns r (and leaves
    the integrator alone); slopes_ol=True says s is already pseudo-open-loop (s_ol = s). threads: the
    OpenMP threads of pcg3 / cg9 (the MVM uses OpenBLAS's, OPENBLAS_NUM_THREADS).
    """

    def __init__(self, config: Optional[PathLike] = None, recon: Optional[str] = None, *,
                 matrix: Optional[PathLike] = None, text: Optional[str] = None, set: Overrides = None,
                 threads: Optional[int] = None) -> None:
        if matrix is not None:
            if recon not in (None, "mvm"):
                raise TypeError("recon=%r with matrix=: a stored MVM is the reconstructor" % (recon,))
        elif recon is None:
            recon = "pcg3"
        elif recon == "mvm":
            raise TypeError("recon='mvm' needs matrix=MATRIX.h5 (from wavetomo.build)")
        elif recon == "none":
            raise TypeError("recon='none' is the system alone: use wavetomo.System")
        self.last_status = 0
        self._open(recon or "mvm", config, text, matrix, set, threads)

    def share(self, *, threads: Optional[int] = None) -> "Reconstructor":
        """Another loop on this reconstructor's plan: the same system, Â and stored R (not copied: one R in
        memory for several loops), with its own integrator and delay queue (at zero), warm start, frame count,
        context and lock; the two may run frames in parallel threads and be closed in either order. pcg3 and
        cg9 build their own operators on the shared system (wavetomo/rtc.h, wt_rtc_share). threads: the new
        loop's OpenMP threads (default: this one's)."""
        h = self._handle()
        new = type(self).__new__(type(self))
        new._rtc = None
        new.last_status = 0
        new._context = _Context(threads if threads is not None else int(_L().wt_context_threads(self._ctx)))
        new._plan_context = self._plan_context
        new._ctx = new._context.handle
        new._lock = threading.Lock()
        out = ctypes.c_void_p()
        with _plan_lock:
            st = _L().wt_rtc_share(new._ctx, h, ctypes.byref(out))
        if st < 0:
            new._raise(st)
        new._opened(out.value)
        return new

    @property
    def frames(self) -> int:
        """Frames run since open or reset."""
        return int(_L().wt_rtc_frames(self._handle()))

    @property
    def frame_time(self) -> float:
        """Wall time of the last frame call in the library [s] (input checks, conversions, reconstruction)."""
        return float(_L().wt_rtc_frame_time(self._handle()))

    def reset(self) -> None:
        """Forget the history: the integrator, its delay queue, the warm start, the frame count."""
        with self._lock:
            _L().wt_rtc_reset(self._handle())

    def _vector(self, x: npt.ArrayLike, n: int, dtype: Any, what: str) -> np.ndarray:
        x = np.asarray(x)
        if not (np.issubdtype(x.dtype, np.floating) or np.issubdtype(x.dtype, np.integer)):
            raise TypeError("%s: expected real numbers, got dtype %s" % (what, x.dtype))
        if x.ndim != 1:
            raise ValueError("%s: expected a vector of %d values, got shape %s%s" % (
                what, n, x.shape, " (replay() takes frames x values)" if x.ndim == 2 else ""))
        return np.ascontiguousarray(x, dtype=dtype)

    def __call__(self, slopes: npt.ArrayLike, applied: Optional[npt.ArrayLike] = None, *, raw: bool = False,
                 slopes_ol: bool = False, out: Optional[np.ndarray] = None) -> np.ndarray:
        """One frame: the commands [m] of slopes [rad] (see the class). float32 slopes give float32
        commands (the library's float32 entry), others float64. out: a C-contiguous vector of that
        dtype to write into (no allocation per frame). Raises InvalidError (a size other than the
        system's, named), NumericError (NaN or Inf, naming the frame, index, sensor and subaperture);
        warns SolverWarning when an iterative solver stopped early."""
        s0 = np.asarray(slopes)
        dtype = np.float32 if s0.dtype == np.float32 else np.float64
        s = self._vector(s0, self.nslopes, dtype, "slopes")
        a = self._vector(applied, self.nactuators, dtype, "applied") if applied is not None else None
        if out is None:
            out = np.empty(self.nactuators, dtype=dtype)
        elif not (isinstance(out, np.ndarray) and out.dtype == dtype and out.ndim == 1 and out.flags.c_contiguous
                  and out.flags.writeable):
            raise ValueError("out: expected a writeable C-contiguous %s vector" % np.dtype(dtype).name)
        flags = (_lib.WT_RTC_RAW if raw else 0) | (_lib.WT_RTC_SLOPES_OL if slopes_ol else 0)
        fn = _L().wt_rtc_frame_f32 if dtype == np.float32 else _L().wt_rtc_frame
        h = self._handle()
        with self._lock:
            st = fn(h, _ptr(s), s.size, _ptr(a), flags, _ptr(out), out.size)
            if st < 0:
                self._raise(st)
            self.last_status = st
            if st > 0:
                msg = _L().wt_error_message(self._ctx).decode(errors="replace")
                warnings.warn(SolverWarning(msg or _L().wt_strerror(st).decode()), stacklevel=2)
        return out

    def replay(self, slopes: npt.ArrayLike, applied: Optional[npt.ArrayLike] = None, *, raw: bool = False,
               slopes_ol: bool = False) -> np.ndarray:
        """Frames in order: slopes (frames, nslopes) [and applied (frames, nactuators)] -> commands
        (frames, nactuators), each row as one call. `wavetomo run` is replay(tel["slopes_ol"], raw=True,
        slopes_ol=True) for pcg3 / cg9 and replay(tel["slopes"], tel["commands"], raw=True) for the MVM."""
        s = np.asarray(slopes)
        if s.ndim != 2:
            raise ValueError("slopes: expected frames x %d slopes, got shape %s" % (self.nslopes, s.shape))
        a = np.asarray(applied) if applied is not None else None
        if a is not None and (a.ndim != 2 or a.shape[0] != s.shape[0]):
            raise ValueError("applied: expected %d frames x %d commands, got shape %s" % (s.shape[0], self.nactuators,
                                                                                       a.shape))
        dtype = np.float32 if s.dtype == np.float32 else np.float64
        out = np.empty((s.shape[0], self.nactuators), dtype=dtype)
        for t in range(s.shape[0]):
            self(s[t], a[t] if a is not None else None, raw=raw, slopes_ol=slopes_ol, out=out[t])
        return out
