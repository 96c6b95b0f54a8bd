#!/usr/bin/python3
"""Executes every example notebook (examples/*.ipynb) with Debian's nbclient, as Jupyter would (issue 43).

usage: run_notebooks.py EXAMPLES_DIR WORK_DIR

Each notebook runs in a folder of its own under WORK_DIR, beside a copy of the example specs (a notebook
names its spec relative to itself, as in Jupyter), in the `python3` kernel (Debian's ipykernel:
/usr/bin/python3) with this process's environment (PYTHONPATH at the build tree's module, or the module
installed). A cell that raises fails the notebook (nbclient's CellExecutionError); so does a notebook
that draws no figure. First, a notebook whose cell raises must fail here: the harness can fail.
"""
import glob
import os
import shutil
import sys
import time

import nbclient
import nbformat
from nbclient.exceptions import CellExecutionError

examples, work = sys.argv[1], sys.argv[2]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)


def execute(nb, cwd):
    client = nbclient.NotebookClient(nb, kernel_name="python3", timeout=900, resources={"metadata": {"path": cwd}})
    client.execute()  # raises CellExecutionError on the first cell that raises
    return nb


# The harness fails on a raising cell.
bad = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("x = 1"), nbformat.v4.new_code_cell("raise RuntimeError('boom')")])
try:
    execute(bad, work)
    sys.exit("a notebook whose cell raises was not reported as failing")
except CellExecutionError as e:
    assert "boom" in str(e), e

notebooks = sorted(glob.glob(os.path.join(examples, "*.ipynb")))
assert len(notebooks) >= 2, notebooks
for path in notebooks:
    name = os.path.splitext(os.path.basename(path))[0]
    cwd = os.path.join(work, name)
    os.makedirs(cwd)
    for spec in glob.glob(os.path.join(examples, "*.toml")):
        shutil.copy(spec, cwd)
    nb = nbformat.read(path, as_version=4)
    assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code"), "%s is committed with outputs" % path
    t = time.monotonic()
    try:
        execute(nb, cwd)
    except CellExecutionError as e:
        sys.exit("%s: a cell raised:\n%s" % (path, e))
    figures = sum(1 for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {}))
    assert figures >= 2, "%s drew %d figures" % (path, figures)
    nbformat.write(nb, os.path.join(cwd, name + ".executed.ipynb"))
    print("ok %s: %d cells, %d figures, %.1f s" % (os.path.basename(path), len(nb.cells), figures, time.monotonic() - t))
