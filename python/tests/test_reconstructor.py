"""python/tests/test_reconstructor.py: wavetomo.Reconstructor and System over libwavetomo.so. The
reconstructor's commands are `wavetomo run`'s bit for bit (pcg3, cg9, the MVM; float32 and float64 frames),
its POLC is the closed loop's, it is the composition of the raw reconstruction, Â and the integrator, reset
forgets, instances run in parallel threads, shares of one plan are independent loops, the geometry is the files' layout group, and bad input raises
with the library's message."""
import re
import threading

import numpy as np
import pytest

import wavetomo
from conftest import DEMO, REPO, cli


def open_case(files, case):
    """pcg3 / cg9 on the pcg3 loop's configuration (its telemetry's text); the MVM from its matrix file."""
    if case == "mvm":
        return wavetomo.Reconstructor(matrix=files["matrix"])
    return wavetomo.Reconstructor(text=wavetomo.read_telemetry(files["tel"]).config, recon=case)


def test_version_and_library():
    h = (REPO / "include" / "wavetomo" / "version.h").read_text()
    v = ".".join(re.search(r"#define WT_VERSION_%s (\d+)" % p, h).group(1) for p in ("MAJOR", "MINOR", "PATCH"))
    assert wavetomo.version() == v == wavetomo.__version__
    assert "libwavetomo.so" in wavetomo.library_path()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("case", ["pcg3", "cg9", "mvm"])
def test_equals_run(files, case, dtype):
    """`wavetomo run` is replay in raw mode: pcg3 / cg9 on s_ol, the MVM on s with the applied commands
    (R s + (R Â) a). float32 frames give its float32 output bit for bit; float64 frames too once rounded
    (a float converts to double and back unchanged, the reconstructors compute in double either way)."""
    tel = wavetomo.read_telemetry(files["tel_mvm" if case == "mvm" else "tel"])
    ref = wavetomo.read_commands(files["cmds_" + case])["reconstruction"]
    rec = open_case(files, case)
    assert rec.recon == ("mvm-pcg3" if case == "mvm" else case)
    if case == "mvm":
        out = rec.replay(tel["slopes"].astype(dtype), tel["commands"].astype(dtype), raw=True)
    else:
        out = rec.replay(tel["slopes_ol"].astype(dtype), raw=True, slopes_ol=True)
    assert out.dtype == dtype and out.shape == ref.shape
    assert rec.frames == len(ref)
    assert np.array_equal(out.astype(np.float32), ref), "max |difference| %g" % np.abs(out - ref).max()
    assert np.abs(ref).max() > 0.0
    assert rec.frame_time > 0.0


def test_polc_is_the_closed_loop(files):
    """POLC inside: fed the closed loop's measured slopes, pcg3 returns the commands that loop applied d
    frames later. The telemetry holds the slopes in float32 (the loop used them in double): within 1e-5 of
    the commands' norm (the rounding is 6e-8 relative and the measured difference 4e-8), where a missing
    POLC term, a wrong delay or gain, or another reconstructor is an O(1) difference (cg9 replaying the
    pcg3 loop: 0.7)."""
    tel = wavetomo.read_telemetry(files["tel"])
    s, applied = tel["slopes"], tel["commands"]

    def worst(rec):
        d = rec.delay
        out = rec.replay(s)
        return max(np.linalg.norm(out[t - d] - applied[t]) / np.linalg.norm(applied[t]) for t in range(d, len(s)))

    rec = open_case(files, "pcg3")
    assert rec.delay >= 1 and 0 < rec.gain <= 1
    assert worst(rec) <= 1e-5
    assert worst(open_case(files, "cg9")) > 0.1


@pytest.mark.parametrize("case", ["pcg3", "mvm"])
def test_polc_is_its_parts(files, case):
    """A POLC frame is, bit for bit, the raw reconstruction of s + Â a_t (pcg3; the MVM's R s + (R Â) a_t)
    followed by the integrator a_{t+d} = a_{t+d-1} + g (r - a_t) on the commands returned d frames
    earlier: the delay queue, the gain and the POLC term, checked in numpy (float64, both sides)."""
    s = wavetomo.read_telemetry(files["tel"])["slopes"].astype(np.float64)
    polc, raw = open_case(files, case), open_case(files, case)
    d, g = polc.delay, polc.gain
    queue = [np.zeros(polc.nactuators)] * d  # a_t for t < d: zero
    last = np.zeros(polc.nactuators)
    for t in range(len(s)):
        a_t = queue[t]
        if case == "mvm":
            r = raw(s[t], a_t, raw=True)
        else:
            r = raw(s[t] + polc.interaction(a_t), raw=True, slopes_ol=True)
        last = last + g * (r - a_t)
        queue.append(last)
        mine = polc(s[t])
        assert np.array_equal(mine, last), "frame %d" % t
    assert np.abs(last).max() > 0.0


def test_raw_and_applied(files):
    """A raw frame leaves the integrator alone (the MVM, which has no other state: POLC, RAW, POLC gives the
    second frame of POLC, POLC), and applied= replaces the instance's own a_t: the zeros it holds at frame 1
    (d = 2) change nothing, other commands do."""
    s = wavetomo.read_telemetry(files["tel_mvm"])["slopes"]
    a, b = open_case(files, "mvm"), open_case(files, "mvm")
    assert a.delay == 2
    a(s[0]), b(s[0])
    a(s[1], raw=True)
    assert np.array_equal(a(s[1]), b(s[1]))
    s = wavetomo.read_telemetry(files["tel"])["slopes"]
    c, e = open_case(files, "pcg3"), open_case(files, "pcg3")
    c(s[0]), e(s[0])
    zero = np.zeros(c.nactuators, np.float32)
    assert np.array_equal(c(s[1], applied=zero), e(s[1]))
    c.reset(), e.reset()
    c(s[0]), e(s[0])
    assert not np.array_equal(c(s[1], applied=zero + 1e-7), e(s[1]))


def test_reset(files):
    """reset() forgets the integrator, its queue and the warm start: the replay after it is the first
    replay bit for bit, while continuing without it is not."""
    s = wavetomo.read_telemetry(files["tel"])["slopes"]
    rec = open_case(files, "pcg3")
    first = rec.replay(s)
    assert rec.frames == len(s)
    cont = rec.replay(s)
    rec.reset()
    assert rec.frames == 0
    again = rec.replay(s)
    assert np.array_equal(first, again)
    assert not np.array_equal(first, cont)


def test_out_buffer(files):
    """out= receives the commands (no allocation per frame) and must have the frame's dtype."""
    s = wavetomo.read_telemetry(files["tel"])["slopes"][0]
    rec = open_case(files, "pcg3")
    buf = np.empty(rec.nactuators, np.float32)
    assert rec(s, raw=True, out=buf) is buf
    assert np.array_equal(buf, open_case(files, "pcg3")(s, raw=True))
    with pytest.raises(ValueError, match="out"):
        rec(s, out=np.empty(rec.nactuators))  # float64 buffer for a float32 frame


def test_threads(files):
    """Two instances run frames at the same time from two Python threads (ctypes releases the GIL) and
    give what each gives alone."""
    s = wavetomo.read_telemetry(files["tel"])["slopes_ol"]
    alone = {c: open_case(files, c).replay(s, raw=True, slopes_ol=True) for c in ("pcg3", "cg9")}
    recs = {c: open_case(files, c) for c in alone}
    got = {}

    def work(c):
        got[c] = recs[c].replay(s, raw=True, slopes_ol=True)

    th = [threading.Thread(target=work, args=(c,)) for c in recs]
    [t.start() for t in th]
    [t.join() for t in th]
    for c in alone:
        assert np.array_equal(got[c], alone[c])


@pytest.mark.parametrize("case", ["pcg3", "mvm"])
def test_share(files, case):
    """share(): another loop on the same plan. The original and its share fed different slopes give the
    commands of two objects opened independently (their own integrators and warm starts), in two threads at
    once too; the original closed first leaves the share running (its plan and the context that built it are
    held)."""
    tel = wavetomo.read_telemetry(files["tel"])
    s1, s2 = tel["slopes"].astype(np.float64), tel["slopes"][::-1].astype(np.float64)
    ref1, ref2 = open_case(files, case).replay(s1), open_case(files, case).replay(s2)
    rec = open_case(files, case)
    sh = rec.share()
    assert isinstance(sh, wavetomo.Reconstructor) and sh.recon == rec.recon and sh.config == rec.config
    assert sh.frames == 0 and sh.nslopes == rec.nslopes
    got = {}
    th = [threading.Thread(target=lambda r=r, s=s, k=k: got.__setitem__(k, r.replay(s)))
          for k, (r, s) in enumerate(((rec, s1), (sh, s2)))]
    [t.start() for t in th]
    [t.join() for t in th]
    assert np.array_equal(got[0], ref1) and np.array_equal(got[1], ref2)
    rec.close()
    sh.reset()
    assert np.array_equal(sh.replay(s2), ref2)
    with pytest.raises(wavetomo.Error, match="closed"):
        rec.share()


def test_interaction(files):
    """Â: the telemetry's pseudo-open-loop slopes are its slopes plus Â of its commands (float32 files:
    within 1e-6 of the norm of Â a, the commands' rounding being 6e-8); the transpose satisfies
    <Â a, s> = <a, Âᵀ s> to 1e-12 (sums of ~10^3 products); rows of a 2-D input are frames; the same
    operator from a System, a pcg3 and an MVM instance."""
    tel = wavetomo.read_telemetry(files["tel"])
    rec = open_case(files, "pcg3")
    t = len(tel["slopes"]) - 1
    polc = rec.interaction(tel["commands"][t])
    diff = tel["slopes_ol"][t].astype(np.float64) - tel["slopes"][t] - polc
    assert np.linalg.norm(polc) > 0.0
    assert np.linalg.norm(diff) <= 1e-6 * np.linalg.norm(polc)
    rng = np.random.default_rng(5)
    a, s = rng.standard_normal(rec.nactuators) * 1e-7, rng.standard_normal(rec.nslopes) * 1e-6
    y, at = rec.interaction(a), rec.interaction_t(s)
    assert abs(y @ s - a @ at) <= 1e-12 * np.linalg.norm(y) * np.linalg.norm(s)
    both = rec.interaction(np.stack([a, 2 * a]))
    assert both.shape == (2, rec.nslopes) and np.array_equal(both[0], y) and np.array_equal(both[1], 2 * y)
    assert np.array_equal(wavetomo.System(text=tel.config).interaction(a), y)
    assert np.array_equal(open_case(files, "mvm").interaction(a), y)


def test_geometry_is_the_layout(files):
    """Sizes, sensors, subaperture centres, actuator positions and indices from the library equal every
    output file's layout group (run, telemetry, matrix, commands) exactly; directions to the rounding of
    the files' arcseconds; the DMs' blocks tile the command vector; the sensors' blocks the slope vector."""
    sysm = wavetomo.System(DEMO)
    mine = sysm.layout
    assert sysm.recon == "none" and mine.nslopes == sysm.nslopes and mine.nactuators == sysm.nactuators
    for key in ("run", "tel", "matrix", "cmds_pcg3"):
        f = wavetomo.read(files[key])
        lay = f.layout
        assert [s.name for s in lay.sensors] == [s.name for s in mine.sensors]
        for a, b in zip(mine.sensors, lay.sensors):
            assert (a.kind, a.nsub, a.offset, a.altitude) == (b.kind, b.nsub, b.offset, b.altitude)
            assert np.array_equal(a.subapertures, b.subapertures)
            g = f.meta["layout/" + a.name]  # the file's arcseconds: the library's radians / WT_ARCSEC
            assert (a.theta_x / wavetomo.ARCSEC, a.theta_y / wavetomo.ARCSEC) == (g["theta_x_arcsec"], g["theta_y_arcsec"])
        assert np.array_equal(mine.actuator_index, lay.actuator_index)
        assert np.array_equal(mine.actuator_position, lay.actuator_position)
    f = wavetomo.read_run(files["run"])
    assert np.array_equal([s.offset for s in mine.sensors], f["layout/sensor_slope_offset"])
    assert np.array_equal([s.nslopes for s in mine.sensors], f["layout/sensor_slope_count"])
    assert [s.kind for s in mine.sensors] == sorted(s.kind for s in mine.sensors)  # the LGS first
    dms = sysm.dms
    assert len(dms) == sysm.ndms and [d.offset for d in dms] == list(np.cumsum([0] + [d.nactive for d in dms])[:-1])
    assert sum(d.nactive for d in dms) == sysm.nactuators
    for k, d in enumerate(dms):
        on = mine.actuator_index[:, 0] == k
        assert on.sum() == d.nactive and np.all(np.flatnonzero(on) == np.arange(d.offset, d.offset + d.nactive))
        assert np.array_equal(mine.actuator_position[on, 0], d.x0 + mine.actuator_index[on, 1] * d.pitch)
    sx, sy = mine.sensor("LGS1").split(np.arange(sysm.nslopes))
    assert sx[0] == 0 and sy[0] == mine.sensors[0].nsub


def test_configuration(files, tmp_path):
    """Overrides from a dict reach the library in libconfig syntax: the effective configuration text is
    the command line's with the same --set (bit for bit), and reads back as the values given."""
    sets = {"loop.gain": 0.4, "loop.frames": 4, "evaluation.settle_frames": 2, "sim.seed": 9, "sim.noise": False,
            "dm.pitch_m": [0.5, 1, 1], "lgs.wfs.centroider": "cog"}
    sysm = wavetomo.System(DEMO, set=sets)
    st = sysm.settings
    assert st["loop.gain"] == 0.4 == sysm.gain and st["sim.seed"] == 9 and st["sim.noise"] is False
    assert st["dm.pitch_m"] == [0.5, 1.0, 1.0] and st["lgs.wfs.centroider"] == "cog"
    out = tmp_path / "r.h5"
    cli("sim", "--config", DEMO, *sum((["--set", s] for s in wavetomo.overrides(sets)), []), "--out", out)
    assert wavetomo.read_run(out).config == sysm.config
    assert wavetomo.System(text=sysm.config).config == sysm.config


def has(exc, text):
    assert text in str(exc.value), str(exc.value)


def test_bad_input(files):
    """Refusals carry the library's own message (frame, index, sensor, subaperture; sizes; key; file) and
    change nothing: a refused frame does not count."""
    rec = open_case(files, "pcg3")
    s = np.zeros(rec.nslopes)
    s[17] = np.nan
    with pytest.raises(wavetomo.NumericError) as e:
        rec(s)
    has(e, "frame 0: slope 17 (LGS1 s_x of valid subaperture 17) is NaN")
    assert e.value.status == -6 and rec.frames == 0
    s[17] = 0.0
    a = np.zeros(rec.nactuators, np.float32)
    a[3] = np.inf
    with pytest.raises(wavetomo.NumericError) as e:
        rec(s.astype(np.float32), a)
    has(e, "applied command 3 (DM 1 active actuator 3) is Inf")
    with pytest.raises(wavetomo.InvalidError) as e:
        rec(np.zeros(5))
    has(e, "frame 0: 5 slopes and %d commands given, the system" % rec.nactuators)
    has(e, "has %d slopes" % rec.nslopes)
    assert isinstance(e.value, ValueError)
    with pytest.raises(wavetomo.InvalidError) as e:
        rec.interaction(np.zeros(3))
    has(e, "wt_rtc_interaction: 3 values in")
    with pytest.raises(ValueError, match="replay"):
        rec(np.zeros((2, rec.nslopes)))
    with pytest.raises(TypeError):
        rec(np.zeros(rec.nslopes, complex))
    assert rec.frames == 0
    with pytest.raises(wavetomo.ConfigError) as e:
        wavetomo.Reconstructor(DEMO, "pcg3", set={"loop.gain": 1.5})
    has(e, "loop.gain")
    has(e, "out of range")
    with pytest.raises(wavetomo.ConfigError) as e:
        wavetomo.System(DEMO, set=["loop.no_such_key=1"])
    has(e, "no_such_key")
    with pytest.raises(wavetomo.ConfigError) as e:
        wavetomo.System(text="telescope = { diameter_m = ")
    has(e, "(configuration text)")
    with pytest.raises(wavetomo.FileError) as e:
        wavetomo.System("/nonexistent/demo.cfg")
    has(e, "/nonexistent/demo.cfg")
    assert isinstance(e.value, OSError)
    with pytest.raises(wavetomo.InvalidError) as e:
        wavetomo.Reconstructor(DEMO, "pcg4")
    has(e, "'pcg4'")
    with pytest.raises(wavetomo.FormatError) as e:
        wavetomo.Reconstructor(matrix=files["matrix"], set={"recon.alpha": 3.0})
    has(e, "built for another system")
    g = wavetomo.Reconstructor(matrix=files["matrix"], set={"loop.gain": 0.3})  # the loop's keys are not the matrix's
    assert g.gain == 0.3
    with pytest.raises(wavetomo.Error) as e:
        wavetomo.Reconstructor(matrix=files["tel"])
    has(e, "tel.h5")
    rec.close()
    with pytest.raises(wavetomo.Error, match="closed"):
        rec(np.zeros(10))
