#!/usr/bin/env bash
# `pip install .` as docs/python.md says (issue 43), checked from a fresh venv and another directory:
# Debian's python3 -m venv --system-site-packages (its pip is Debian's python3-pip-whl), then
# pip install --no-build-isolation --no-index (nothing downloaded; --isolated: no pip configuration of the
# machine either). setup.py builds bistable._core with the project's CMake in BISTABLE_BUILD_DIR (this build
# folder: built already, so only the packaging runs). The package is installed from a copy of setup.py,
# pyproject.toml, CMakeLists.txt and python/bistable/, so pip's scratch stays out of the source tree.
# Then, from another directory and without PYTHONPATH, the venv's python3 imports the installed module
# (not the build tree's), which runs a sweep and draws labelled figures.
#
# usage: pip_install.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build=$1 source=$2 work=$3
rm -rf "$work"
mkdir -p "$work/src/python" "$work/elsewhere"
cp "$source/setup.py" "$source/pyproject.toml" "$source/CMakeLists.txt" "$work/src/"
cp -r "$source/python/bistable" "$work/src/python/"
/usr/bin/python3 -m venv --system-site-packages "$work/venv"
BISTABLE_BUILD_DIR="$build" "$work/venv/bin/python3" -m pip install --isolated --no-build-isolation --no-index \
  "$work/src"
cd "$work/elsewhere"
env -u PYTHONPATH MPLBACKEND=Agg "$work/venv/bin/python3" - "$work" "$source" <<'PY'
import importlib.metadata
import os
import re
import sys

import matplotlib.pyplot as plt
import numpy as np

import bistable

work, source = sys.argv[1], sys.argv[2]
site = os.path.join(work, "venv", "lib")
assert bistable.__file__.startswith(site) and bistable._core.__file__.startswith(site), (bistable.__file__, bistable._core.__file__)
project = re.search(r"project\(bistable_sweep VERSION (\S+)", open(os.path.join(source, "CMakeLists.txt")).read()).group(1)
assert bistable.__version__ == importlib.metadata.version("bistable") == project, (bistable.__version__, project)
spec = {"name": "pip install check", "model": "coupled",
        "axes": {"alpha": {"linspace": [0.5, 1.5, 4]}, "omega": {"linspace": [0.8, 1.4, 5]}},
        "integration": {"t_end": 200.0, "t_keep": 100.0}}
ds = bistable.run(spec, data=os.path.join(work, "data"))
assert ds.attrs["software_version"] == project
q = ds.frf_db.plot(x="omega")
frf_label = q.colorbar.ax.get_ylabel().replace("\n", " ")
assert frf_label.endswith(" [dB]"), frf_label
plt.savefig(os.path.join(work, "frf_db.png"))
plt.close("all")
m = bistable.plot(ds.motion, x="omega")
names = [t.get_text() for t in m.colorbar.ax.get_yticklabels()]
assert names == ds.motion.attrs["flag_meanings"].split(), names
plt.savefig(os.path.join(work, "motion.png"))
print("installed", bistable.__file__, "version", bistable.__version__, "| frf_db:", repr(frf_label), "| motion:", names)
PY
