"""The Python module against the CLI: same numbers bit for bit, same errors, real files and processes.

Run by ctest (Python.Module) with PYTHONPATH at the build tree's python/ and BISTABLE_CLI, BISTABLE_COORDINATOR,
BISTABLE_WORKER, BISTABLE_SOURCE pointing at the built programs and the source tree.
"""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time

import h5py
import numpy as np
import pytest

import bistable

CLI = os.environ["BISTABLE_CLI"]
SOURCE = os.environ["BISTABLE_SOURCE"]


def cli_json(*args):
    r = subprocess.run([CLI, *args, "--json"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


SMALL = {
    "name": "python module test",
    "model": "coupled",
    "params": {"eta": 0.1},
    "axes": {"alpha": {"linspace": [0.2, 2.0, 5]}, "omega": {"linspace": [0.5, 1.5, 4]}},
    "integration": {"t_end": 200.0, "t_keep": 100.0},
}


@pytest.mark.parametrize(
    "kw,flags",
    [
        (dict(model="coupled", alpha=1.0, omega=1.2), ["--model", "coupled", "--alpha", "1", "--omega", "1.2"]),
        (dict(model="standalone", alpha=0.3, omega=0.9, eta=0.05), ["--model", "standalone", "--alpha", "0.3", "--omega", "0.9", "--eta", "0.05"]),
        (dict(model="linear-coupled", alpha=0.5, omega=1.0), None),
        (dict(model="coupled", alpha=2.0, omega=0.7, integrator="adaptive", t_end=120.0, t_keep=60.0, ic=(0.5, 0.0, 0.5, 0.0)),
         ["--model", "coupled", "--alpha", "2", "--omega", "0.7", "--integrator", "adaptive", "--t-end", "120", "--t-keep", "60", "--ic", "0.5,0,0.5,0"]),
    ],
)
def test_point_is_the_cli_point_bit_for_bit(kw, flags):
    kw = {k: v for k, v in kw.items() if v is not None}
    if flags is None:
        flags = ["--model", kw["model"], "--alpha", repr(kw["alpha"]), "--omega", repr(kw["omega"])]
    assert bistable.point(**kw) == cli_json("point", *flags)


def test_point_spectrum_is_the_cli_spectrum():
    r = bistable.point(model="coupled", alpha=1.0, omega=1.0, t_end=1000.0, spectrum=True)
    assert r == cli_json("point", "--model", "coupled", "--alpha", "1", "--omega", "1", "--t-end", "1000", "--spectrum")
    assert len(r["lyapunov_spectrum"]) == 4 and abs(r["lyapunov_spectrum"][0] - r["lle"]) <= 1e-9
    with pytest.raises(ValueError, match="spectrum"):
        bistable.point(alpha=1.0, omega=1.0, spectrum="yes")


def test_nan_is_none_as_the_cli_prints_null():
    r = bistable.point(model="coupled", alpha=1.0, omega=1.2, rosenstein=False)
    assert r["lle_rosenstein"] is None
    assert r == cli_json("point", "--model", "coupled", "--alpha", "1", "--omega", "1.2", "--no-rosenstein")


def test_trajectory_gives_the_window_and_the_same_metrics():
    t = bistable.trajectory(model="coupled", alpha=1.0, omega=1.2, t_end=300.0, t_keep=200.0, sample_every=10)
    tau = t["tau"]
    assert tau.ndim == 1 and len(tau) > 900
    assert tau[0] >= 200.0 - 1e-9 and tau[-1] <= 300.0 + 1e-9 and np.all(np.diff(tau) > 0)
    for k in ("y_m", "dy_m", "y_r", "dy_r"):
        assert t[k].shape == tau.shape and np.isfinite(t[k]).all()
    same = bistable.point(model="coupled", alpha=1.0, omega=1.2, t_end=300.0, t_keep=200.0, sample_every=10)
    assert t["metrics"] == same
    assert abs(t["y_m"].max() - same["y_max"]) < 0.05 * (same["y_max"] - same["y_min"])


@pytest.mark.parametrize(
    "kw,expect",
    [
        (dict(alpha=-1.0, omega=1.0), "alpha = -1 violates alpha > 0"),
        (dict(alpha=1.0, omega=1.0, etta=0.1), "did you mean 'eta'"),
        (dict(alpha=1.0, omega=1.0, model="bistable"), "model"),
        (dict(alpha="1", omega=1.0), "alpha"),
        (dict(alpha=1.0, omega=float("nan")), "omega"),
        (dict(alpha=1.0), "omega is required"),
        (dict(alpha=1.0, omega=1.0, t_keep=600.0), "t_keep"),
        (dict(alpha=1.0, omega=1.0, ic=(1, 2, 3)), "ic"),
        (dict(alpha=1.0, omega=1.0, ic=5), "ic"),
    ],
)
def test_bad_point_arguments_raise_value_error_naming_the_field(kw, expect):
    with pytest.raises(ValueError, match=expect.replace("(", r"\(")):
        bistable.point(**kw)


def cli_args(kw):
    """point()'s keywords as `bistable point` flags (bools: flags; poincare=True: --poincare -)."""
    args = []
    for k, v in kw.items():
        if k == "poincare":
            args += ["--poincare", "-"] if v else []
        elif k == "rosenstein":
            args += [] if v else ["--no-rosenstein"]
        else:
            args += ["--" + k.replace("_", "-"), v if isinstance(v, str) else repr(v)]
    return args


@pytest.mark.parametrize(
    "kw",
    [
        # The chaotic Duffing point of the CLI's section test, a window of N periods at a phase.
        dict(model="standalone", alpha=0.3472222222222222, omega=1.2, eta=0.3, rosenstein=False, poincare=True,
             poincare_periods=300, poincare_phase=0.5),
        # Coupled: six columns (the resonator's too), the whole window's section.
        dict(model="coupled", alpha=0.3, omega=0.8, rosenstein=False, poincare=True, poincare_phase=1.5),
        dict(model="coupled", alpha=1.0, omega=1.2, rosenstein=False, poincare=True, poincare_periods=200, poincare_phase=4.0),
    ],
)
def test_poincare_section_is_the_cli_section(kw):
    mine = bistable.point(**kw)
    theirs = cli_json("point", *cli_args(kw))
    sec, cli_sec = mine.pop("poincare"), theirs.pop("poincare")
    assert mine == theirs  # the metrics, computed over the same window
    for k in ("phase", "count", "k0", "columns", "units"):
        assert sec[k] == cli_sec[k], k
    resonator = kw["model"] == "coupled"
    assert sec["columns"] == ["k", "tau", "y_m", "dy_m"] + (["y_r", "dy_r"] if resonator else [])
    assert sec["units"][:4] == ["", "1/omega_n", "delta_s", "delta_s/tau"]
    n = sec["count"]
    assert n > 20 and (n == kw["poincare_periods"] if "poincare_periods" in kw else True)
    assert sec["k"].dtype == np.int64 and all(sec[c].shape == (n,) for c in sec["columns"])
    rows = np.column_stack([sec[c] for c in sec["columns"]])
    assert np.array_equal(rows, np.array(cli_sec["points"], dtype=float))  # bit for bit
    assert np.array_equal(sec["k"], sec["k0"] + np.arange(n))
    # The strobe times are at the phase: tau_k = (phase + 2 pi k)/Omega.
    assert np.allclose(sec["tau"], (kw["poincare_phase"] + 2 * np.pi * sec["k"]) / kw["omega"], rtol=1e-12)


def test_poincare_periods_without_poincare_still_gives_the_section():
    r = bistable.point(model="standalone", alpha=0.3, omega=1.2, poincare_periods=40)
    assert r["poincare"]["count"] == 40 and len(r["poincare"]["y_m"]) == 40
    assert "poincare" not in bistable.point(model="standalone", alpha=0.3, omega=1.2, poincare_phase=1.0)
    t = bistable.trajectory(model="standalone", alpha=0.3, omega=1.2, poincare_periods=40)
    assert t["metrics"] == {k: v for k, v in r.items() if k != "poincare"}


@pytest.mark.parametrize(
    "kw,expect",
    [
        (dict(poincare_phase=6.3), "poincare_phase = 6.3 violates poincare_phase in [0, 2 pi)"),
        (dict(poincare_phase=-1.0), "poincare_phase = -1 violates poincare_phase in [0, 2 pi)"),
        (dict(poincare_phase=float("nan")), "poincare_phase = nan violates poincare_phase finite"),
        (dict(poincare_phase="0"), "poincare_phase = '0' violates poincare_phase a number"),
        (dict(poincare_periods=0), "poincare_periods = 0 violates poincare_periods in [1, 100000]"),
        (dict(poincare_periods=-3), "poincare_periods = -3 violates poincare_periods in [1, 100000]"),
        (dict(poincare_periods=100001), "poincare_periods = 100001 violates poincare_periods in [1, 100000]"),
        (dict(poincare_periods=10**30), "poincare_periods = 10{30} violates poincare_periods in [1, 100000]"),
        (dict(poincare_periods=2.5), "poincare_periods = 2.5 violates poincare_periods an integer"),
        (dict(poincare_periods=True), "poincare_periods = True violates poincare_periods an integer"),
        (dict(poincare_periods=10, t_end=600.0), "t_end excludes poincare_periods"),
        (dict(omega=0.01, poincare_periods=100000), "poincare_periods = 100000 violates poincare_periods <= 1590"),
        (dict(poincare="yes"), "poincare = 'yes' violates poincare True or False"),
    ],
)
def test_bad_poincare_arguments_raise_value_error_naming_the_field(kw, expect):
    args = dict(model="standalone", alpha=0.3, omega=1.2)
    args.update(kw)
    with pytest.raises(ValueError, match=re.escape(expect.replace("10{30}", "1" + "0" * 30))):
        bistable.point(**args)


def test_an_integer_beyond_long_long_raises_value_error_naming_the_field():
    for name in ("renorm_every", "sample_every"):
        with pytest.raises(ValueError, match=re.escape("%s = %d violates |%s| <= 2^30" % (name, -(10**30), name))):
            bistable.point(alpha=1.0, omega=1.0, **{name: -(10**30)})
    with pytest.raises(ValueError, match=re.escape("harmonics = %d violates |harmonics| <= 2^30" % 10**30)):
        bistable.hbm(harmonics=10**30)


def test_error_messages_show_hostile_values_bounded():
    with pytest.raises(ValueError, match=re.escape("poincare_periods = an integer of about 5001 digits violates poincare_periods in [1, 100000]")):
        bistable.point(model="standalone", alpha=0.3, omega=1.2, poincare_periods=10**5000)
    with pytest.raises(ValueError, match=re.escape("harmonics = an integer of about 5001 digits violates |harmonics| <= 2^30")):
        bistable.hbm(harmonics=10**5000)
    with pytest.raises(ValueError) as e:
        bistable.point(alpha="x" * 10**7, omega=1.0)
    assert len(str(e.value)) < 400 and "(10000000 characters)" in str(e.value) and "alpha = 'xxx" in str(e.value)
    with pytest.raises(ValueError) as e:  # a model name is cut in the message (it was echoed whole: 10 MB)
        bistable.point(model="m" * 10**7, alpha=0.3, omega=1.2)
    assert len(str(e.value)) < 400 and "violates model in {standalone" in str(e.value)
    with pytest.raises(ValueError, match=re.escape("t_keep = 9.3e+18 violates t_keep <=")):
        bistable.point(model="standalone", alpha=0.3, omega=1.2, t_keep=9.3e18, dt=1.0, poincare_periods=10)


def test_identify_takes_any_file_name_and_refuses_what_is_not_a_path(tmp_path):
    with pytest.raises(ValueError, match=re.escape("violates data a path")):
        bistable.identify([3], terms="main.linear")
    name = os.path.join(os.fsencode(str(tmp_path)), b"bad\xff.csv")
    with open(name, "w") as f:
        f.write("t,x0,x\n" + "".join("%g,%g,%g\n" % (i * 0.01, 0.001 * np.sin(i * 0.3), 0.0012 * np.sin(i * 0.3 - 0.2)) for i in range(200)))
    r = bistable.identify(name, terms="main.linear,main.viscous", known={"m_main": 1}, max_added=0, global_evals=0, horizon=0)
    assert r["records"][0]["name"].startswith("bad") and "\ufffd" in r["records"][0]["name"]


def test_numpy_scalars_are_numbers_and_integers_but_numpy_bools_are_not():
    # numpy.float64 is a float; numpy.float32 and numpy.int64 are not, but users pass them (np.arange, np.linspace).
    a = bistable.hbm(param="omega", start=0.4, stop=1.6, alpha=0.3, harmonics=5)
    b = bistable.hbm(param="omega", start=np.float32(0.4), stop=np.int64(2) * 0.8, alpha=np.float64(0.3), harmonics=np.int64(5))
    assert b["settings"]["start"] == float(np.float32(0.4)) and b["settings"]["harmonics"] == 5
    assert np.array_equal(b["branches"][0]["amplitude"][:3], bistable.hbm(param="omega", start=float(np.float32(0.4)), stop=1.6,
                                                                           alpha=0.3, harmonics=5)["branches"][0]["amplitude"][:3])
    assert len(a["branches"]) == len(b["branches"])
    p = bistable.point(model="standalone", alpha=np.float32(0.5), omega=1.0, renorm_every=np.int16(10), poincare=True,
                       poincare_periods=np.uint8(4))
    assert p["poincare"]["count"] == 4
    with pytest.raises(ValueError, match=re.escape("harmonics = np.True_ violates harmonics an integer")
                       if np.__version__ >= "2" else "harmonics = True violates harmonics an integer"):
        bistable.hbm(alpha=0.3, harmonics=np.bool_(True))
    with pytest.raises(ValueError, match="alpha = .* violates alpha a number"):
        bistable.hbm(alpha=np.bool_(False))
    with pytest.raises(ValueError, match="alpha = .* violates alpha a number"):
        bistable.hbm(alpha=1 + 2j)
    with pytest.raises(ValueError, match=re.escape("harmonics = %d violates |harmonics| <= 2^30" % 2**40)):
        bistable.hbm(alpha=0.3, harmonics=np.int64(2**40))
    with pytest.raises(ValueError, match=re.escape("alpha = %d violates alpha finite" % 10**400)):
        bistable.hbm(alpha=10**400)
    with pytest.raises(ValueError, match="harmonics = 5.0 violates harmonics an integer"):
        bistable.hbm(alpha=0.3, harmonics=np.float64(5.0))


def test_run_gives_the_cli_map_and_open_finds_it(tmp_path):
    ds = bistable.run(SMALL, data=tmp_path / "py")
    assert ds.frf_db.dims == ("alpha", "omega") and ds.frf_db.shape == (5, 4)
    assert float(ds.eta) == 0.1 and ds.attrs["Conventions"] == "CF-1.10"
    # The same spec through the CLI, in another data directory: the same numbers, bit for bit.
    spec = tmp_path / "small.toml"
    spec.write_text(bistable._toml_dump(SMALL))
    out = cli_json("run", str(spec), "--data", str(tmp_path / "cli"), "--no-plots", "--quiet")
    assert out["id"] == ds.attrs["sweep_id"]
    with h5py.File(tmp_path / "cli" / "sweeps" / (out["id"] + ".h5")) as f:
        for name in ("frf_db", "lle", "motion", "edr_t", "hd_index"):
            assert np.array_equal(f[name][()], ds[name].values, equal_nan=True), name
    again = bistable.open(out["id"][:5], data=tmp_path / "py")
    assert again.frf_db.equals(ds.frf_db)
    assert bistable.run(SMALL, data=tmp_path / "py", path_only=True).endswith(out["id"] + ".h5")
    with pytest.raises(ValueError, match="no sweep 'ffffffffffff'"):
        bistable.open("ffffffffffff", data=tmp_path / "py")


def test_run_threads_out_of_range_raise_value_error_naming_the_bound(tmp_path):
    # issue 39: 2**63 raised TypeError (the C++ int overflowed before the range check)
    for threads in (2**63, -1, 1025):
        with pytest.raises(ValueError, match=f"threads = {threads} violates threads in \\[0, 1024\\]"):
            bistable.run(SMALL, data=tmp_path / "d", threads=threads)


def test_run_takes_paths_and_toml_text_and_refuses_bad_specs(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(bistable._toml_dump(SMALL))
    a = bistable.run(spec, data=tmp_path / "d", path_only=True)
    b = bistable.run(spec.read_text(), data=tmp_path / "d", path_only=True)
    assert a == b
    bad = dict(SMALL, axes={"alpha": {"linspace": [0.2, 2.0, -5]}})
    with pytest.raises(ValueError, match=r"axes\.alpha\.linspace\.count"):
        bistable.run(bad, data=tmp_path / "d")
    with pytest.raises(ValueError, match="threads"):
        bistable.run(SMALL, data=tmp_path / "d", threads=-2)


def test_hbm_branches_are_the_cli_branches():
    h = bistable.hbm(model="standalone", param="omega", start=0.4, stop=1.6, alpha=0.3, harmonics=5)
    c = cli_json("hbm", "--model", "standalone", "--continue", "omega", "--from", "0.4", "--to", "1.6", "--alpha", "0.3",
                 "--harmonics", "5")
    assert len(h["branches"]) == len(c["branches"]) >= 2
    for mine, theirs in zip(h["branches"], c["branches"]):
        assert mine["start"] == theirs["start"]
        assert np.array_equal(mine["amplitude"], [p["amplitude"] for p in theirs["points"]])
        assert np.array_equal(mine["stable"], [p["stable"] for p in theirs["points"]])
        assert mine["well"] == [p["well"] for p in theirs["points"]]
    with pytest.raises(ValueError, match="param"):
        bistable.hbm(param="beta")


def test_hbm_period_doubling_and_switching_are_the_cli_ones():
    kw = dict(model="standalone", param="alpha", start=0.1, stop=0.25, omega=1.2, eta=0.3, harmonics=10, switch_pd=1)
    h = bistable.hbm(**kw)
    c = cli_json("hbm", "--model", "standalone", "--continue", "alpha", "--from", "0.1", "--to", "0.25", "--omega", "1.2",
                 "--eta", "0.3", "--harmonics", "10", "--switch-pd", "1")
    assert [b["period"] for b in h["branches"]] == [b["period"] for b in c["branches"]]
    assert any(b["period"] == 2 for b in h["branches"])  # switched onto the doubled branch
    for mine, theirs in zip(h["branches"], c["branches"]):
        assert list(mine["period_doubling"]) == [bool(p.get("period_doubling", False)) for p in theirs["points"]]
    assert h["notes"] == c["notes"]
    # `bifurcations` as `hbm --json` gives it: the same list, every number to the bit.
    assert h["bifurcations"] == c["bifurcations"]
    assert {b["kind"] for b in h["bifurcations"]} >= {"period_doubling"}


@pytest.mark.parametrize(
    "kw,flags",
    [
        (dict(alpha=0.3), ["--alpha", "0.3"]),
        (dict(model="coupled", alpha=0.3, alpha_range=(0.05, 1.0), omega_range=(0.3, 2.0)),
         ["--model", "coupled", "--alpha", "0.3", "--alpha-range", "0.05,1", "--omega-range", "0.3,2"]),
    ],
)
def test_hbm_fold_curves_are_the_cli_fold_curves(kw, flags):
    h = bistable.hbm(fold_curve=True, **kw)
    c = cli_json("hbm", *flags, "--fold-curve")
    assert len(h["fold_curves"]) == len(c["fold_curves"]) >= 1
    for mine, theirs in zip(h["fold_curves"], c["fold_curves"]):
        assert mine["start"] == theirs["start"] and mine["converged"] == theirs["converged"]
        keys = set(theirs["points"][0])
        assert set(mine) == keys | {"start", "converged"}
        for k in keys:
            col = [p[k] for p in theirs["points"]]
            if k == "well":
                assert mine[k] == col
            elif k == "cusp":
                assert mine[k].dtype == bool and list(mine[k]) == col
            else:
                assert np.array_equal(mine[k], np.array([np.nan if x is None else x for x in col], dtype=float), equal_nan=True), k
    assert h["settings"]["alpha_range"] == c["settings"]["alpha_range"]
    assert h["settings"]["omega_range"] == c["settings"]["omega_range"]
    assert sum(int(f["cusp"].sum()) for f in h["fold_curves"]) >= 1
    assert "fold_curves" not in bistable.hbm(alpha=0.3, harmonics=3)


@pytest.mark.parametrize(
    "kw,expect",
    [
        (dict(fold_curve="yes"), "fold_curve = 'yes' violates fold_curve True or False"),
        (dict(fold_curve=True, alpha_range=(2.0, 1.0)), "alpha_range = 1 violates alpha_range > its low end 2"),
        (dict(fold_curve=True, omega_range=(0, 1)), "omega_range = 0 violates omega_range > 0"),
        (dict(fold_curve=True, omega_range=(0.1, float("inf"))), "omega_range[1] = inf violates omega_range[1] finite"),
        (dict(fold_curve=True, alpha_range="0.1,1"), "alpha_range = '0.1,1' violates alpha_range = (lo, hi)"),
        (dict(fold_curve=True, alpha_range=(0.1, 0.5, 1.0)), "alpha_range = (0.1, 0.5, 1.0) violates alpha_range = (lo, hi)"),
        (dict(fold_curve=True, alpha_range=(None, 1.0)), "alpha_range[0] = None violates alpha_range[0] a number"),
        (dict(alpha_rang=(0.1, 1.0)), "did you mean 'alpha_range'"),
    ],
)
def test_bad_fold_curve_arguments_raise_value_error_naming_the_field(kw, expect):
    with pytest.raises(ValueError, match=re.escape(expect)):
        bistable.hbm(alpha=0.3, harmonics=3, **kw)


def test_the_gil_is_released_while_computing():
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.005)

    t = threading.Thread(target=tick)
    t.start()
    start = time.monotonic()
    bistable.point(model="coupled", alpha=1.0, omega=1.2, t_end=3000.0, t_keep=100.0)
    elapsed = time.monotonic() - start
    done.set()
    t.join()
    during = [x for x in ticks if start < x < start + elapsed]
    assert elapsed > 0.1, elapsed
    # A held GIL would allow ~1 tick per switch interval at most; released, the thread ticks freely.
    assert len(during) > 0.3 * elapsed / 0.005, (len(during), elapsed)


def test_ctrl_c_stops_a_computation_and_the_next_call_runs(tmp_path):
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        bistable.point(model="coupled", alpha=1.0, omega=1.2, t_end=9e5, t_keep=100.0, sample_every=50, rosenstein=False)
    assert time.monotonic() - start < 5
    timer.join()
    assert bistable.point(model="coupled", alpha=1.0, omega=1.2)["motion"] == "chaotic"
    # Python's own SIGINT handler is back: a second Ctrl-C outside a computation is KeyboardInterrupt.
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(1)


def test_the_fig8b_example_runs_as_a_script(tmp_path):
    example = os.path.join(SOURCE, "examples", "fig8b.py")
    code = [line for line in open(example) if line.strip() and not line.lstrip().startswith("#")]
    assert len(code) < 20, len(code)
    env = dict(os.environ, MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, example], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    png = tmp_path / "fig8b.png"
    import matplotlib.pyplot as plt

    img = plt.imread(png)
    assert len(np.unique(img.reshape(-1, img.shape[-1]), axis=0)) > 50


def test_sweeps_and_query_are_the_cli_json(tmp_path):
    data = tmp_path / "d"
    ds = bistable.run(SMALL, data=data)
    sid = ds.attrs["sweep_id"]
    mine = bistable.sweeps(data=data)
    theirs = cli_json("sweeps", "--data", str(data))
    assert mine == theirs and mine[0]["id"] == sid and mine[0]["created"].endswith("Z")
    expr = "frf_db < 0 or motion == chaotic"
    q = bistable.query(sid, expr, data=data)
    assert q == cli_json("query", sid, expr, "--data", str(data))
    assert q["count"] == len(q["points"]) and 0 < q["total"] == 20
    chaotic = (ds.motion.values == 2) | (ds.frf_db.values < 0)
    assert q["count"] == int(chaotic.sum())
    assert all(isinstance(p["motion"], str) for p in q["points"])
    assert len(bistable.query(sid, expr, data=data, limit=1)["points"]) == min(1, q["count"])
    with pytest.raises(ValueError, match="limit = -5 violates limit >= 0"):  # issue 39: it returned every point
        bistable.query(sid, expr, data=data, limit=-5)
    assert bistable.query(sid, expr, data=data, limit=2**70)["count"] == q["count"]
    with pytest.raises(ValueError, match="query"):
        bistable.query(sid, "frf_dbb < 0", data=data)
    assert bistable.sweeps(data=tmp_path / "none") == []
    with pytest.raises(ValueError, match="is not a directory"):  # issue 39: a file was "no sweeps", []
        bistable.sweeps(data="/etc/passwd")


def test_identify_is_the_cli_identify(tmp_path):
    syn = bistable.identify([], make_synthetic=str(tmp_path / "syn"))
    assert len(syn["files"]) == 3
    record = syn["files"][0]
    args = dict(terms="main.linear,main.viscous", known={"m_main": 0.282}, max_seconds=6, global_evals=0, max_added=0)
    mine = bistable.identify(record, **args)
    flags = ["identify", "--data", record, "--terms", "main.linear,main.viscous", "--known", "m_main=0.282",
             "--max-seconds", "6", "--global-evals", "0", "--max-added", "0"]
    theirs = cli_json(*flags)
    # The same code and arguments give the same numbers to the bit: both binaries link Ceres as the
    # shared library, whose Eigen instances are its own (identify/CMakeLists.txt). The static archive
    # let the linker merge its generic-x86-64 Eigen copies with ours per binary (fits differed by ~4e-7
    # between module and CLI, and `bistable hbm` crashed with one link order).
    assert mine["effects_added"] == theirs["effects_added"]
    assert mine["params"] == theirs["params"]
    assert mine["params"]["main.linear.k_lin"] > 0
    terms = bistable.identify([], list_terms=True)
    assert any(t["term"] == "main.friction" for t in terms)
    with pytest.raises(ValueError, match="terms"):
        bistable.identify(record, terms="main.nonsense")
    with pytest.raises(ValueError, match="unknown keyword 'no_such_flag'"):
        bistable.identify(record, no_such_flag=1)


def test_identify_full_report_is_the_cli_text(tmp_path):
    # identify::Summary::FullReport, one copy: what `bistable identify` prints without --json is the Python
    # result's full_report() (but for the wall time on the last line).
    record = bistable.identify([], make_synthetic=str(tmp_path / "syn"))["files"][0]
    r = bistable.identify(record, terms=["main.linear", "main.viscous"], known={"m_main": 0.282}, max_seconds=6,
                          global_evals=0, max_added=1, test_range=[(720, 960)])
    text = r.full_report()
    for part in ["1 record(s)", "error (NRMSE of the output)", "declared model (fitted):", "final model:",
                 "main.linear.k_lin", "test ", " simulations"]:
        assert part in text
    cli = subprocess.run([CLI, "identify", "--data", record, "--terms", "main.linear,main.viscous", "--known",
                          "m_main=0.282", "--max-seconds", "6", "--global-evals", "0", "--max-added", "1",
                          "--test-range", "720:960"], capture_output=True, text=True, timeout=600)
    assert cli.returncode == 0, cli.stderr
    assert cli.stdout.splitlines()[:-1] == text.splitlines()[:-1]
    assert isinstance(r, dict) and r["params"]["main.linear.k_lin"] > 0


def without_seconds(j):
    """A result without its timing fields ("seconds" anywhere)."""
    if isinstance(j, dict):
        return {k: without_seconds(v) for k, v in j.items() if k != "seconds"}
    if isinstance(j, list):
        return [without_seconds(v) for v in j]
    return j


def test_identify_takes_typed_options_and_names_the_bad_one(tmp_path):
    # Keyword arguments onto the library's options (identify/options.h), no command-line text: lists, dicts,
    # (A, B) ranges. The result is the CLI's --json but for the timing fields.
    record = bistable.identify([], make_synthetic=str(tmp_path / "syn"))["files"][0]
    mine = bistable.identify(record, terms=["main.linear", "main.viscous"], known={"m_main": 0.282}, max_seconds=6,
                             global_evals=0, max_added=0, objective="time", test_range=[(720, 960), "960:1200"])
    theirs = cli_json("identify", "--data", record, "--terms", "main.linear,main.viscous", "--known", "m_main=0.282",
                      "--max-seconds", "6", "--global-evals", "0", "--max-added", "0", "--objective", "time",
                      "--test-range", "720:960", "--test-range", "960:1200")
    assert without_seconds(mine) == without_seconds(theirs)
    assert [t["range"] for t in mine["tests"]] == ["720:960", "960:1200"]
    ok = dict(terms="main.linear,main.viscous", known={"m_main": 0.282}, max_added=0, global_evals=0)
    for bad, message in [
        (dict(lm_iterations=0), "lm-iterations: must be in [1, 10000]"),
        (dict(range=(5, 5)), "range: range = 5:5 is empty"),
        (dict(range="1e3:2000"), "violates range = A:B"),
        (dict(known={"m_main": -1}), "known.m_main: m_main = -1 violates m_main > 0"),
        (dict(known={"m_mian": 1}), "did you mean 'm_main'"),
        (dict(objective="phase"), "violates objective in {auto, time, fft, shooting}"),
        (dict(columns={"outptu": "x"}), "did you mean 'output'"),
        (dict(horizon=4000), "horizon = 4000 violates 0 <= horizon <= 3600 s"),
        (dict(horizon=float("nan")), "horizon = nan violates horizon finite"),
        (dict(max_added="3"), "max_added = '3' violates max_added an integer"),
        (dict(guess={"main.linear.k": 1.0}), "did you mean 'main.linear.k_lin'"),
        (dict(terms=["main.linear", "main.stifness_y3"]), "did you mean 'main.stiffness_y3'"),
    ]:
        with pytest.raises(ValueError, match=re.escape(message)):
            bistable.identify(record, **{**ok, **bad})


def test_identify_synthetic_and_predict_take_typed_options(tmp_path):
    # make_synthetic and predict=True: keywords onto identify::MakeSyntheticOptions and PredictOptions (issue 40),
    # no command-line text; the files and the JSON are the CLI's (but for the timing fields).
    mine = bistable.identify([], make_synthetic=tmp_path / "py", synthetic="bistable", synthetic_amplitude=[8, 12],
                             synthetic_extra={"main.drag": 5}, synthetic_start="left", synthetic_duration=10,
                             synthetic_seed=3)
    theirs = cli_json("identify", "--make-synthetic", str(tmp_path / "cli"), "--synthetic", "bistable",
                      "--synthetic-amplitude", "8", "--synthetic-amplitude", "12", "--synthetic-extra", "main.drag=5",
                      "--synthetic-start", "left", "--synthetic-duration", "10", "--synthetic-seed", "3", "--json")
    assert [os.path.basename(f) for f in mine["files"]] == [os.path.basename(f) for f in theirs["files"]]
    for a, b in zip(mine["files"] + [mine["truth"]], theirs["files"] + [theirs["truth"]]):
        assert open(a, "rb").read() == open(b, "rb").read(), a
    record = mine["files"][0]
    predicted = bistable.identify(record, predict=True, model=mine["truth"], range=(0, 600), objective="time")
    cli = cli_json("identify", "--predict", "--model", mine["truth"], "--data", record, "--range", "0:600",
                   "--objective", "time", "--json")
    assert without_seconds(predicted) == without_seconds(cli)
    assert predicted["prediction"]["settings"]["range"] == "0:600"
    for bad, message in [
        (dict(synthetic_amplitude=-1), "synthetic-amplitude: --synthetic-amplitude = -1 violates 0.01 <= value <= 100"),
        (dict(synthetic_f_end=60), "synthetic-f-end: --synthetic-f-end = 60 violates 0.01 <= value <= 50"),
        (dict(synthetic_start="middle"), "synthetic-start: --synthetic-start 'middle' is not left or right"),
        (dict(synthetic="nope"), "synthetic: 'nope' is not linear, coupled, bistable or bistable-coupled"),
        (dict(synthetic_extra={"main.drag": -1}), "synthetic-extra: --synthetic-extra main.drag.cq = -1 violates >= 0"),
        (dict(synthetic_extra="res.drag=1"), "needs --synthetic bistable-coupled"),
        (dict(synthetic_seed=-3), "synthetic_seed = -3 violates 0 <= synthetic_seed <= 4294967295"),
        (dict(synthetic_noise="0.1"), "synthetic_noise = '0.1' violates synthetic_noise a number"),
    ]:
        with pytest.raises(ValueError, match=re.escape(message)):
            bistable.identify([], make_synthetic=str(tmp_path / "bad"), **{"synthetic": "bistable", **bad})
    assert not (tmp_path / "bad").exists()  # every option checked before anything is written
    with pytest.raises(ValueError, match=re.escape("synthetic: --synthetic-extra and --synthetic-amplitude")):
        bistable.identify([], make_synthetic=str(tmp_path / "bad"), synthetic_amplitude=3)
    for bad, message in [
        (dict(start_well="middle"), "start-well: 'middle' violates start-well in {none, left, right}"),
        (dict(start_well=["left", "right"]), "start-well: give one value for all --data files or one per file (1)"),
        (dict(known={"m_main": -1}), "known.m_main: m_main = -1 violates m_main > 0"),
        (dict(guess={"main.linear.k_lin": 3.0}), "guess: --predict fits nothing"),
        (dict(report=str(tmp_path / "r")), "report: --predict writes no report directory"),
        (dict(model=""), "model: --predict needs --model FILE"),
        (dict(decimate=0), "decimate"),
    ]:
        with pytest.raises(ValueError, match=re.escape(message)):
            bistable.identify(record, **{"predict": True, "model": mine["truth"], **bad})


def start(cmd, log):
    return subprocess.Popen(cmd, stdout=open(log, "w"), stderr=subprocess.STDOUT)


def listening_address(log):
    """The address a coordinator started with --listen 127.0.0.1:0 prints in its log (waits up to 10 s)."""
    for _ in range(400):
        lines = [x for x in open(log).read().splitlines() if x.startswith("listening on ")]
        if lines:
            return lines[0].split()[-1]
        time.sleep(0.025)
    raise AssertionError(open(log).read())


def test_client_refuses_a_token_with_a_control_byte_and_never_shows_it(tmp_path):
    """Issue 39: a newline, NUL or control byte in a token used to abort the interpreter (gRPC aborts on
    invalid metadata, logging the token). Each case runs in a child interpreter, so an abort fails the
    case instead of killing pytest."""
    log = tmp_path / "coordinator.log"
    coord = start([os.environ["BISTABLE_COORDINATOR"], "--listen", "127.0.0.1:0", "--data", str(tmp_path / "server")], log)
    try:
        address = listening_address(log)
        for token in ("SECRETA\nSECRETB", "SECRETA\0SECRETB", "SECRETA\x01SECRETB", "SECRETA SECRETB"):
            code = ("import bistable\n"
                    "try:\n"
                    f"    bistable.Client({address!r}, token={token!r}).status('abc')\n"
                    "except ValueError as e:\n"
                    "    print('ValueError:', e)\n")
            r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
            assert r.returncode == 0, (repr(token), r.returncode, r.stderr[-2000:])
            assert "ValueError:" in r.stdout and "token" in r.stdout, (repr(token), r.stdout)
            assert "SECRET" not in r.stdout + r.stderr, (repr(token), r.stdout, r.stderr[-2000:])
    finally:
        coord.terminate()
        coord.wait(timeout=20)


def test_client_refuses_a_token_in_plaintext_to_an_address_that_is_not_loopback():
    with pytest.raises(ValueError, match="insecure-remote"):
        bistable.Client("0.0.0.0:1", token="goodtoken")
    with pytest.raises(ValueError, match="insecure-remote"):
        bistable.Client("coordinator.example:50051", token="goodtoken")
    bistable.Client("127.0.0.1:1", token="goodtoken")  # loopback: plaintext is this host only
    bistable.Client("0.0.0.0:1")  # no token: nothing to leak
    with pytest.raises(OSError, match="cannot reach"):  # allowed explicitly: the call is made
        bistable.Client("0.0.0.0:1", token="goodtoken", insecure_remote=True).status("abc")


def test_client_submits_watches_and_fetches_through_a_real_coordinator(tmp_path):
    log = tmp_path / "coordinator.log"
    coord = start([os.environ["BISTABLE_COORDINATOR"], "--listen", "127.0.0.1:0", "--data", str(tmp_path / "server"),
                   "--lease-seconds", "2", "--job-seconds", "0.01"], log)
    worker = None
    try:
        address = listening_address(log)
        c = bistable.Client(address)
        sub = c.submit(SMALL)
        assert sub["items_total"] == 20
        worker = start([os.environ["BISTABLE_WORKER"], "--coordinator", address, "--threads", "1", "--name", "py-w"],
                       tmp_path / "worker.log")
        final = c.wait(sub["id"], timeout=120)
        assert final["state"] == "done", final
        assert c.status(sub["id"])["items_done"] == 20
        assert [s["id"] for s in c.sweeps()] == [sub["id"]]
        assert any(w["name"] == "py-w" and w["last_seen"].endswith("Z") for w in c.workers())
        remote = c.map(sub["id"], path=tmp_path / "fetched.h5")
        local = bistable.run(SMALL, data=tmp_path / "local")
        for name in ("frf_db", "lle", "motion"):
            assert np.array_equal(remote[name].values, local[name].values, equal_nan=True), name
        with pytest.raises(ValueError):
            c.status("not-an-id!")
        with pytest.raises(OSError):
            bistable.Client("127.0.0.1:1").status(sub["id"])
    finally:
        for p in (worker, coord):
            if p:
                p.terminate()
                p.wait(timeout=20)


def test_ctrl_c_in_one_thread_does_not_let_another_store_a_cut_short_job(tmp_path):
    # A sweep in a worker thread and a long point on the main thread: Ctrl-C stops both (the flag is
    # process-wide); the sweep raises KeyboardInterrupt rather than publishing, and running it again
    # afterwards gives the same map as an undisturbed run.
    spec = dict(SMALL, axes={"alpha": {"linspace": [0.2, 2.0, 40]}, "omega": {"linspace": [0.5, 1.5, 40]}},
                integration={"t_end": 2000.0, "t_keep": 1000.0})
    outcome = {}

    def sweep():
        try:
            outcome["path"] = bistable.run(spec, data=tmp_path / "a", threads=1, path_only=True)
        except KeyboardInterrupt:
            outcome["interrupted"] = True

    t = threading.Thread(target=sweep)
    t.start()
    time.sleep(0.3)
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        bistable.point(model="coupled", alpha=1.0, omega=1.2, t_end=9e5, t_keep=100.0, sample_every=50, rosenstein=False)
    t.join()
    timer.join()
    assert outcome.get("interrupted") or "path" in outcome, outcome
    resumed = bistable.run(spec, data=tmp_path / "a", path_only=True)
    clean = bistable.run(spec, data=tmp_path / "b", path_only=True)
    with h5py.File(resumed) as f, h5py.File(clean) as g:
        for name in ("frf_db", "lle", "motion"):
            assert np.array_equal(f[name][()], g[name][()], equal_nan=True), name


def test_one_version_in_the_cli_the_map_and_the_module(tmp_path):
    # CMake's project version is the one software version (issue 43): `bistable --version`, a map's
    # software_version and bistable.__version__ all say it; the numerics version follows it where it is shown.
    project = re.search(r"project\(bistable_sweep VERSION (\d+\.\d+\.\d+)", open(os.path.join(SOURCE, "CMakeLists.txt")).read())
    r = subprocess.run([CLI, "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "bistable %s (numerics %s)" % (project.group(1), bistable.numerics_version)
    ds = bistable.run(SMALL, data=tmp_path / "d")
    assert bistable.__version__ == ds.attrs["software_version"] == project.group(1)
    assert ds.attrs["numerics_version"] == bistable.numerics_version


def test_plots_are_labelled_with_units_and_category_names(tmp_path):
    # What xarray draws from the map's attributes (issue 43): long_name [units], or the scale of a dimensionless
    # quantity ([1/tau], [A0/delta_s]) where it has no units; never "[1]". Codes plot with their names.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ds = bistable.run(SMALL, data=tmp_path / "d")
    label = lambda text: text.replace("\n", " ")  # noqa: E731 (xarray wraps labels at 30 characters)
    q = ds.frf_db.plot(x="omega")
    assert label(q.colorbar.ax.get_ylabel()) == ds.frf_db.attrs["long_name"] + " [dB]"
    assert label(q.axes.get_xlabel()) == "excitation frequency Omega = omega0/omega_n [omega0/omega_n]"
    assert label(q.axes.get_ylabel()) == "base excitation amplitude alpha = A0/delta_s [A0/delta_s]"
    plt.close("all")
    assert label(ds.lle.plot(x="omega").colorbar.ax.get_ylabel()).endswith(" [1/tau]")
    plt.close("all")
    # A code variable: one colour per flag value, the flag meanings on the colour bar.
    m = bistable.plot(ds.motion, x="omega")
    names = ds.motion.attrs["flag_meanings"].split()
    assert [t.get_text() for t in m.colorbar.ax.get_yticklabels()] == names
    assert list(m.colorbar.get_ticks()) == sorted(np.atleast_1d(ds.motion.attrs["flag_values"]).tolist())
    assert m.colorbar.ax.get_ylabel() == "type of steady-state motion"
    colours = m.cmap(m.norm(np.atleast_1d(ds.motion.attrs["flag_values"])))
    assert len({tuple(c) for c in colours}) == len(names)  # a colour per category
    png = tmp_path / "motion.png"
    plt.savefig(png)
    plt.close("all")
    img = plt.imread(png)
    assert len(np.unique(img.reshape(-1, img.shape[-1]), axis=0)) > 20
    # Facets (col=) share one colour bar, named too.
    grid = bistable.plot(ds.motion.expand_dims(run=[0, 1]), x="omega", col="run")
    assert [t.get_text() for t in grid.cbar.ax.get_yticklabels()] == names
    plt.close("all")
    # 1-D: the names on the y axis; a variable without flags is xarray's own plot.
    lines = bistable.plot(ds.motion.isel(alpha=0))
    assert [t.get_text() for t in lines[0].axes.get_yticklabels()] == names
    plt.close("all")
    q = bistable.plot(ds.edr_t, x="omega")
    assert label(q.colorbar.ax.get_ylabel()) == "total energy dissipation ratio [percent]"
    plt.close("all")


def test_shards_run_and_merge_to_the_embedded_map_bit_for_bit(tmp_path):
    whole = bistable.run(SMALL, data=str(tmp_path / "whole"), threads=1, path_only=True)
    data = str(tmp_path / "shards")
    done = [bistable.run(SMALL, data=data, threads=1, shard=f"{i}/3") for i in range(3)]
    assert sum(d["items"] for d in done) == 20 and all(d["computed"] == d["items"] for d in done)
    again = bistable.run(SMALL, data=data, threads=1, shard="1/3")  # resumed: nothing left to compute
    assert again["computed"] == 0 and again["cached"] == again["items"]
    merged = bistable.merge(SMALL, data=data, path_only=True)
    with h5py.File(whole) as a, h5py.File(merged) as b:
        for name in ("frf_db", "lle", "motion"):
            assert np.array_equal(a[name][()], b[name][()], equal_nan=True), name
    with pytest.raises(ValueError, match="shard"):
        bistable.run(SMALL, data=data, shard="3/3")
    with pytest.raises(ValueError, match="shard"):
        bistable.run(SMALL, data=data, shard=3)
