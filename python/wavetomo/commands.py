"""wavetomo/commands.py: sim, compare, budget, build and run from Python.

Each function runs the `wavetomo` executable with the same options as the command line and reads the
files it writes (wavetomo.files), so its numbers are the command line's bit for bit: it is the command
line. Why a subprocess and not more C API: the runs take seconds to hours, beside which starting a
process is nothing; the closed loop, the report and the output writers live in the drivers, above the
library (one code path, no second entry to keep identical); and a separate process keeps
OpenMP and OpenBLAS thread pools, MPI, signals (Ctrl-C makes compare write what it has) and memory out
of the interpreter. A failed run raises CommandError with the command's own error message.

The executable is $WAVETOMO_BIN, else the build tree's bin/wavetomo next to this package, else the
installed prefix's bin/wavetomo, else `wavetomo` on the PATH.
"""
import os
import pathlib
import shutil
import signal
import subprocess
import tempfile
from typing import Any, List, Optional, Sequence, Tuple, Union

from . import files
from .config import Overrides, overrides
from .errors import CommandError, FileError
from .files import PathLike, Result

__all__ = ["executable", "sim", "build", "run", "compare", "budget"]

_HERE = pathlib.Path(__file__).resolve().parent


def executable() -> str:
    """The path of the `wavetomo` executable the runs use."""
    env = os.environ.get("WAVETOMO_BIN")
    if env:
        return env
    # the build tree (python/wavetomo -> bin/), an installed prefix (LIBDIR/pythonX.Y/dist-packages/wavetomo
    # -> PREFIX/bin/)
    up = list(_HERE.parents)
    for c in (up[1] / "bin" / "wavetomo", up[min(3, len(up) - 1)] / "bin" / "wavetomo"):
        if os.access(c, os.X_OK):
            return str(c)
    w = shutil.which("wavetomo")
    if w:
        return w
    raise FileError("wavetomo: the executable is neither in the build tree (bin/wavetomo), nor in the installed "
                    "prefix, nor on the PATH: build it with `make`, or set WAVETOMO_BIN", -4)


def _common(args: List[Any], config: Optional[PathLike], set: Overrides, threads: Optional[int],
            force: bool) -> List[Any]:
    if config is not None:
        args += ["--config", os.fspath(config)]
    for s in overrides(set):
        args += ["--set", s]
    if threads is not None:
        args += ["--threads", str(int(threads))]
    if force:
        args.append("--force")
    return args


def _call(args: List[Any]) -> Tuple[str, str]:
    """Run `wavetomo ARGS`; its stdout (the summary it prints) on success, CommandError otherwise."""
    cmd = [executable()] + [str(a) for a in args]
    # its own session: a Ctrl-C reaches Python only (on a terminal as in Jupyter), which passes the command
    # one SIGINT, lets it stop as it does on the command line (compare writes its files with the cases done)
    # and then raises KeyboardInterrupt; a second Ctrl-C kills it
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, errors="replace",
                         start_new_session=True)
    try:
        out, err = p.communicate()
    except KeyboardInterrupt:
        p.send_signal(signal.SIGINT)
        try:
            p.communicate()
        except KeyboardInterrupt:
            p.kill()
            p.wait()
        raise
    if p.returncode != 0:
        lines = [l for l in err.splitlines() if ": error: " in l]
        msg = "\n".join(lines) if lines else (err.strip().splitlines() or ["exit status %d" % p.returncode])[-1]
        raise CommandError(msg, p.returncode, err, cmd)
    return out, err


def _methods(recon: Union[str, Sequence[str]]) -> str:
    return recon if isinstance(recon, str) else ",".join(recon)


class _Out:
    """An output path: the caller's, or one in a temporary directory removed after reading."""

    def __init__(self, path: Optional[PathLike], name: str) -> None:
        self.tmp = tempfile.TemporaryDirectory(prefix="wavetomo-") if path is None else None
        self.path = os.path.join(self.tmp.name, name) if self.tmp else os.fspath(path)

    def done(self) -> None:
        if self.tmp:
            self.tmp.cleanup()


def sim(config: PathLike, recon: str = "pcg3", *, set: Overrides = None, frames: Optional[int] = None,
        seed: Optional[int] = None, iters: Optional[int] = None, noise: bool = True, matrix: Optional[PathLike] = None,
        out: Optional[PathLike] = None, telemetry: Union[PathLike, bool, None] = None, dump_screens: bool = False,
        threads: Optional[int] = None, force: bool = False) -> Result:
    """`wavetomo sim`: the closed loop of one reconstructor ("pcg3", "cg9", "none", or "mvm" with
    matrix=). Returns read_run(RUN.h5) (out=None: a temporary file, removed), with .stdout (the summary)
    and .telemetry = read_telemetry(TEL.h5) when telemetry= is a path or True (True: temporary)."""
    o = _Out(out, "run.h5")
    t = _Out(None if isinstance(telemetry, bool) else telemetry, "tel.h5") if telemetry else None
    try:
        args = _common(["sim"], config, set, threads, force) + ["--recon", recon, "--out", o.path]
        if matrix is not None:
            args += ["--matrix", os.fspath(matrix)]
        if frames is not None:
            args += ["--frames", int(frames)]
        if seed is not None:
            args += ["--seed", int(seed)]
        if iters is not None:
            args += ["--iters", int(iters)]
        if not noise:
            args.append("--no-noise")
        if t:
            args += ["--telemetry", t.path]
        if dump_screens:
            args.append("--dump-screens")
        stdout, stderr = _call(args)
        res = files.read_run(o.path)
        res.telemetry = files.read_telemetry(t.path) if t else None
        res.stdout, res.stderr = stdout, stderr
        return res
    finally:
        o.done()
        if t:
            t.done()


def build(config: PathLike, out: PathLike, *, recon: str = "pcg3", set: Overrides = None,
          memory: Union[str, float, None] = None, threads: Optional[int] = None, force: bool = False) -> pathlib.Path:
    """`wavetomo build`: the MVM control matrix of the configuration into `out` (MATRIX.h5). Returns the
    path (give it to Reconstructor(matrix=...), or read it with read_matrix)."""
    args = _common(["build"], config, set, threads, force) + ["--recon", recon, "--out", os.fspath(out)]
    if memory is not None:
        args += ["--memory", memory]
    _call(args)
    return pathlib.Path(out)


def run(telemetry: PathLike, *, recon: Optional[str] = None, matrix: Optional[PathLike] = None,
        config: Optional[PathLike] = None, iters: Optional[int] = None, out: Optional[PathLike] = None,
        set: Overrides = None, threads: Optional[int] = None, force: bool = False) -> Result:
    """`wavetomo run`: a telemetry file replayed through pcg3 / cg9 (recon=) or a stored MVM (matrix=).
    Returns read_commands(CMDS.h5) (out=None: temporary): "reconstruction" (frames, nactuators) = R s_ol."""
    o = _Out(out, "cmds.h5")
    try:
        args = _common(["run"], config, set, threads, force) + ["--telemetry", os.fspath(telemetry), "--out", o.path]
        if recon is not None:
            args += ["--recon", recon]
        if matrix is not None:
            args += ["--matrix", os.fspath(matrix)]
        if iters is not None:
            args += ["--iters", int(iters)]
        stdout, stderr = _call(args)
        res = files.read_commands(o.path)
        res.stdout, res.stderr = stdout, stderr
        return res
    finally:
        o.done()


def _sweep(sweep: Union[str, Tuple[str, Sequence[Any]], None]) -> Optional[str]:
    if sweep is None or isinstance(sweep, str):
        return sweep
    key, values = sweep
    return "%s=%s" % (key, ",".join(overrides({key: v})[0].split("=", 1)[1] for v in values))


def compare(config: PathLike, recon: Union[str, Sequence[str]] = ("mvm", "pcg3", "cg9"), *,
            out: Optional[PathLike] = None, sweep: Union[str, Tuple[str, Sequence[Any]], None] = None,
            seeds: Optional[int] = None, frames: Optional[int] = None, seed: Optional[int] = None,
            resume: bool = False, set: Overrides = None, threads: Optional[int] = None, force: bool = False) -> Result:
    """`wavetomo compare`: the closed loop of each method (and each sweep value, and seed) on the same
    turbulence and noise. recon: "mvm,pcg3" or a list; sweep: ("lgs.wfs.photons", [50, 100]) or
    "lgs.wfs.photons=50,100"; seeds: N seeds from sim.seed. Returns read_compare(DIR/results.h5) with
    .dir (the report, summary.csv and figures; None when out=None: a temporary directory, removed)."""
    o = _Out(out, "compare")
    try:
        args = _common(["compare"], config, set, threads, force) + ["--recon", _methods(recon), "--out", o.path]
        if sweep is not None:
            args += ["--sweep", _sweep(sweep)]
        if seeds is not None:
            args += ["--seeds", int(seeds)]
        if frames is not None:
            args += ["--frames", int(frames)]
        if seed is not None:
            args += ["--seed", int(seed)]
        if resume:
            args.append("--resume")
        stdout, stderr = _call(args)
        res = files.read_compare(os.path.join(o.path, "results.h5"))
        res.dir = None if o.tmp else o.path
        res.stdout, res.stderr = stdout, stderr
        return res
    finally:
        o.done()


def budget(config: PathLike, recon: Union[str, Sequence[str]] = ("cg9",), *, out: Optional[PathLike] = None,
           frames: Optional[int] = None, seed: Optional[int] = None, set: Overrides = None,
           threads: Optional[int] = None, force: bool = False) -> Result:
    """`wavetomo budget`: the error budget of each method ("cg9", "pcg3", "mvm"). Returns
    read_budget(DIR/results.h5): "<method>/<term>" [nm] with the analytic estimates in .meta, .dir as
    compare's."""
    o = _Out(out, "budget")
    try:
        args = _common(["budget"], config, set, threads, force) + ["--recon", _methods(recon), "--out", o.path]
        if frames is not None:
            args += ["--frames", int(frames)]
        if seed is not None:
            args += ["--seed", int(seed)]
        stdout, stderr = _call(args)
        res = files.read_budget(os.path.join(o.path, "results.h5"))
        res.dir = None if o.tmp else o.path
        res.stdout, res.stderr = stdout, stderr
        return res
    finally:
        o.done()
