"""python/tests/test_commands.py: wavetomo.sim / compare / budget / build / run return what the command
line writes (every dataset bit for bit, the timings aside), their options reach the command, and a failed
run raises with the command's own message."""
import numpy as np
import pytest

import wavetomo
from conftest import DEMO, FRAMES, SEED, cli

# wall times differ from run to run; everything else is deterministic (docs/formats.md)
TIMES = ("timing/", "frame/time", "time", "setup_time", "time_per_frame", "time_parts", "seeds/setup_time",
         "seeds/time_per_frame", "seeds/time_parts", "seeds/time_psf", "build/time")
PROVENANCE = ("created_utc", "command_line")


def same_file(a, b):
    """Every dataset and attribute of two Results equal (bit for bit), but wall times and provenance."""
    keys = {k for k in a if not k.startswith(TIMES)}
    assert keys == {k for k in b if not k.startswith(TIMES)}
    for k in sorted(keys):
        x, y = a[k], b[k]
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), k
        else:
            assert x == y, k
    assert {k: v for k, v in a.attrs.items() if k not in PROVENANCE} == \
        {k: v for k, v in b.attrs.items() if k not in PROVENANCE}
    meta = lambda r: {k: {n: v for n, v in m.items() if n not in ("seconds",)} for k, m in r.meta.items()}
    assert meta(a) == meta(b)


def test_sim_is_the_command_line(files):
    """wavetomo.sim (with telemetry) equals `wavetomo sim` with the same options: the result file and the
    telemetry; the MVM's too."""
    res = wavetomo.sim(DEMO, "pcg3", frames=FRAMES, seed=SEED, telemetry=True, threads=1)
    assert res.kind == "run" and res.attrs["recon"] == "pcg3" and "LE Strehl" in res.stdout
    same_file(res, wavetomo.read_run(files["run"]))
    same_file(res.telemetry, wavetomo.read_telemetry(files["tel"]))
    assert res["frames"] == FRAMES and res["eval/strehl_le"].shape == (25,)
    assert 0.0 < res["strehl_le_field"] < 1.0 and res.units("wfe_le_field") == "nm"
    m = wavetomo.sim(DEMO, "mvm", matrix=files["matrix"], frames=FRAMES, seed=SEED, threads=1)
    same_file(m, wavetomo.read_run(files["run_mvm"]))


def test_sim_options(tmp_path):
    """The options reach the command: the configuration it ran (set=, noise=False, frames, seed), the
    reconstructor, the files kept where asked."""
    out, tel = tmp_path / "r.h5", tmp_path / "t.h5"
    res = wavetomo.sim(DEMO, "cg9", frames=3, seed=11, noise=False, set={"loop.gain": 0.3}, out=out, telemetry=tel,
                       threads=1)
    cfg = wavetomo.parse_config(res.config)
    assert (cfg["sim.noise"], cfg["loop.gain"], cfg["loop.frames"], cfg["sim.seed"]) == (False, 0.3, 3, 11)
    assert res.attrs["recon"] == "cg9" and res.attrs["seed"] == 11 and res["frames"] == 3
    assert out.exists() and tel.exists() and res.telemetry["slopes"].shape[0] == 3
    assert res.path == str(out)


def test_build_and_run(files, tmp_path):
    """wavetomo.build makes the command line's matrix (bit for bit), and wavetomo.run its replay."""
    m = wavetomo.build(DEMO, tmp_path / "M.h5", threads=1)
    mine, ref = wavetomo.read_matrix(m), wavetomo.read_matrix(files["matrix"])
    same_file(mine, ref)
    c = wavetomo.run(files["tel"], recon="pcg3", threads=1)
    same_file(c, wavetomo.read_commands(files["cmds_pcg3"]))
    c = wavetomo.run(files["tel_mvm"], matrix=m, threads=1)
    assert np.array_equal(c["reconstruction"], wavetomo.read_commands(files["cmds_mvm"])["reconstruction"])


def test_compare(tmp_path):
    """wavetomo.compare: (method, sweep value, direction) arrays in the order asked, the report kept in
    .dir; each case is the closed loop `wavetomo sim` runs with that value and seed, bit for bit."""
    res = wavetomo.compare(DEMO, ["pcg3", "cg9"], sweep=("lgs.wfs.photons", [50, 100]), frames=6, seed=SEED,
                           out=tmp_path / "cmp", threads=1)
    assert res.kind == "compare" and res.methods == ["pcg3", "cg9"]
    assert res.attrs["sweep_key"] == "lgs.wfs.photons" and res["strehl_le"].shape == (2, 2, 25)
    assert np.all(res["done"] == 1) and (tmp_path / "cmp" / "report.md").exists() and res.dir == str(tmp_path / "cmp")
    one = wavetomo.sim(DEMO, "cg9", frames=6, seed=SEED, set={"lgs.wfs.photons": 100}, threads=1)
    assert np.array_equal(res["strehl_le"][1, 1], one["eval/strehl_le"])
    assert np.array_equal(res["wfe_le"][1, 1], one["eval/wfe_le"])
    cli_out = tmp_path / "cli"
    cli("compare", "--config", DEMO, "--recon", "pcg3,cg9", "--sweep", "lgs.wfs.photons=50,100", "--frames", 6,
        "--seed", SEED, "--out", cli_out)
    same_file(res, wavetomo.read_compare(cli_out))


def test_compare_seeds():
    """--seeds: the per-seed arrays, their means and standard errors, and the paired differences."""
    res = wavetomo.compare(DEMO, "pcg3,cg9", seeds=2, frames=4, threads=1)
    assert res.dir is None and res.attrs["seeds"] == "%d,%d" % (1, 2)
    per = res["seeds/wfe_le_field"]
    assert per.shape == (2, 1, 2)
    assert np.allclose(res["wfe_le_field"], per.mean(axis=2), rtol=1e-12)
    d = res["difference/wfe_le_field"]
    assert res.meta["difference"]["pairs"] == "pcg3-cg9"
    assert np.allclose(d[0, 0], (per[0, 0] - per[1, 0]).mean(), rtol=1e-12)


def test_budget(tmp_path):
    """wavetomo.budget: the terms [nm] of each method and the runs they come from, as the command line
    writes them; the terms are the runs' quadrature differences (docs/guide.md, error budget)."""
    res = wavetomo.budget(DEMO, "pcg3", frames=6, out=tmp_path / "b", threads=1)
    cli("budget", "--config", DEMO, "--recon", "pcg3", "--frames", 6, "--out", tmp_path / "c")
    same_file(res, wavetomo.read_budget(tmp_path / "c"))
    assert res.methods == ["pcg3"]
    b = res.group("pcg3")
    assert b["fitting"] == b["runs/fitting"] and b["total"] == b["runs/closed_loop"]
    assert b["tomography"] == pytest.approx(np.sqrt(b["runs/open_loop_noise_free"] ** 2 - b["runs/fitting"] ** 2),
                                            rel=1e-12)
    assert b["noise_cl"] == pytest.approx(np.sqrt(abs(b["runs/closed_loop"] ** 2 - b["runs/closed_loop_noise_free"] ** 2)),
                                          rel=1e-12)
    assert res.meta["pcg3/fitting"]["analytic_nm"] > 0 and res.units("pcg3/total") == "nm"
    assert res.meta["pcg3/runs/closed_loop"]["frames"] > 0


def test_command_errors(files, tmp_path):
    """A refused run raises CommandError with the command's error message and exit status."""
    with pytest.raises(wavetomo.CommandError) as e:
        wavetomo.sim(DEMO, "pcg3", set={"loop.gain": 1.5})
    assert e.value.returncode == 1 and "wavetomo sim: error:" in str(e.value) and "loop.gain" in str(e.value)
    with pytest.raises(wavetomo.CommandError) as e:
        wavetomo.sim(DEMO, "pcg4")
    assert e.value.returncode == 2 and "--recon expects" in str(e.value)
    with pytest.raises(wavetomo.CommandError) as e:
        wavetomo.run(files["tel"], matrix=files["matrix"], set={"recon.alpha": 3.0}, config=DEMO)
    assert "wavetomo run: error:" in str(e.value)
    with pytest.raises(wavetomo.CommandError) as e:
        wavetomo.sim("/nonexistent/demo.cfg")
    assert "/nonexistent/demo.cfg" in str(e.value)
