#!/usr/bin/python3
"""Opens a bistable-sweep map file with h5py (Debian's python3-h5py) and checks the obvious shapes.

usage: h5py_check.py FILE.h5 N_ALPHA N_OMEGA
"""
import sys

import h5py
import numpy as np

path, na, nw = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
with h5py.File(path, "r") as f:
    assert f.attrs["axes"] == "alpha,omega", f.attrs["axes"]
    assert f.attrs["numerics_version"], "numerics_version missing"
    assert "model" in f.attrs and "spec" in f.attrs
    for name in ("frf_db", "lle", "motion", "period", "edr_t", "hd_index"):
        d = f[name]
        assert d.shape == (na, nw), (name, d.shape)
        assert d.dims[0].label == "alpha" and d.dims[1].label == "omega", (name, d.dims[0].label)
        assert np.allclose(d.dims[0][0][:], f["alpha"][:]) and np.allclose(d.dims[1][0][:], f["omega"][:])
        assert d.attrs["definition"] and d.attrs["long_name"], name
        # CF: codes carry flags; scaled dimensionless quantities no units (CF 3.1) but their scale in `unit` (xarray's label)
        assert isinstance(d.attrs.get("units"), str) or isinstance(d.attrs.get("unit"), str) or len(d.attrs["flag_values"]) > 1, name
        assert d.chunks is not None and d.compression == "gzip", (name, d.chunks, d.compression)
    assert "units" not in f["alpha"].attrs and f["alpha"].attrs["unit"] == f["alpha"].attrs["unit_label"] == "A0/delta_s"
    assert f["frf_db"].attrs["units"] == "dB" and f["lle"].attrs["unit"] == "1/tau" and f["edr_t"].attrs["units"] == "percent"
    assert f.attrs["Conventions"] == "CF-1.10"
    assert f["hd_peak_freq"].shape == (na, nw, 10)
    assert set(np.unique(f["motion"][:])) <= {-1, 0, 1, 2}
    assert np.isfinite(f["frf_db"][:]).all()
print("ok", path)
