#!/usr/bin/python3
"""Compares two bistable-sweep HDF5 maps: every dataset's shape, dtype and values bit for bit, and
every attribute (object references by the path they point to). Attributes that record when, where or
how a file was made (a map merged from shards) may differ legitimately; those whose names say so are skipped
and listed.

usage: deploy/compare-maps.py A.h5 B.h5   → one line of figures; exit 0 when identical, 1 otherwise
Needs h5py and numpy (Debian's python3-h5py, python3-numpy): run it with /usr/bin/python3.
"""
import re
import sys

import h5py
import numpy as np

# Names of when/where/how-made attributes ("created_at", "creation_time", "hostname", "wall_seconds", CF's
# "history", a merged map's "merged_from_shards", ...); "time_unit" and the like are compared.
SKIP = re.compile(r"(^|_)(created|creation|timestamp|date|datetime|host|hostname|pid|elapsed|wall|history|merged)(_|$)|(^|_)(time|seconds)$",
                  re.IGNORECASE)


def collect(f):
    datasets, attrs = {}, {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            datasets[name] = obj
        for key in obj.attrs:
            attrs[(name, key)] = obj

    for key in f.attrs:
        attrs[("/", key)] = f
    f.visititems(visit)
    return datasets, attrs


def normal(f, value):
    """An attribute's value with object references replaced by the paths they name."""
    if isinstance(value, h5py.Reference):
        return ("ref", f[value].name if value else None)
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "O":
            return ("array", value.shape, tuple(normal(f, v) for v in value.flat))
        if value.dtype.fields:  # compound (e.g. REFERENCE_LIST: reference + index)
            return ("compound", value.shape, tuple(tuple(normal(f, v) for v in row) for row in value.flat))
        return ("array", value.shape, value.dtype.str, value.tobytes())
    if isinstance(value, (bytes, str, int, float, np.generic)):
        return ("scalar", type(value).__name__, value.tobytes() if isinstance(value, np.generic) else value)
    if isinstance(value, tuple):
        return tuple(normal(f, v) for v in value)
    return ("other", repr(value))


def main():
    a, b = sys.argv[1], sys.argv[2]
    problems = []
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        da, aa = collect(fa)
        db, ab = collect(fb)
        if set(da) != set(db):
            problems.append(f"datasets differ: only in A {sorted(set(da) - set(db))}, only in B {sorted(set(db) - set(da))}")
        values = 0
        for name in sorted(set(da) & set(db)):
            x, y = da[name], db[name]
            if x.shape != y.shape or x.dtype != y.dtype:
                problems.append(f"{name}: {x.shape} {x.dtype} vs {y.shape} {y.dtype}")
                continue
            vx, vy = x[()], y[()]
            if isinstance(vx, np.ndarray) and vx.dtype.kind != "O":
                same = vx.tobytes() == vy.tobytes()
                values += vx.size
            else:
                same = normal(fa, vx) == normal(fb, vy)
                values += getattr(vx, "size", 1)
            if not same:
                problems.append(f"{name}: values differ")
        skipped = sorted({key for (_, key) in set(aa) | set(ab) if SKIP.search(key)})
        compared = 0
        for where, key in sorted(set(aa) | set(ab)):
            if SKIP.search(key):
                continue
            if (where, key) not in aa or (where, key) not in ab:
                problems.append(f"attribute {where}@{key} only in one file")
                continue
            compared += 1
            if normal(fa, aa[(where, key)].attrs[key]) != normal(fb, ab[(where, key)].attrs[key]):
                problems.append(f"attribute {where}@{key} differs")
    figures = (f"{len(db)} datasets ({values} values) identical in shape, dtype and bits; {compared} attributes equal"
               f" (references by target); skipped attributes: {', '.join(skipped) if skipped else 'none present'}")
    if problems:
        print("DIFFERENT: " + "; ".join(problems[:5]) + (f" (+{len(problems) - 5} more)" if len(problems) > 5 else ""))
        return 1
    print(figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
