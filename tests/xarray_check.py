#!/usr/bin/python3
"""Every example spec, on a coarse grid, gives a map file that xarray opens as CF-1.10 (issue 13).

usage: xarray_check.py BISTABLE_BINARY EXAMPLES_DIR WORK_DIR

For each examples/*.toml: the axes are cut to at most 4 values (linspace/logspace counts, lists) so the
whole check runs in about a minute, the spec is run by the real `bistable run` (a process, embedded
default), and the map file is checked:
  * xarray.open_dataset opens it with both engines Debian ships (h5netcdf and netCDF4);
  * every dimension of every variable has a coordinate variable, and the sweep's axes are exactly
    the map's leading dimensions;
  * CF attributes: Conventions, history, source; every data variable has long_name, and either units
    that UDUNITS-2 parses (the udunits2 program; or dB), or flag_values/flag_meanings, or (a dimensionless
    quantity scaled by the model's references) no units and its scale in `unit`, which xarray's labels
    show; fixed parameters are scalar coordinates holding the spec's values;
  * values read through xarray equal what h5py reads, bit for bit (NaN where NaN), and motion decodes
    to its flag meanings;
  * ds.frf_db.plot() (or the first data variable's) writes a PNG that is not blank.
Prints one line per spec; exits non-zero on the first failure with the reason.
"""
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

binary, examples, work = sys.argv[1], sys.argv[2], sys.argv[3]
data = os.path.join(work, "data")
shutil.rmtree(data, ignore_errors=True)  # maps of an earlier build must not stand in for this one's
os.makedirs(work, exist_ok=True)


def coarse(text):
    """The spec with every axis cut to at most 4 values (counts of linspace/logspace, list items); a refined
    map ([refine] levels = L) keeps 2^L + 1 values, the fewest it accepts."""
    levels = re.search(r"^\s*levels\s*=\s*(\d+)", text[text.find("[refine]"):], re.M) if "[refine]" in text else None
    most = 2 ** int(levels.group(1)) + 1 if levels else 4
    text = re.sub(r"((?:lin|log)space\s*=\s*\[[^,\]]+,[^,\]]+,\s*)(\d+)", lambda m: m.group(1) + str(min(int(m.group(2)), most)), text)
    out, in_axes = [], False
    for line in text.splitlines():
        if line.startswith("["):
            in_axes = line.strip() == "[axes]"
        m = re.match(r"^(\s*\w+\s*=\s*)\[([^\]]*)\](.*)$", line) if in_axes else None
        if m:
            items = [x for x in m.group(2).split(",") if x.strip()]
            line = m.group(1) + "[" + ",".join(items[:3]) + "]" + m.group(3)
        out.append(line)
    return "\n".join(out) + "\n"


units_seen = {}


def udunits_ok(unit):
    if unit not in units_seen:
        r = subprocess.run(["udunits2", "-H", unit, "-W", ""], capture_output=True, text=True, timeout=20)
        units_seen[unit] = r.returncode == 0 and "recognize" not in (r.stdout + r.stderr)
    return units_seen[unit]


def check(path, spec):
    engines = {}
    for engine in ("h5netcdf", "netcdf4"):
        ds = xr.open_dataset(path, engine=engine)
        ds.load()
        engines[engine] = ds
    ds = engines["h5netcdf"]
    g = ds.attrs
    assert g.get("Conventions") == "CF-1.10", g.get("Conventions")
    for key in ("history", "source", "title", "references"):
        assert g.get(key), "global attribute %s missing" % key
    assert g["sweep_id"] in g["history"], g["history"]
    axes = [a for a in g["axes"].split(",") if a]
    assert axes == list(spec.get("axes", {}).keys()), (axes, list(spec.get("axes", {})))
    for name, var in ds.variables.items():
        for dim in var.dims:
            assert dim in ds.coords and ds[dim].dims == (dim,), "%s: dimension %s has no coordinate variable" % (name, dim)
        a = var.attrs
        assert a.get("long_name"), "%s has no long_name" % name
        if "flag_values" in a:
            assert len(a["flag_meanings"].split()) == len(np.atleast_1d(a["flag_values"])), name
        elif "units" in a:  # UDUNITS-2's, or dB: the CF standard-name table's unit of levels, which UDUNITS lacks
            assert a["units"] == "dB" or udunits_ok(a["units"]), "%s: units %r not UDUNITS-parsable" % (name, a.get("units"))
            assert a["units"] != "1" or a.get("unit_label") in ("fraction", ""), "%s: a scaled quantity with units 1" % name
        else:  # dimensionless (CF 3.1: no units), its scale in `unit`, which xarray's plot labels show
            assert a.get("unit") and a["unit"] == a["unit_label"] and a.get("comment"), "%s: no units, no unit" % name
            assert xr.plot.utils.label_from_attrs(var).replace("\n", " ").endswith("[%s]" % a["unit"]), name
    data_vars = list(ds.data_vars)
    assert data_vars, "no data variables"
    for name in data_vars:
        assert list(ds[name].dims[: len(axes)]) == axes, (name, ds[name].dims)
    # Fixed parameters are scalar coordinates holding the spec's values.
    params = spec.get("params", {})
    per_cell = {k for cell in spec.get("series", {}).get("cell", []) for k in cell}  # not one value: no scalar
    for key, value in params.items():
        if key in axes or not isinstance(value, (int, float)):
            continue
        if key in per_cell:
            assert key not in ds.coords, "%s is overridden per cell, yet written as one scalar" % key
            continue
        assert key in ds.coords, "fixed parameter %s of the spec is not a scalar coordinate" % key
        assert ds.coords[key].ndim == 0 and float(ds.coords[key]) == float(value), (key, float(ds.coords[key]), value)
    scalars = [c for c in ds.coords if ds.coords[c].ndim == 0]
    assert scalars, "no fixed parameters as scalar coordinates"
    # Round trip: xarray (both engines) sees exactly the stored values.
    with h5py.File(path, "r") as f:
        for name in data_vars:
            raw = f[name][()]
            for engine, e in engines.items():
                got = e[name].values
                assert got.shape == raw.shape, (engine, name, got.shape, raw.shape)
                assert np.array_equal(got, raw, equal_nan=raw.dtype.kind == "f"), "%s: %s differs from h5py" % (engine, name)
    if "motion" in ds:
        meanings = dict(zip(np.atleast_1d(ds.motion.attrs["flag_values"]).tolist(), ds.motion.attrs["flag_meanings"].split()))
        assert set(np.unique(ds.motion.values).tolist()) <= set(meanings), meanings
        assert meanings[1] == "interwell" and meanings[-1] == "undefined", meanings
    # A plot of the first map variable is written and not blank.
    name = "frf_db" if "frf_db" in ds else data_vars[0]
    da = ds[name]
    extra = [d for d in da.dims[2:]] if len(axes) >= 2 else list(da.dims[1:])
    da = da.isel({d: 0 for d in extra})
    png = os.path.join(work, os.path.basename(path) + ".png")
    for coord in [v for v in axes + [name] if "flag_values" not in ds[v].attrs]:  # codes: bistable.plot names them
        # xarray's labels (long_name [units]) name a real unit or scale; "[1]" only for fractions (CF's unit of them)
        label = xr.plot.utils.label_from_attrs(ds[coord]).replace("\n", " ")
        fraction = ds[coord].attrs.get("unit_label") in ("fraction", "")
        assert label.endswith("]") and (fraction or not label.endswith("[1]")), "%s is labelled %r" % (coord, label)
    plt.figure()
    da.plot()
    plt.savefig(png)
    plt.close("all")
    img = plt.imread(png)
    colours = np.unique(img.reshape(-1, img.shape[-1]), axis=0)
    assert len(colours) > 20, "%s: the plot of %s has %d colours (blank?)" % (png, name, len(colours))
    return name, dict(ds.sizes)


specs = sorted(p for p in glob.glob(os.path.join(examples, "*.toml"))
               if "\n[design]" not in open(p).read())  # design specs are not sweeps (tests/design_test.cc)
assert len(specs) >= 10, specs
for src in specs:
    text = coarse(open(src).read())
    spec = tomllib.loads(text)
    small = os.path.join(work, os.path.basename(src))
    open(small, "w").write(text)
    r = subprocess.run([binary, "run", small, "--data", data, "--no-plots", "--quiet", "--json"], capture_output=True,
                       text=True, timeout=600)
    if r.returncode != 0:
        sys.exit("%s: bistable run failed (%d): %s" % (src, r.returncode, r.stderr[-2000:]))
    path = os.path.join(data, "sweeps", json.loads(r.stdout)["id"] + ".h5")
    try:
        name, sizes = check(path, spec)
    except AssertionError as e:
        sys.exit("%s (%s): %s" % (os.path.basename(src), path, e))
    print("ok", os.path.basename(src), sizes, "plotted", name)
print("all %d example maps open in xarray as CF-1.10" % len(specs))
