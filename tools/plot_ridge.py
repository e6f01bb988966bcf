#!/usr/bin/python3
"""Plot a ridge file written by hs::rigid::save_ridge (docs/ridge.md).

Usage: tools/plot_ridge.py ridge.h5 [-o PREFIX] [--slab Y0 Y1]

Writes PREFIX_side.png (x-z: blocks within the y slab drawn as their rotated outlines,
i.e. the cross-section of each box's projection; level ice and consolidated layer; target
and achieved keel/sail profiles) and PREFIX_top.png (x-y: keel blocks shaded by depth,
sail blocks outlined) and PREFIX_tilt.png (histogram of the keel blocks' inclination:
angle between a block's thickness axis and the vertical, 0 = lying flat, 90 = on edge;
the median is printed). PREFIX defaults to the file name without extension.
"""
import argparse
import json
import os

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402


def rotmat(q):
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)


def hull2d(p):
    """Convex hull (monotone chain) of 2-D points, counter-clockwise."""
    p = sorted(map(tuple, p))
    if len(p) < 3:
        return np.array(p)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for q in p:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], q) <= 0:
            lower.pop()
        lower.append(q)
    for q in reversed(p):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], q) <= 0:
            upper.pop()
        upper.append(q)
    return np.array(lower[:-1] + upper[:-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ridge")
    ap.add_argument("-o", "--prefix")
    ap.add_argument("--slab", nargs=2, type=float, metavar=("Y0", "Y1"),
                    help="y range of blocks in the side view (default: a 4 m slab in the middle)")
    a = ap.parse_args()
    prefix = a.prefix or os.path.splitext(a.ridge)[0]

    with h5py.File(a.ridge, "r") as f:
        g = f["ridge"]
        definition = json.loads(g.attrs["definition"])
        report = json.loads(g.attrs["report"])
        he = g["blocks/half_extents"][()].reshape(-1, 3)
        pos = g["blocks/position"][()].reshape(-1, 3)
        quat = g["blocks/orientation"][()].reshape(-1, 4)
        part = g["blocks/part"][()]
        ice_he = g["ice/half_extents"][()].reshape(-1, 3)
        ice_pos = g["ice/position"][()].reshape(-1, 3)
        ice_part = g["ice/part"][()]
        px = g["profile/x"][()]
        keel_t = g["profile/keel_target"][()]
        keel_a = g["profile/keel_depth"][()]
        sail_t = g["profile/sail_target"][()]
        sail_a = g["profile/sail_height"][()]

    length = definition["length"]
    y0, y1 = a.slab if a.slab else (0.5 * length - 2.0, 0.5 * length + 2.0)
    corners = [pos[i] + (rotmat(quat[i]) @ (CORNERS * he[i]).T).T for i in range(len(pos))]

    # ---- side view
    fig, ax = plt.subplots(figsize=(14, 5))
    for k in range(len(ice_pos)):
        x0, z0 = ice_pos[k][0] - ice_he[k][0], ice_pos[k][2] - ice_he[k][2]
        ax.add_patch(plt.Rectangle((x0, z0), 2 * ice_he[k][0], 2 * ice_he[k][2],
                                   color="#9ecae1" if ice_part[k] == 0 else "#4292c6", zorder=1,
                                   label="level ice" if ice_part[k] == 0 else "consolidated layer"))
    sel = [i for i in range(len(pos)) if y0 <= pos[i][1] <= y1]
    polys = [hull2d(corners[i][:, [0, 2]]) for i in sel]
    colors = ["#bdbdbd" if part[i] == 0 else "#fdae6b" for i in sel]
    ax.add_collection(PolyCollection(polys, facecolors=colors, edgecolors="k", linewidths=0.3, zorder=2))
    ax.plot(px, -keel_t, "r-", lw=1.5, label="target keel", zorder=3)
    ax.plot(px, -keel_a, "b--", lw=1.2, label="achieved keel (p95 of block bottoms)", zorder=3)
    if np.any(sail_t > 0):
        ax.plot(px, sail_t, "r-", lw=1.5, zorder=3)
        ax.plot(px, sail_a, "b--", lw=1.2, zorder=3)
    ax.axhline(0.0, color="c", lw=0.8, label="waterline")
    xmax = max(abs(ice_pos[:, 0] - ice_he[:, 0]).max(), abs(ice_pos[:, 0] + ice_he[:, 0]).max())
    ax.set_xlim(-xmax, xmax)
    zlo = min(-keel_t.max(), -keel_a.max(), (pos[:, 2] - he.max(axis=1)).min()) - 1.0
    zhi = max(sail_t.max(), sail_a.max(), 1.0) + 1.0
    ax.set_ylim(zlo, zhi)
    ax.set_xlabel("x across the ridge [m]")
    ax.set_ylabel("z [m]")
    ax.set_aspect("auto")
    handles, labels = ax.get_legend_handles_labels()
    uniq = dict(zip(labels, handles))
    ax.legend(uniq.values(), uniq.keys(), loc="lower right", fontsize=8)
    ax.set_title("%s: %d blocks (%d in %.1f<y<%.1f m shown), porosity %.2f, keel %.2f of %.2f m" % (
        definition.get("name") or os.path.basename(a.ridge), len(pos), len(sel), y0, y1,
        report["keel_porosity"], report["keel_depth_m"]["achieved_p95"], report["keel_depth_m"]["target"]))
    fig.tight_layout()
    fig.savefig(prefix + "_side.png", dpi=130)
    plt.close(fig)

    # ---- top view
    fig, ax = plt.subplots(figsize=(10, 10 * min(2.0, max(0.3, length / (2 * xmax)))))
    keel = [i for i in range(len(pos)) if part[i] == 0]
    sail = [i for i in range(len(pos)) if part[i] == 1]
    kp = [hull2d(corners[i][:, [0, 1]]) for i in keel]
    depth = np.array([-(corners[i][:, 2].min()) for i in keel])
    pc = PolyCollection(kp, array=depth, cmap="viridis_r", edgecolors="k", linewidths=0.1)
    ax.add_collection(pc)
    fig.colorbar(pc, ax=ax, label="block bottom depth [m]")
    sp = [hull2d(corners[i][:, [0, 1]]) for i in sail]
    ax.add_collection(PolyCollection(sp, facecolors="none", edgecolors="#e6550d", linewidths=0.4))
    for k in range(len(ice_pos)):
        if ice_part[k] == 1:
            ax.axvline(ice_pos[k][0] - ice_he[k][0], color="#4292c6", ls=":")
            ax.axvline(ice_pos[k][0] + ice_he[k][0], color="#4292c6", ls=":")
    ax.set_xlim(-xmax, xmax)
    ax.set_ylim(0, length)
    ax.set_aspect("equal")
    ax.set_xlabel("x across the ridge [m]")
    ax.set_ylabel("y along the ridge [m]")
    ax.set_title("top view: keel blocks (colour: depth), sail blocks (orange outlines)")
    fig.tight_layout()
    fig.savefig(prefix + "_top.png", dpi=110)
    plt.close(fig)
    # ---- keel block inclination
    tilt = np.array([np.degrees(np.arccos(min(1.0, abs(rotmat(quat[i])[2, 2])))) for i in keel])
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.hist(tilt, bins=np.arange(0, 91, 5), color="#bdbdbd", edgecolor="k")
    ax.set_xlabel("keel block inclination [deg] (0: flat, 90: on edge)")
    ax.set_ylabel("blocks")
    ax.set_title("median %.0f deg, %.0f %% above 60 deg" % (np.median(tilt), 100.0 * np.mean(tilt > 60.0)))
    fig.tight_layout()
    fig.savefig(prefix + "_tilt.png", dpi=110)
    plt.close(fig)
    print(prefix + "_side.png", prefix + "_top.png", prefix + "_tilt.png",
          "keel inclination median %.1f deg, >60 deg: %.1f %%" % (np.median(tilt), 100.0 * np.mean(tilt > 60.0)))


if __name__ == "__main__":
    main()
