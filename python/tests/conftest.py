"""python/tests/conftest.py: the files the Python tests compare against, made once per session by the
command line itself (`wavetomo sim/build/run` on the demo preset; the executable wavetomo.executable()
finds: $WAVETOMO_BIN under make test). tests/test_python.sh runs this suite for make test, with the package
pip-installed into a virtual environment.

The suite tests this checkout's build: without $WAVETOMO_LIB and $WAVETOMO_BIN it sets them to build/ and bin/
here, so that a package installed elsewhere (a venv's site-packages, which finds no library beside itself)
runs against them too."""
import os
import pathlib
import subprocess

import pytest

import wavetomo
from wavetomo import _lib

REPO = pathlib.Path(__file__).resolve().parents[2]
for var, path in (("WAVETOMO_LIB", REPO / "build" / _lib.SONAME), ("WAVETOMO_BIN", REPO / "bin" / "wavetomo")):
    if not os.environ.get(var) and path.exists():
        os.environ[var] = str(path)
DEMO = str(REPO / "data" / "presets" / "demo.cfg")
FRAMES = 8
SEED = 3


def cli(*args):
    """Run `wavetomo ARGS --threads 1 --quiet`; fail the test with its stderr when it fails."""
    cmd = [wavetomo.executable()] + [str(a) for a in args] + ["--threads", "1", "--quiet"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    assert p.returncode == 0, "%s failed:\n%s" % (" ".join(cmd), p.stderr)
    return p


@pytest.fixture(scope="session")
def files(tmp_path_factory):
    """The demo's closed loops (pcg3, and the MVM), their telemetry, the matrix, and `wavetomo run`'s
    reconstructions: pcg3 and cg9 of the pcg3 telemetry, the MVM of the MVM telemetry."""
    d = tmp_path_factory.mktemp("cli")
    f = {k: str(d / v) for k, v in dict(run="r.h5", tel="tel.h5", matrix="M.h5", run_mvm="rm.h5", tel_mvm="tel-mvm.h5",
                                        cmds_pcg3="c-pcg3.h5", cmds_cg9="c-cg9.h5", cmds_mvm="c-mvm.h5").items()}
    c = ["--config", DEMO, "--frames", FRAMES, "--seed", SEED]
    cli("sim", *c, "--recon", "pcg3", "--out", f["run"], "--telemetry", f["tel"])
    cli("build", "--config", DEMO, "--out", f["matrix"])
    cli("sim", *c, "--recon", "mvm", "--matrix", f["matrix"], "--out", f["run_mvm"], "--telemetry", f["tel_mvm"])
    cli("run", "--recon", "pcg3", "--telemetry", f["tel"], "--out", f["cmds_pcg3"])
    cli("run", "--recon", "cg9", "--telemetry", f["tel"], "--out", f["cmds_cg9"])
    cli("run", "--matrix", f["matrix"], "--telemetry", f["tel_mvm"], "--out", f["cmds_mvm"])
    f["dir"] = str(d)
    return f
