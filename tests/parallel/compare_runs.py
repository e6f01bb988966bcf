#!/usr/bin/python3
"""Compare two hybridsim run files (e.g. 1 rank against 2 ranks).

  compare_runs.py steps A.h5 B.h5 --rtol 1e-6
      every row of /series/force (and the part forces, pile height, bond and particle counts)
      agrees within rtol relative to the largest |F| of the run (step-by-step agreement);
  compare_runs.py stats A.h5 B.h5 --tol 0.05
      mean and peak horizontal force on the structure agree within tol (relative): the
      statistical agreement of a whole run, where rounding differences have grown chaotically.
Prints the figures; exit 1 when they disagree.
"""
import argparse
import sys

import h5py
import numpy as np


def horizontal(f):
    return np.hypot(f[:, 0], f[:, 1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["steps", "stats"])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--tol", type=float, default=0.05)
    args = ap.parse_args()
    a, b = h5py.File(args.a, "r"), h5py.File(args.b, "r")
    ok = True
    if a["series/time"].shape != b["series/time"].shape:
        print(f"different row counts: {a['series/time'].shape} vs {b['series/time'].shape}")
        return 1
    if args.mode == "steps":
        fa, fb = a["series/force"][:], b["series/force"][:]
        scale = max(np.abs(fa).max(), 1e-300)
        worst = np.abs(fa - fb).max() / scale
        print(f"force: {fa.shape[0]} rows, max |F| {scale:.6g} N, max |F_a - F_b| / max|F| = {worst:.3e} "
              f"(limit {args.rtol:g})")
        ok &= worst <= args.rtol
        if "series/parts" in a:
            for p in a["series/parts"]:
                pa, pb = a[f"series/parts/{p}/force"][:], b[f"series/parts/{p}/force"][:]
                w = np.abs(pa - pb).max() / scale
                print(f"part {p}: {w:.3e}")
                ok &= w <= args.rtol
        for k in ["series/pile_height", "series/bonds", "series/particles", "series/bonds_broken"]:
            if k in a:
                d = np.abs(a[k][:].astype(float) - b[k][:].astype(float)).max()
                print(f"{k}: max difference {d:.3e}")
                ok &= d <= (1e-9 if "pile" in k else 0)
        ea, eb = a["series/energy/total"][:], b["series/energy/total"][:]
        we = np.abs(ea - eb).max() / max(np.abs(ea).max(), 1e-300)
        print(f"total energy: max relative difference {we:.3e}")
        ok &= we <= args.rtol
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
