#!/usr/bin/env python3
"""The at-rest check of a run file (issue 15, docs/bridge.md "Relaxation"): freeze joints and
block-particle freeze bonds broken, conversions, the fastest block and particle at the end, and
the sheet's mean vertical displacement from t = 0 (first to last snapshot, particles matched by
global id; --sheet N takes only ids < N, the particles built before any conversion).

  /usr/bin/python3 tools/rest_check.py run.h5 [--sheet N] [--limits]

With --limits it exits 1 unless: no joints or freeze bonds broken, no conversions (unless the run's
mode is all_at_start), every block and every particle slower than 0.01 m/s on average (path length / time) over the
run's last 0.1 s (rest_window; the speeds at the last step are printed beside them; files from
before that figure are judged by the last step), |mean dz| < 0.02 m.
"""
import argparse
import sys

import h5py
import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run")
    ap.add_argument("--sheet", type=int, default=None)
    ap.add_argument("--limits", action="store_true")
    a = ap.parse_args()
    with h5py.File(a.run, "r") as f:
        snaps = sorted(k for k in f["snapshots"].keys() if k.isdigit())
        s0, s1 = f["snapshots"][snaps[0]], f["snapshots"][snaps[-1]]
        g0, g1 = s0["global_id"][:].ravel(), s1["global_id"][:].ravel()
        z0 = dict(zip(g0.tolist(), s0["position"][:, 2].tolist()))
        x1, v1 = s1["position"][:], s1["velocity"][:]
        keep = np.array([g in z0 and (a.sheet is None or g < a.sheet) for g in g1.tolist()])
        dz = np.array([x1[k, 2] - z0[g] for k, g in enumerate(g1.tolist()) if keep[k]])
        h = f["analysis/hybrid"].attrs
        conv = h["conversion"] if "conversion" in h else "?"
        conv = conv.decode() if isinstance(conv, bytes) else str(conv)
        # rest_window 0 (or absent): the run measured no window (no rigid block, or an older file)
        windowed = "final_mean_particle_speed" in h and float(h["rest_window"]) > 0
        out = {
            "mode": conv,
            "t_end": float(s1.attrs["time"]) if "time" in s1.attrs else float("nan"),
            "joints_broken": int(np.ravel(f["series/blocks/joints_broken"][-1])[0]),
            "freeze_bonds_broken": int(h["freeze_bonds_broken"]),
            "conversions": int(np.ravel(f["series/blocks/conversions"][-1])[0]),
            "lattice_bonds_broken": int(np.ravel(f["series/bonds_broken"][-1])[0]),
            # The at-rest block figure: the largest mean speed of a block over the run's last
            # rest_window s (0.1 s; docs/bridge.md "Relaxation"); files from before it have only
            # the speed at the last step, which one-step contact hiccups can inflate.
            "max_block_speed": float(h["final_mean_block_speed"] if windowed else h["final_max_block_speed"]),
            "rest_window": float(h["rest_window"]) if "rest_window" in h else 0.0,
            "max_block_speed_last_step": float(h["final_max_block_speed"]),
            # Likewise for the particles (those bonded to a block follow its one-step turns).
            "max_particle_speed": float(h["final_mean_particle_speed"] if windowed
                                        else np.sqrt((v1 ** 2).sum(axis=1)).max()),
            "max_particle_speed_last_step": float(np.sqrt((v1 ** 2).sum(axis=1)).max()),
            "sheet_mean_dz": float(dz.mean()) if dz.size else 0.0,
            "sheet_max_abs_dz": float(np.abs(dz).max()) if dz.size else 0.0,
        }
        if "analysis/relaxation" in f:
            r = f["analysis/relaxation"].attrs
            out["relax_time"] = float(r["time"])
            out["relax_converged"] = int(r["converged"])
            if "jointed_time" in r and float(r["jointed_time"]) > 0:
                out["relax_jointed_time"] = float(r["jointed_time"])
                if "at_rest" in r:
                    out["relax_at_rest"] = int(r["at_rest"])
                out["relax_joints_overloaded"] = int(r["joints_overloaded"])
    for k, v in out.items():
        print(f"{k:22s} {v}")
    if a.limits:
        ok = (out["joints_broken"] == 0 and out["freeze_bonds_broken"] == 0
              and (out["conversions"] == 0 or out["mode"] == "all_at_start")
              and out["max_block_speed"] < 0.01 and out["max_particle_speed"] < 0.01
              and abs(out["sheet_mean_dz"]) < 0.02)
        print("at rest:", "yes" if ok else "NO")
        return 0 if ok else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
