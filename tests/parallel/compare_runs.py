#!/usr/bin/python3
"""Compare two hybridsim run files (e.g. 1 rank against 2 ranks, or a run against its repeat).

  compare_runs.py steps A.h5 B.h5 --rtol 1e-11 [--etol 6e-11] [--rows N] [--pile-tol 1e-9]
      every row (the first N when given) of /series/force and the part forces agrees within
      rtol relative to the largest |F| of the run, the total energy within etol (default rtol)
      relative to its largest magnitude, the pile height within pile-tol (m), and the bond, particle and
      broken-bond counts exactly (step-by-step agreement); also prints the mean and peak
      horizontal force and the final broken-bond count and largest pile height of each run;
  compare_runs.py same A.h5 B.h5
      every dataset under /series is bit-identical (a repeated run);
  compare_runs.py stats A.h5 B.h5 --tol 0.05
      mean and peak horizontal force on the structure agree within tol (relative).
  compare_runs.py sane A.h5
      one run on its own: every dataset under /series finite; rows contiguous (step strictly
      increasing by the same count every row but the last, time = step x dt with one dt);
      without rigid blocks (no /series/blocks: no conversion) the particle count constant and
      bonds + bonds_broken constant, with them both non-decreasing; bonds_broken non-decreasing.
Prints the figures; exit 1 when they disagree.
"""
import argparse
import sys

import h5py
import numpy as np


def horizontal(f):
    return np.hypot(f[:, 0], f[:, 1])


def datasets(group, prefix=""):
    out = {}
    for k, v in group.items():
        if isinstance(v, h5py.Group):
            out.update(datasets(v, f"{prefix}{k}/"))
        else:
            out[prefix + k] = v[()]
    return out


def print_summary(a, b, rows):
    ha, hb = horizontal(a["series/force"][:rows]), horizontal(b["series/force"][:rows])
    for name, x, y in [("mean", ha.mean(), hb.mean()), ("peak", ha.max(), hb.max())]:
        print(f"horizontal force {name}: {x:.9g} N vs {y:.9g} N, relative difference {abs(x - y) / max(abs(x), 1e-300):.3e}")
    for k in ["series/bonds_broken", "series/pile_height", "series/pile_height_mean"]:
        if k in a:
            print(f"{k}: last {a[k][:rows][-1]} vs {b[k][:rows][-1]}, largest {a[k][:rows].max()} vs {b[k][:rows].max()}")


def sane(path):
    f = h5py.File(path, "r")
    s = f["series"]
    ok = True

    def check(cond, msg):
        nonlocal ok
        print(("ok    " if cond else "FAIL  ") + msg)
        ok &= bool(cond)

    ds = datasets(s)
    bad = [k for k, v in ds.items() if np.issubdtype(v.dtype, np.floating) and not np.isfinite(v).all()]
    check(not bad, f"{len(ds)} datasets finite" + (f" (not: {bad})" if bad else ""))
    t, step = s["time"][()], s["step"][()]
    n = len(t)
    check(n >= 2 and all(len(v) == n for v in ds.values()), f"{n} rows in every dataset")
    ds_ = np.diff(step)
    check((ds_ > 0).all() and (n < 3 or ((ds_[:-1] == ds_[0]).all() and ds_[-1] <= ds_[0])),
          f"steps {step[0]}..{step[-1]}, every {ds_[0] if n > 1 else 0} (last {ds_[-1] if n > 1 else 0})")
    dt = t[-1] / max(step[-1], 1)
    terr = np.abs(t - step * dt).max()
    check((np.diff(t) > 0).all() and terr <= 1e-9 * max(t[-1], 1e-300),
          f"time {t[0]:.6g}..{t[-1]:.6g} s = step x {dt:.6g} s (max difference {terr:.1e} s)")
    p, b, nb = s["particles"][()], s["bonds"][()], s["bonds_broken"][()]
    check((np.diff(nb) >= 0).all(), f"bonds broken non-decreasing, {nb[0]} -> {nb[-1]}")
    if "blocks" in s:
        check((np.diff(p) >= 0).all(), f"particles non-decreasing (conversion only adds), {p[0]} -> {p[-1]}")
        check((np.diff(b + nb) >= 0).all(), f"bonds + broken non-decreasing, {b[0] + nb[0]} -> {b[-1] + nb[-1]}")
    else:
        check((p == p[0]).all(), f"particles conserved ({p[0]}; no blocks, none leaves)")
        check((b + nb == b[0] + nb[0]).all(),
              f"bonds + broken conserved ({b[0] + nb[0]}), bonds {b[0]} -> {b[-1]} non-increasing")
    e = s["energy/total"][()]
    check(np.isfinite(e).all(), f"total energy finite, {e[0]:.6g} -> {e[-1]:.6g} J")
    print("sane" if ok else "NOT SANE")
    return 0 if ok else 1


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "sane":
        return sane(sys.argv[2])
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["steps", "same", "stats"])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--etol", type=float, default=None, help="total energy, relative (default: rtol)")
    ap.add_argument("--tol", type=float, default=0.05)
    ap.add_argument("--rows", type=int, default=0, help="compare only the first N rows (0: all; the files may differ in length)")
    ap.add_argument("--pile-tol", type=float, default=1e-9, help="m")
    args = ap.parse_args()
    a, b = h5py.File(args.a, "r"), h5py.File(args.b, "r")
    ok = True
    na, nb = a["series/time"].shape[0], b["series/time"].shape[0]
    rows = args.rows if args.rows else na
    if (not args.rows and na != nb) or rows > min(na, nb):
        print(f"different row counts: {na} vs {nb} (comparing {rows})")
        return 1
    if args.mode == "same":
        da, db = datasets(a["series"]), datasets(b["series"])
        if sorted(da) != sorted(db):
            print(f"different datasets: {sorted(set(da) ^ set(db))}")
            return 1
        for k in sorted(da):
            same = da[k].shape == db[k].shape and da[k].tobytes() == db[k].tobytes()
            if not same:
                d = np.abs(da[k].astype(float) - db[k].astype(float)).max() if da[k].shape == db[k].shape else "shape"
                print(f"series/{k}: DIFFERS (max difference {d})")
            ok &= same
        print(f"{len(da)} datasets, {na} rows: {'bit-identical' if ok else 'NOT bit-identical'}")
    elif args.mode == "steps":
        ta, tb = a["series/time"][:rows], b["series/time"][:rows]
        dt = np.abs(ta - tb).max()
        print(f"time: {rows} rows to t = {ta[-1]:.6g} s, max difference {dt:.3e} s")
        ok &= dt <= 1e-12 * max(abs(ta[-1]), 1.0)
        fa, fb = a["series/force"][:rows], b["series/force"][:rows]
        scale = max(np.abs(fa).max(), 1e-300)
        worst = np.abs(fa - fb).max() / scale
        print(f"force: max |F| {scale:.6g} N, max |F_a - F_b| / max|F| = {worst:.3e} (limit {args.rtol:g})")
        ok &= worst <= args.rtol
        if "series/parts" in a:
            for p in a["series/parts"]:
                pa, pb = a[f"series/parts/{p}/force"][:rows], b[f"series/parts/{p}/force"][:rows]
                w = np.abs(pa - pb).max() / scale
                print(f"part {p}: {w:.3e}")
                ok &= w <= args.rtol
        for k in ["series/pile_height", "series/pile_height_mean", "series/bonds", "series/particles",
                  "series/bonds_broken"]:
            if k in a:
                xa, xb = a[k][:rows].astype(float), b[k][:rows].astype(float)
                d = np.abs(xa - xb).max()
                lim = args.pile_tol if "pile" in k else 0
                print(f"{k}: max difference {d:.3e} (limit {lim:g})")
                if d > lim:
                    i = int(np.argmax(np.abs(xa - xb) > lim))
                    print(f"  first at row {i}, t = {ta[i]:.6g} s: {xa[i]} vs {xb[i]}")
                ok &= d <= lim
        ea, eb = a["series/energy/total"][:rows], b["series/energy/total"][:rows]
        we = np.abs(ea - eb).max() / max(np.abs(ea).max(), 1e-300)
        etol = args.rtol if args.etol is None else args.etol
        print(f"total energy: max relative difference {we:.3e} (limit {etol:g})")
        ok &= we <= etol
        print_summary(a, b, rows)
    else:
        ha, hb = horizontal(a["series/force"][:]), horizontal(b["series/force"][:])
        for name, x, y in [("mean", ha.mean(), hb.mean()), ("peak", ha.max(), hb.max())]:
            rel = abs(x - y) / max(abs(x), 1e-300)
            print(f"horizontal force {name}: {x:.6g} N vs {y:.6g} N, relative difference {rel:.3%} "
                  f"(limit {args.tol:.0%})")
            ok &= rel <= args.tol
        for k in ["series/bonds_broken", "series/pile_height"]:
            x, y = a[k][-1], b[k][-1]
            print(f"{k} at the end: {x} vs {y}")
    print("agree" if ok else "DISAGREE")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
