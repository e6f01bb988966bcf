#!/usr/bin/python3
"""Stores the /series of a hybridsim run file as a reference, or compares a run with one.

    /usr/bin/python3 tools/series_reference.py write out.h5 ref.json
    /usr/bin/python3 tools/series_reference.py compare out.h5 ref.json [--tol 1e-9] [-v]

A reference holds every numeric dataset under /series (values as exact decimal strings, so a
reference written by one build reads back bit for bit). `compare` measures, per dataset,
max |run - ref| / max(|ref|, tiny) over the rows (NaN where the reference has NaN counts as
equal, NaN elsewhere as a difference of inf), prints the largest, and exits 1 when it is above
--tol or when a dataset is missing or has another shape. PinnedRun uses it for builds whose
fingerprint has no pinned hash: their results must agree with the stored ones to round-off.
"""
import argparse
import json
import math
import sys

import h5py
import numpy as np


def series(path):
    out = {}
    with h5py.File(path, "r") as f:
        if "series" not in f:
            sys.exit(f"series_reference: {path} has no /series group")
        for name in sorted(f["series"].keys()):
            d = f["series"][name]
            if isinstance(d, h5py.Dataset) and d.dtype.kind in "fiu":
                out[name] = np.asarray(d[()], dtype=np.float64)
    return out


def write(run, ref):
    data = {k: {"shape": list(v.shape), "values": [repr(float(x)) for x in v.ravel()]} for k, v in series(run).items()}
    with open(ref, "w") as f:
        json.dump({"source": run.split("/")[-1], "series": data}, f, indent=0)
        f.write("\n")
    print(f"series_reference: {len(data)} datasets of {run} written to {ref}")


def compare(run, ref, tol, verbose):
    with open(ref) as f:
        stored = json.load(f)["series"]
    got = series(run)
    worst, worst_name, bad = 0.0, "", []
    for name, s in sorted(stored.items()):
        want = np.array([float(x) for x in s["values"]], dtype=np.float64).reshape(s["shape"])
        if name not in got:
            bad.append(f"{name}: missing from the run")
            continue
        have = got[name]
        if have.shape != want.shape:
            bad.append(f"{name}: shape {have.shape}, reference {want.shape}")
            continue
        both_nan = np.isnan(have) & np.isnan(want)
        diff = np.where(both_nan, 0.0, np.abs(have - want))
        diff = np.where(np.isnan(diff), math.inf, diff)
        scale = max(float(np.nanmax(np.abs(want))) if want.size and not np.all(np.isnan(want)) else 0.0, 1e-300)
        rel = float(diff.max() / scale) if diff.size else 0.0
        if verbose:
            print(f"{rel:.3e}  {name} {have.shape}")
        if rel > worst:
            worst, worst_name = rel, name
    for b in bad:
        print(f"series_reference: {b}")
    print(f"series_reference: largest relative difference {worst:.3e} ({worst_name or '-'}), tolerance {tol:.1e}")
    return 1 if bad or worst > tol else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["write", "compare"])
    ap.add_argument("run")
    ap.add_argument("reference")
    ap.add_argument("--tol", type=float, default=1e-9, help="largest relative difference allowed (compare)")
    ap.add_argument("-v", "--verbose", action="store_true", help="one line per dataset (compare)")
    a = ap.parse_args()
    if a.mode == "write":
        write(a.run, a.reference)
        return 0
    return compare(a.run, a.reference, a.tol, a.verbose)


if __name__ == "__main__":
    sys.exit(main())
