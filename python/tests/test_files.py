"""python/tests/test_files.py: the readers of every output file (docs/formats.md): the kind found from the
datasets, strings and scalars as Python values, the matrices as the MVM applies them, and refusals of
incomplete, foreign and wrong-kind files naming what is wrong."""
import shutil

import h5py
import numpy as np
import pytest

import wavetomo
from conftest import DEMO, FRAMES, cli


def test_kinds_and_values(files):
    kinds = {"run": "run", "tel": "telemetry", "matrix": "matrix", "cmds_pcg3": "commands"}
    for key, kind in kinds.items():
        r = wavetomo.read(files[key])
        assert r.kind == kind and r.attrs["wavetomo_version"] == wavetomo.version() and r.attrs["complete"] == 1
        assert isinstance(r.config, str) and r.config.startswith("telescope")
        assert r.layout is not None and r.layout.nactuators == 759
    run = wavetomo.read_run(files["run"])
    assert isinstance(run["strehl_le_field"], float) and isinstance(run["frames"], int) and run["frames"] == FRAMES
    assert run.group("eval")["strehl_le"] is run["eval/strehl_le"] and run.units("eval/wfe_le") == "nm"
    assert run["frame/rms"].shape == (FRAMES, 25) and run.meta["frame/time"]["columns"].startswith("atmosphere")
    # the field summaries are the per-direction values' mean and rms (docs/formats.md)
    assert run["strehl_le_field"] == pytest.approx(run["eval/strehl_le"].mean(), rel=1e-12)
    assert run["wfe_le_field"] == pytest.approx(np.sqrt((run["eval/wfe_le"] ** 2).mean()), rel=1e-12)
    tel = wavetomo.read_telemetry(files["tel"])
    assert tel["slopes"].dtype == np.float32 and tel["slopes"].shape == (FRAMES, 1548)
    assert tel["commands"].shape == (FRAMES, 759)
    cmds = wavetomo.read_commands(files["cmds_pcg3"])
    assert cmds["reconstruction"].shape == (FRAMES, 759) and cmds["time"].shape == (FRAMES,)


def test_matrix(files):
    """The MVM the reader gives (R, R Â as float32) is the one `wavetomo run` applies: R s + (R Â) a
    equals its output within 1e-5 of the norm (float32 GEMVs of ~2300 terms summed in another order)."""
    m = wavetomo.read_matrix(files["matrix"])
    assert isinstance(m, wavetomo.MatrixResult) and m.attrs["precision"] == "fp32" and m.attrs["variant"] == "pcg3"
    tel = wavetomo.read_telemetry(files["tel_mvm"])
    ref = wavetomo.read_commands(files["cmds_mvm"])["reconstruction"]
    for t in range(FRAMES):
        r = m.R @ tel["slopes"][t] + m.RA @ tel["commands"][t]
        assert np.linalg.norm(r - ref[t]) <= 1e-5 * np.linalg.norm(ref[t])


def test_matrix_half(files, tmp_path):
    """A 16-bit matrix (fp16, one power-of-two scale per row) reads back as the float32 matrix it rounds:
    within 2^-11 of each row's largest entry (half precision's 11-bit significand), where a missing row
    scale is off by orders of magnitude; and its Reconstructor agrees with R @ s to 1e-5."""
    p = wavetomo.build(DEMO, tmp_path / "Mh.h5", set={"recon.mvm_precision": "fp16"}, threads=1)
    h, f = wavetomo.read_matrix(p), wavetomo.read_matrix(files["matrix"])
    assert h.attrs["precision"] == "fp16" and h["R"].dtype == np.float16
    err = np.abs(h.R - f.R).max(axis=1) / np.abs(f.R).max(axis=1)
    assert err.max() <= 2.0 ** -11
    s = wavetomo.read_telemetry(files["tel"])["slopes_ol"][0]
    rec = wavetomo.Reconstructor(matrix=p)
    r = rec(s, raw=True, slopes_ol=True)
    assert np.linalg.norm(r - h.R @ s) <= 1e-5 * np.linalg.norm(r)


def test_strings_for_plain_h5py(files, tmp_path):
    """Strings are variable-length UTF-8: h5py alone gives attributes as str and string datasets through
    .asstr() (docs/python.md). A file of an earlier wavetomo (fixed-length strings, which h5py gives as bytes)
    still reads with str values through the package."""
    with h5py.File(files["run"], "r") as f:
        assert f.attrs["recon"] == "pcg3" and isinstance(f.attrs["wavetomo_version"], str)
        assert f["eval/wfe_le"].attrs["units"] == "nm" and isinstance(f["eval/wfe_le"].attrs["description"], str)
        assert h5py.check_string_dtype(f["config"].dtype).encoding == "utf-8"
        assert f["config"].asstr()[()].startswith("telescope")
    with h5py.File(files["matrix"], "r") as f:
        assert f.attrs["precision"] == "fp32" and f.attrs["variant"] == "pcg3"
    old = tmp_path / "old.h5"
    shutil.copy(files["run"], old)
    with h5py.File(old, "r+") as f:
        text = f["config"].asstr()[()]
        del f["config"]
        f["config"] = np.bytes_(text.encode())
        f.attrs["recon"] = np.bytes_(b"pcg3")
        f["eval/wfe_le"].attrs["units"] = np.bytes_(b"nm")
    with h5py.File(old, "r") as f:
        assert f.attrs["recon"] == b"pcg3" and f["config"].dtype.kind == "S"
    r = wavetomo.read_run(old)
    assert r.attrs["recon"] == "pcg3" and r.units("eval/wfe_le") == "nm" and r.config == text

def test_refusals(files, tmp_path):
    """Missing, not HDF5, incomplete (an interrupted run's), and of another kind: each named."""
    with pytest.raises(wavetomo.FileError):
        wavetomo.read(tmp_path / "none.h5")
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    with pytest.raises(wavetomo.FormatError, match="not an HDF5 file"):
        wavetomo.read(junk)
    cut = tmp_path / "cut.h5"
    shutil.copy(files["run"], cut)
    with h5py.File(cut, "r+") as f:
        del f.attrs["complete"]
    with pytest.raises(wavetomo.FormatError, match="incomplete"):
        wavetomo.read_run(cut)
    with pytest.raises(wavetomo.FormatError) as e:
        wavetomo.read_run(files["tel"])
    assert "is not a RUN.h5" in str(e.value) and "no strehl_le_field" in str(e.value)
    with pytest.raises(wavetomo.FormatError, match="is not a MATRIX.h5"):
        wavetomo.read_matrix(files["cmds_mvm"])
    with pytest.raises(wavetomo.FormatError, match="results.h5 of wavetomo compare"):
        wavetomo.read_compare(files["run"])


def test_psf(files, tmp_path):
    """The long-exposure PSFs of a run (sim.psf_interval_frames, docs/formats.md): an image per direction, its peak is the
    PSF-peak Strehl, below the diffraction-limited 1; compare's per method, per seed, with the per-frame WFE."""
    run = wavetomo.read_run(files["run"])
    p = run.psf()
    n = p["image"].shape[-1]
    assert p["image"].dtype == np.float32 and p["image"].shape == (25, n, n)
    assert p["pixel_lambda_over_d"] <= 0.5 and p["wavelength_nm"] == 2200.0 and p["frames"] >= 1
    assert p["pixel_mas"] == pytest.approx(p["pixel_lambda_over_d"] * 2.2e-6 / 8.0 * 206264806.2, rel=1e-9)
    # the peak in double, the image in float32: the same value rounded once
    assert np.array_equal(p["strehl_peak"].astype(np.float32), p["image"].reshape(25, -1).max(axis=1))
    assert np.all((p["strehl_peak"] > 0) & (p["strehl_peak"] <= 1))
    off = wavetomo.sim(DEMO, "pcg3", frames=4, seed=2, set={"sim.psf_interval_frames": 0}, threads=1)
    assert off.psf() is None and "psf/image" not in off
    # bands (sim.psf_wavelengths_nm): the evaluation wavelength's band is psf/ itself; θ_p ∝ λ at one N
    b = wavetomo.sim(DEMO, "pcg3", frames=6, seed=2, threads=1,
                     set={"evaluation.settle_frames": 2, "sim.psf_interval_frames": 2,
                          "sim.psf_wavelengths_nm": [1650.0, 2200.0]})
    j, k = b.psf(wavelength_nm=1650.0), b.psf(wavelength_nm=2200)
    assert np.array_equal(k["image"], b.psf()["image"]) and k["pixel_mas"] == b.psf()["pixel_mas"]
    assert j["pixel_mas"] == pytest.approx(k["pixel_mas"] * 1650 / 2200, rel=1e-12)
    assert np.all(j["strehl_peak"] < k["strehl_peak"])
    with pytest.raises(ValueError, match="bands are"):
        b.psf(wavelength_nm=1250.0)
    with pytest.raises(ValueError, match="no PSF bands"):
        run.psf(wavelength_nm=2200.0)
    d = tmp_path / "cmp"
    cli("compare", "--config", DEMO, "--recon", "pcg3,none", "--frames", FRAMES, "--out", d)
    c = wavetomo.read_compare(d)
    q = c.psf("pcg3")
    assert q["image"].shape == (1, 25, n, n) and q["strehl_peak"].shape == (1, 25)
    assert np.allclose(c["strehl_psf"][0, 0], q["strehl_peak"][0])
    assert c["series/wfe_field"].shape == (2, 1, 1, FRAMES) and c.units("series/wfe_field") == "nm"
    with pytest.raises(ValueError):
        c.psf("cg9")
