#!/usr/bin/python3
"""Top and side views of one particle snapshot of a run, coloured by intact bonds.

    tools/plot_snapshot.py RUN.h5 [--index K] [--band 1.0] [-o OUT.png]

K is the snapshot index (default: the last one); the side view shows particles within
--band metres of y = 0 (the pier axis plane in the cone scenes). Cracks show up as lines
of particles with fewer than 12 bonds; loose rubble as particles with none.
"""
import argparse
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run")
    ap.add_argument("--index", type=int, default=-1)
    ap.add_argument("--band", type=float, default=1.0)
    ap.add_argument("-o", "--output")
    a = ap.parse_args()
    try:
        f = h5py.File(a.run, "r")
    except OSError as e:
        sys.exit(f"error: {a.run}: cannot open ({e})")
    if "snapshots" not in f:
        sys.exit(f"error: {a.run}: no /snapshots group (set time.snapshot_interval > 0 in the scene)")
    names = sorted(k for k in f["snapshots"].keys() if k.isdigit())
    if not names:
        sys.exit(f"error: {a.run}: the run wrote no snapshot")
    g = f["snapshots"][names[a.index]]
    x, bonds = g["position"][:], g["bond_count"][:]
    t = float(g.attrs["time"])
    fig, ax = plt.subplots(1, 2, figsize=(15, 6), gridspec_kw={"width_ratios": [1, 1.6]})
    sc = ax[0].scatter(x[:, 0], x[:, 1], c=bonds, s=2, cmap="viridis", vmin=0, vmax=12)
    ax[0].set(aspect="equal", xlabel="x [m]", ylabel="y [m]", title=f"top view, t = {t:.2f} s")
    sel = np.abs(x[:, 1]) < a.band
    ax[1].scatter(x[sel, 0], x[sel, 2], c=bonds[sel], s=4, cmap="viridis", vmin=0, vmax=12)
    ax[1].set(aspect="equal", xlabel="x [m]", ylabel="z [m]", title=f"side view, |y| < {a.band} m")
    fig.colorbar(sc, ax=ax, label="intact bonds per particle", shrink=0.8)
    out = a.output or a.run.rsplit(".", 1)[0] + f"_snapshot_{names[a.index]}.png"
    fig.savefig(out, dpi=100)
    print(out)


if __name__ == "__main__":
    main()
