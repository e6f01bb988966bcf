#!/usr/bin/python3
"""Hashes the datasets of a hybridsim HDF5 file, to check that a change leaves results
bit-identical (the refactoring check of issue 12).

    /usr/bin/python3 tools/series_hash.py out.h5 [--group /series] [--all] [-v]

Prints one SHA-256 over every dataset under the group (default: /series of a run file; for a
ridge file use --group / ), taken in sorted path order over the raw bytes, dtype and shape,
and with -v one line per dataset. Attributes are not hashed: they hold wall times and dates;
nor is /analysis/cost, the run's wall time by phase (docs/output.md).
"""
import argparse
import hashlib
import sys

import h5py
import numpy as np


# Groups whose datasets are wall times: they differ from run to run by design.
WALL_TIME_GROUPS = {"/analysis/cost"}


def datasets(group, prefix):
    out = []
    for name in sorted(group.keys()):
        obj = group[name]
        path = f"{prefix.rstrip('/')}/{name}"
        if path in WALL_TIME_GROUPS:
            continue
        if isinstance(obj, h5py.Group):
            out += datasets(obj, path)
        elif isinstance(obj, h5py.Dataset):
            out.append((path, obj))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file")
    ap.add_argument("--group", default="/series", help="group to hash (default /series)")
    ap.add_argument("-v", "--verbose", action="store_true", help="one line per dataset")
    a = ap.parse_args()
    total = hashlib.sha256()
    with h5py.File(a.file, "r") as f:
        if a.group not in f:
            sys.exit(f"series_hash: {a.file} has no group {a.group}")
        for path, d in datasets(f[a.group], a.group):
            data = np.ascontiguousarray(d[()])
            h = hashlib.sha256()
            h.update(f"{path}|{data.dtype.str}|{data.shape}".encode())
            h.update(data.tobytes())
            total.update(h.digest())
            if a.verbose:
                print(f"{h.hexdigest()[:16]}  {path} {data.shape}")
    print(f"{total.hexdigest()}  {a.file}:{a.group}")


if __name__ == "__main__":
    main()
