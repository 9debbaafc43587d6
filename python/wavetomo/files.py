"""wavetomo/files.py: readers of every file wavetomo writes (docs/formats.md), with h5py.

A file is read whole into a Result: a dict {dataset path: value} keyed as docs/formats.md names the
datasets ("strehl_le_field", "eval/strehl_le", "layout/LGS1/subaperture_centre"), arrays as numpy arrays
in the file's type, scalars as Python numbers, strings as str; with the root attributes in .attrs and every
dataset's or group's attributes (units, description, ...) in .meta[path]. Like the library's own readers,
these refuse a file that is not complete (no root attribute complete = 1: written by a run that was
stopped) and a file of another kind, with FormatError naming what is missing.
"""
import os
from typing import Any, Dict, List, Optional, Union

import numpy as np

from .errors import FileError, FormatError
from .layout import ARCSEC, Layout, Sensor

__all__ = ["Result", "MatrixResult", "read", "read_run", "read_telemetry", "read_matrix", "read_commands",
           "read_compare", "read_budget"]

PathLike = Union[str, "os.PathLike[str]"]

# What identifies each kind of file: required datasets (and root attributes)
_KINDS = {
    "run": (["strehl_le_field", "strehl_le_on_axis", "wfe_le_field", "eval/strehl_le", "frame/rms"], []),
    "telemetry": (["slopes", "slopes_ol", "commands"], []),
    "matrix": (["R", "RA", "matrix_config"], ["config_sha256", "variant"]),
    "commands": (["reconstruction", "time"], []),
    "compare": (["strehl_le", "wfe_le", "strehl_le_field", "done"], ["methods", "sweep_key"]),
    "budget": ([], ["methods"]),
}
_NAMES = {"run": "RUN.h5 (wavetomo sim --out)", "telemetry": "TEL.h5 (wavetomo sim --telemetry)",
          "matrix": "MATRIX.h5 (wavetomo build)", "commands": "CMDS.h5 (wavetomo run)",
          "compare": "results.h5 of wavetomo compare", "budget": "results.h5 of wavetomo budget"}


def _attr(v):
    if isinstance(v, bytes):
        return v.decode("utf-8", errors="replace")
    if isinstance(v, np.ndarray) and v.dtype.kind == "S":
        return [x.decode("utf-8", errors="replace") for x in v.ravel()]
    if isinstance(v, np.generic):
        return v.item()
    return v


def _dataset(d):
    if d.dtype.kind in ("S", "O", "U"):
        v = d[()]
        return v.decode("utf-8", errors="replace") if isinstance(v, bytes) else v
    v = d[()]
    return v.item() if d.shape == () else v


class Result(dict):
    """A wavetomo output file in memory (see the module). path: the file; kind: "run", "telemetry",
    "matrix", "commands", "compare" or "budget"; attrs: the root attributes (strings as str); meta[path]:
    the attributes of a dataset or group."""

    # set by the runs (wavetomo.sim, compare, budget, run) on the Result they return
    stdout: str
    stderr: str
    telemetry: Optional["Result"]
    dir: Optional[str]

    def __init__(self, path: str, kind: str) -> None:
        super().__init__()
        self.path = path
        self.kind = kind
        self.attrs: Dict[str, Any] = {}
        self.meta: Dict[str, Dict[str, Any]] = {}

    def __repr__(self) -> str:
        return "<wavetomo.Result %s %s: %d datasets>" % (self.kind, self.path, len(self))

    def group(self, prefix: str) -> Dict[str, Any]:
        """The datasets under prefix/ as a dict, keyed by the rest of their path: group("eval")["strehl_le"]."""
        p = prefix.rstrip("/") + "/"
        return {k[len(p):]: v for k, v in self.items() if k.startswith(p)}

    def units(self, name: str) -> str:
        """The units of dataset `name` ("" when dimensionless)."""
        return self.meta.get(name, {}).get("units", "")

    @property
    def config(self) -> Optional[str]:
        """The effective configuration text of the run (the "config" dataset)."""
        return self.get("config")

    @property
    def methods(self) -> List[str]:
        """compare / budget: the methods in their order ([M] of the (M, ...) datasets)."""
        m = self.attrs.get("methods", "")
        return [x for x in m.split(",") if x]

    @property
    def layout(self) -> Optional[Layout]:
        """The Layout of the file's "layout" group (None when the file has none, as compare's results)."""
        if "layout/sensor_slope_offset" not in self:
            return None
        names = self.meta.get("layout", {}).get("sensors", "").split(",")
        off, cnt = self["layout/sensor_slope_offset"], self["layout/sensor_slope_count"]
        sensors = []
        for m, name in enumerate(names):
            g = self.meta.get("layout/" + name, {})
            sensors.append(Sensor(name, name[:3], int(cnt[m]) // 2, int(off[m]), g.get("theta_x_arcsec", 0.0) * ARCSEC,
                                  g.get("theta_y_arcsec", 0.0) * ARCSEC, g.get("source_altitude_m", 0.0),
                                  self["layout/%s/subaperture_centre" % name]))
        return Layout(sensors, self["layout/actuator_index"], self["layout/actuator_position"])

    def psf(self, method: Optional[str] = None, value: int = 0,
            wavelength_nm: Optional[float] = None) -> Optional[Dict[str, Any]]:
        """The long-exposure PSFs (sim.psf_interval_frames > 0; None without them) as a dict: "image" (directions, n, n)
        for a run file, (seeds, directions, n, n) for compare's method `method` at sweep value index `value`;
        "strehl_peak" (the PSF-peak Strehl, [seeds,] directions); "theta_x", "theta_y" [arcsec] of the
        directions; and the image attributes: "pixel_lambda_over_d", "pixel_mas", "wavelength_nm", "frames",
        "every", "fft_size". Pixel (ix, iy) of an n x n image is at ((ix - n/2), (iy - n/2)) pixels, x right,
        y up; normalised so that the diffraction-limited PSF peaks at 1 (docs/formats.md). wavelength_nm: a run's
        band of sim.psf_wavelengths_nm (psf/wavelengths/), the same dict at that wavelength."""
        if wavelength_nm is not None:
            if self.kind == "compare" or "psf/wavelengths/wavelength_nm" not in self:
                raise ValueError("wavelength_nm=%r: the file has no PSF bands (sim.psf_wavelengths_nm)" % wavelength_nm)
            bands = [float(x) for x in self["psf/wavelengths/wavelength_nm"]]
            if float(wavelength_nm) not in bands:
                raise ValueError("wavelength_nm=%r: the file's bands are %s nm" % (wavelength_nm, bands))
            k = bands.index(float(wavelength_nm))
            m = self.meta.get("psf/wavelengths/image", {})
            out = {key: m.get(key) for key in ("pixel_lambda_over_d", "frames", "every", "fft_size")}
            out.update(wavelength_nm=bands[k], pixel_mas=float(self["psf/wavelengths/pixel_mas"][k]),
                       image=self["psf/wavelengths/image"][k], strehl_peak=self["psf/wavelengths/strehl_peak"][k],
                       theta_x=self["eval/theta_x"], theta_y=self["eval/theta_y"])
            return out
        if self.kind == "compare":
            if method not in self.methods:
                raise ValueError("method %r: the file has %s" % (method, ", ".join(self.methods)))
            group = "psf/%s_%d" % (method, value)
        else:
            group = "psf"
        if group + "/image" not in self:
            return None
        m = self.meta.get(group + "/image", {})
        out = {k: m.get(k) for k in ("pixel_lambda_over_d", "pixel_mas", "wavelength_nm", "frames", "every",
                                      "fft_size")}
        out.update(image=self[group + "/image"], strehl_peak=self[group + "/strehl_peak"],
                   theta_x=self["eval/theta_x"], theta_y=self["eval/theta_y"])
        return out


class MatrixResult(Result):
    """MATRIX.h5: R and RA as stored (float32, or float16 / bfloat16 scaled per row: attrs["precision"]),
    and the matrices they stand for as float32: .R (commands [m] = R @ slopes [rad]) and .RA (R Â)."""

    def _scaled(self, name):
        x = np.asarray(self[name], dtype=np.float32)
        scale = self.get(name + "_row_scale")
        return x * np.asarray(scale, dtype=np.float32)[:, None] if scale is not None else x

    @property
    def R(self) -> np.ndarray:
        return self._scaled("R")

    @property
    def RA(self) -> np.ndarray:
        return self._scaled("RA")


def _kind_of(keys, attrs):
    for kind, (ds, at) in _KINDS.items():
        if kind == "budget":
            continue
        if all(d in keys for d in ds) and all(a in attrs for a in at):
            return kind
    methods = attrs.get("methods")
    if methods and any(k.startswith(m + "/") for m in methods.split(",") for k in keys):
        return "budget"
    return None


def read(path: PathLike, kind: Optional[str] = None) -> Result:
    """Read a wavetomo output file whole. kind: None (found from the datasets) or the kind it must be
    ("run", "telemetry", "matrix", "commands", "compare", "budget"). Raises FileError (missing),
    FormatError (not HDF5, incomplete, or not a file of that kind, naming what is missing)."""
    import h5py

    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileError("%s: no such file" % path, -4)
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise FormatError("%s: not an HDF5 file (%s)" % (path, e), -7)
    with f:
        attrs = {k: _attr(v) for k, v in f.attrs.items()}
        if attrs.get("complete") != 1:
            raise FormatError("%s: incomplete file (no root attribute complete = 1): written by a run that stopped "
                              "before the end, or not by wavetomo" % path, -7)
        data: Dict[str, Any] = {}
        meta: Dict[str, Dict[str, Any]] = {}

        def visit(name: str, obj: Any) -> None:
            m = {k: _attr(v) for k, v in obj.attrs.items()}
            if m:
                meta[name] = m
            if not hasattr(obj, "keys"):  # a dataset
                data[name] = _dataset(obj)

        f.visititems(visit)
    found = _kind_of(data, attrs)
    if kind is not None:
        if kind not in _KINDS:
            raise ValueError("kind %r: expected one of %s" % (kind, ", ".join(_KINDS)))
        if found != kind:
            ds, at = _KINDS[kind]
            missing = [d for d in ds if d not in data] + ["root attribute " + a for a in at if a not in attrs]
            raise FormatError("%s is not a %s: %s" % (
                path, _NAMES[kind], ("no " + ", no ".join(missing)) if missing else "it is a %s" % _NAMES.get(found)), -7)
    if found is None:
        raise FormatError("%s: not a wavetomo output file of a known kind" % path, -7)
    res = (MatrixResult if found == "matrix" else Result)(path, found)
    res.update(data)
    res.attrs, res.meta = attrs, meta
    return res


def read_run(path: PathLike) -> Result:
    """RUN.h5 of `wavetomo sim --out`: LE Strehl and WFE per direction and over the field, per-frame
    Strehl and rms, timings, layout."""
    return read(path, "run")


def read_telemetry(path: PathLike) -> Result:
    """TEL.h5 of `wavetomo sim --telemetry`: slopes, slopes_ol (frames, nslopes) and commands
    (frames, nactuators), float32."""
    return read(path, "telemetry")


def read_matrix(path: PathLike) -> MatrixResult:
    """MATRIX.h5 of `wavetomo build`: a MatrixResult (.R, .RA as float32 matrices)."""
    res = read(path, "matrix")
    assert isinstance(res, MatrixResult)  # read() makes one of every matrix file
    return res


def read_commands(path: PathLike) -> Result:
    """CMDS.h5 of `wavetomo run`: reconstruction (frames, nactuators) float32 = R s_ol, time (frames,) [ms]."""
    return read(path, "commands")


def read_compare(path: PathLike) -> Result:
    """results.h5 of `wavetomo compare` (a directory is taken as DIR/results.h5): (M methods, V sweep
    values[, seeds][, directions]) arrays; .methods."""
    path = os.fspath(path)
    return read(os.path.join(path, "results.h5") if os.path.isdir(path) else path, "compare")


def read_budget(path: PathLike) -> Result:
    """results.h5 of `wavetomo budget` (a directory is taken as DIR/results.h5): "<method>/<term>" [nm],
    analytic estimates in .meta["<method>/<term>"]; .methods."""
    path = os.fspath(path)
    return read(os.path.join(path, "results.h5") if os.path.isdir(path) else path, "budget")
