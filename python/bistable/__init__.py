"""bistable-sweep from Python: the same C++ core as the `bistable` CLI (docs/python.md).

    import bistable
    r = bistable.point(model="coupled", alpha=1.0, omega=1.2)     # dict, as `bistable point --json`
    ds = bistable.run("examples/paper_fig8_frf.toml")              # xarray.Dataset of the map
    ds.frf_db.plot()                                               # labelled: long_name [dB]
    bistable.plot(ds.motion)                                       # codes by name: intrawell, chaotic, ...

Units are the model's (docs/model.md): non-dimensional time tau = omega_n t, lengths in delta_s, unless
the model is "dimensional". Every function releases the GIL while it computes; Ctrl-C stops it
(KeyboardInterrupt; nothing partial is returned). Bad arguments raise ValueError naming the argument and
the bound it violates, as the CLI's error lines do.
"""
import builtins as _builtins
import os as _os
import sys as _sys

from . import _core
from .plotting import plot

__version__ = _core.__version__
numerics_version = _core.numerics_version
DEFAULT_DATA = "bistable-data"

__all__ = ["point", "trajectory", "run", "merge", "open", "open_file", "find", "sweeps", "query", "hbm", "identify",
           "IdentifyResult", "plot", "Client"]


def point(**kw):
    """Integrates one point and returns every metric: the object `bistable point --json` prints.

    Keywords are the CLI's flags with '_' for '-': model ("coupled", "standalone", "linear",
    "linear-coupled"), alpha and omega (required), eps, eta, eta_r, phi, lambda, t_end, t_keep,
    integrator ("rk4" or "adaptive"), dt, rtol, atol, ic=(ym, vm[, yr, vr]), chaos_threshold,
    renorm_every, sample_every, rosenstein (bool), spectrum (bool: also the Lyapunov spectrum,
    lyapunov_spectrum / lyapunov_sum / divergence / kaplan_yorke as `point --spectrum --json`).
    Results are bit-identical to the CLI's.

    Poincare (stroboscopic) section, as `point --poincare - --json`: poincare_phase (radians of
    Omega tau in [0, 2 pi), default 0: strobes at tau_k = (phase + 2 pi k)/Omega; the period test uses
    them too), poincare_periods (int N in [1, 100000], instead of t_end: the window is made N + 1
    forcing periods long and the section keeps its first N points), poincare (bool). With poincare=True
    or poincare_periods, the dict has "poincare": {"phase", "count", "k0", "columns", "units", and one
    numpy array per column: "k" (int64 strobe index), "tau" (1/omega_n), "y_m" (delta_s), "dy_m"
    (delta_s/tau), and "y_r", "dy_r" for models with a resonator}; the CLI's "points" rows are
    numpy.column_stack([sec[c] for c in sec["columns"]]).
    """
    return _core.point(**kw)


def trajectory(**kw):
    """Integrates one point and returns the sampled steady-state window as numpy arrays.

    Same keywords as point() but spectrum and poincare. Returns {"tau", "y_m", "dy_m", "y_r", "dy_r": arrays over the window
    tau in [t_keep, t_end], every sample_every steps; "metrics": point()'s dict}.
    """
    return _core.trajectory(**kw)


def _spec_text(spec):
    """(TOML text, origin) of a spec given as a path, TOML text or a dict (the TOML's tables)."""
    if isinstance(spec, dict):
        return _toml_dump(spec), "<dict>"
    if isinstance(spec, (str, _os.PathLike)):
        text = _os.fspath(spec)
        if "\n" not in text and (text.endswith(".toml") or _os.path.exists(text)):
            with _builtins.open(text, "rb") as f:
                return f.read().decode("utf-8"), text
        return text, "<string>"
    raise ValueError("spec = %r violates spec a path, TOML text or a dict" % (type(spec).__name__,))


def _toml_value(v, where):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if v != v or v in (float("inf"), float("-inf")):
            raise ValueError("%s = %r violates %s finite" % (where, v, where))
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x, where) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join("%s = %s" % (_toml_key(k), _toml_value(x, where + "." + str(k))) for k, x in v.items()) + " }"
    if hasattr(v, "tolist"):  # numpy arrays and scalars
        return _toml_value(v.tolist(), where)
    raise ValueError("%s = %r violates %s a number, string, bool, list or table" % (where, v, where))


def _toml_key(k):
    k = str(k)
    return k if k.replace("_", "a").replace("-", "a").isalnum() else _toml_value(k, "key")


def _toml_dump(spec):
    """A spec dict as TOML: top-level scalars first, then one [table] per dict value."""
    lines, tables = [], []
    for k, v in spec.items():
        (tables if isinstance(v, dict) else lines).append((k, v))
    out = ["%s = %s" % (_toml_key(k), _toml_value(v, str(k))) for k, v in lines]
    for name, table in tables:
        out.append("\n[%s]" % _toml_key(name))
        out += ["%s = %s" % (_toml_key(k), _toml_value(v, "%s.%s" % (name, k))) for k, v in table.items()]
    return "\n".join(out) + "\n"


def open_file(path):
    """The map file at `path` as an xarray.Dataset (CF-1.10; docs/map-files.md), loaded into memory."""
    try:
        import h5netcdf  # noqa: F401 (xarray's engine)
        import xarray
    except ImportError as e:  # another Python than the one the module was built and installed for
        raise ImportError("bistable reads maps with xarray and h5netcdf (Debian: apt-get install python3-xarray "
                          "python3-h5netcdf), which %s cannot import (%s); use Debian's /usr/bin/python3 or a venv "
                          "made with --system-site-packages (docs/python.md)" % (_sys.executable, e)) from e

    with xarray.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()


def run(spec, data=DEFAULT_DATA, threads=0, progress=False, path_only=False, shard=None):
    """Runs a sweep in this process (the embedded default of `bistable run`) and returns its map.

    spec: a path to a TOML spec, TOML text, or a dict of its tables (docs/sweep-spec.md), e.g.
    {"name": "x", "model": "coupled", "axes": {"alpha": {"linspace": [0.1, 3, 50]}, ...}}.
    data: the data directory (cache, index, maps); threads: 0 = every usable CPU; progress: the CLI's
    progress bar on stderr. Points already in the data directory's cache are not recomputed.
    Returns an xarray.Dataset (path_only=True: the map file's path).

    shard="I/N" computes only shard I of N into its own store (`bistable run --shard I/N`, a job array's task)
    and returns {"store", "items", "cached", "computed"}; merge() then assembles the map.
    """
    threads = int(threads)
    if not 0 <= threads <= 1024:  # before the C++ int: 2**63 raised TypeError (issue 39)
        raise ValueError(f"threads = {threads} violates threads in [0, 1024]")
    text, origin = _spec_text(spec)
    if shard is not None:
        if not isinstance(shard, str):
            raise ValueError("shard = %.80r violates shard a string I/N (e.g. '3/8')" % (shard,))
        return _core.run_shard(text, origin, shard, _os.fspath(data), threads, bool(progress))
    r = _core.run(text, origin, _os.fspath(data), threads, bool(progress))
    return r["file"] if path_only else open_file(r["file"])


def merge(spec, stores=None, data=DEFAULT_DATA, path_only=False):
    """Assembles the shards of a sweep (run(..., shard="I/N") or `bistable run --shard I/N`) into the map
    `bistable run` writes, bit for bit (`bistable merge`). stores: the shard stores' directories (None: every
    <data>/shards/<id>-* store). Returns an xarray.Dataset (path_only=True: the map file's path)."""
    text, origin = _spec_text(spec)
    paths = [] if stores is None else [_os.fspath(p) for p in ([stores] if isinstance(stores, (str, _os.PathLike)) else stores)]
    r = _core.merge(text, origin, paths, _os.fspath(data))
    return r["file"] if path_only else open_file(r["file"])


def find(id, data=DEFAULT_DATA):
    """{"id", "name", "state", "file"} of a sweep in `data`, by id or unique prefix (ValueError naming "id" if none)."""
    return _core.find(str(id), _os.fspath(data))


def open(id, data=DEFAULT_DATA):  # noqa: A001 (the module's verb, like xarray.open_dataset)
    """The published map of sweep `id` (or a unique prefix) in `data` as an xarray.Dataset."""
    ref = find(id, data)
    if not ref["file"]:
        raise ValueError("sweep %s has no published map yet (state %s); run it to finish" % (ref["id"], ref["state"]))
    return open_file(ref["file"])


def sweeps(data=DEFAULT_DATA):
    """The sweeps of a data directory: the list `bistable sweeps --json` prints."""
    return _core.sweeps(_os.fspath(data))


def query(id, expr, data=DEFAULT_DATA, limit=None):
    """Points of a map where `expr` holds ("frf_db < -3 and lle < 0.01", "motion == chaotic"): the object
    `bistable query --json` prints ({"sweep", "query", "count", "total", "points": [...]})."""
    if limit is not None:
        limit = int(limit)
        if limit < 0:  # -5 used to return every point
            raise ValueError(f"limit = {limit} violates limit >= 0 (None: every point)")
        limit = min(limit, 2**62)
    return _core.query(str(id), str(expr), _os.fspath(data), -1 if limit is None else limit)


def hbm(**kw):
    """Harmonic balance with continuation and Floquet stability (`bistable hbm`).

    Keywords: model ("standalone", "coupled", "linear", "linear-coupled"), param ("omega" or "alpha",
    the continued parameter), start, stop (its range), alpha / omega (the fixed one), harmonics,
    zero_mean, eps, eta, eta_r, phi, lambda, ds, switch_pd (branch switching at period doublings, 0-3
    levels), fold_curve (bool: also continue every fold of the period-1 branches in (alpha, omega),
    `hbm --fold-curve`), alpha_range / omega_range ((lo, hi), the box the fold curves stay in; default
    (0.01, 3) and (0.05, 3)). Returns {"branches": [{"start", "period", "omega", "alpha", "amplitude",
    "mean", "y_min", "y_max", "max_multiplier", "stable", "fold", "branch_point", "period_doubling",
    "neimark_sacker", "converged": arrays, "well": names per point ("+well", "-well", "interwell"),
    "harmonics": array [points, 2H+1]}], "settings", "truncation_change", "notes"}; with fold_curve also
    "fold_curves": [{"start", "converged", "alpha", "omega" (arrays, A0/delta_s and omega0/omega_n),
    "amplitude", "mean" (arrays, delta_s), "cusp" (bool array), "well" (names; bistable models)}], the
    points of `hbm --fold-curve --json`'s curves as columns, and settings "alpha_range", "omega_range".
    """
    return _core.hbm(**kw)


class IdentifyResult(dict):
    """A fit of `identify`: the dict `bistable identify --json` prints (it compares, indexes and serialises as that
    dict), and the fit as text, `full_report()`."""

    def __init__(self, result, full_report):
        super().__init__(result)
        self._full_report = full_report

    def full_report(self):
        """The fit as text, after Ceres's Summary::FullReport (identify::Summary::FullReport, what `bistable identify`
        prints without --json): the records and the objective, the errors before and after, every step's verdict,
        the declared and the final model (each parameter with its sigma and unit), the test ranges, the diagnostics,
        wall time and simulations."""
        return self._full_report


def identify(data, **kw):
    """Fits the model to measured records (`bistable identify`); the dict `--json` prints (an IdentifyResult: its
    full_report() is the fit as text).

    data: a CSV path or a list of them. Keywords are the fields of the library's options
    (identify/options.h: identify::Options), named as the CLI's flags with '_' for '-', typed, SI units:

        identify(["a.csv"], terms=["main.linear", "main.viscous"], known={"m_main": 0.282},
                 columns={"input": "base_acc_g", "output": "laser_V"}, input_kind="base_acceleration",
                 max_seconds=8, decimate=4, range=(0, 2000), test_range=[(2000, 4000)])

    terms, candidates: a list of term ids (or "a,b"); known, guess: dicts of numbers; columns: a dict of
    role -> column name (group: a list); range, test_range: (A, B) or "A:B"; report: a directory for
    report.md, report.json and the figures. Invalid options raise ValueError naming the option and its bound.

    list_terms=True returns the effect library. make_synthetic=DIR writes synthetic records (`--make-synthetic`;
    identify::MakeSyntheticOptions): synthetic="linear" | "coupled" | "bistable" | "bistable-coupled",
    synthetic_amplitude (mm, a number or a list: one record each), synthetic_f_start, synthetic_f_end (Hz),
    synthetic_duration (s), synthetic_noise (mm), synthetic_seed, synthetic_extra ("main.drag=5", a list of them,
    or {"main.drag": 5}), synthetic_start ("left" | "right"); returns {"files"[, "truth"]}. predict=True with
    model=FILE (`--predict`; PredictOptions) simulates the records with a fitted model, nothing refitted: the
    record keywords above, start_well ("none" | "left" | "right", one or one per file), known and terms (checked
    against the model's); returns {"prediction": ...}. Invalid values raise ValueError naming the option.
    """
    paths = [data] if isinstance(data, (str, bytes, _os.PathLike)) else list(data)
    for path in paths:
        if not isinstance(path, (str, bytes, _os.PathLike)):
            raise ValueError("data = %.80r violates data a path (str, bytes, os.PathLike) or a list of them" % (path,))
    paths = [_os.fsencode(p) for p in paths]  # bytes: any file name the system allows, UTF-8 or not
    if kw.get("list_terms"):
        return _core.identify_terms()
    for key in ("make_synthetic", "model"):  # paths: os.PathLike too
        if isinstance(kw.get(key), _os.PathLike):
            kw[key] = _os.fspath(kw[key])
    if "make_synthetic" in kw:
        return _core.identify_synthetic(kw)
    if kw.get("predict"):
        return _core.identify_predict(paths, kw)
    return IdentifyResult(*_core.identify(paths, kw))


class Client:
    """A coordinator over gRPC, through the CLI's own client (TLS with tls_ca, bearer token).

        c = bistable.Client("coordinator:50051", token=open("token").read().strip(), tls_ca="ca.pem")
        id = c.submit("spec.toml")
        c.wait(id); ds = c.map(id)
    """

    def __init__(self, address, token=None, tls_ca=None, insecure_remote=False):
        """A token is refused in plaintext (no tls_ca) to an address that is not loopback unless
        insecure_remote=True: anyone on the path could read it (ValueError otherwise)."""
        self._c = _core.Client(str(address), "" if token is None else str(token), "" if tls_ca is None else _os.fspath(tls_ca),
                               bool(insecure_remote))

    def submit(self, spec):
        """Submits a spec (path, TOML text or dict); {"id", "items_total", "items_cached", "jobs"}."""
        text, origin = _spec_text(spec)
        return self._c.submit(text, origin)

    def status(self, id):
        """The object `bistable status --json` prints."""
        return self._c.status(str(id))

    def wait(self, id, timeout=None):
        """Blocks until the sweep is final (done, failed, cancelled); its last status."""
        return self._c.wait(str(id), -1.0 if timeout is None else float(timeout))

    def cancel(self, id):
        self._c.cancel(str(id))

    def sweeps(self):
        """The list `bistable sweeps --coordinator ADDR --json` prints."""
        return self._c.sweeps()

    def workers(self):
        """The list `bistable workers --json` prints."""
        return self._c.workers()

    def fetch(self, id, path):
        """Downloads the published map file (SHA-256 checked) to `path`; {"id", "file", "bytes", "sha256"}."""
        return self._c.fetch(str(id), _os.fspath(path))

    def map(self, id, path=None):
        """The published map as an xarray.Dataset (fetched to `path`, default <full sweep id>.h5 in the cwd)."""
        if path is None:
            path = self.status(id)["id"] + ".h5"  # the coordinator's id (12 hex digits), never the caller's text
        r = self.fetch(id, path)
        return open_file(r["file"])
