#!/usr/bin/env python3
"""Which freeze joints between blocks a run has broken, read from its checkpoint (docs/bridge.md,
"Relaxation"): each joint's blocks, area, anchor and the blocks' sizes, from the ridge file.

  /usr/bin/python3 tools/broken_joints.py RUN.ckpt.h5 RIDGE.h5 [--keep-loose]

The rigid world's joint slots are the ridge file's joints between blocks in file order, after the
run's filters; this script applies the loose-block one (blocks.loose_blocks = "drop", the default;
--keep-loose for "keep"). It refuses a scene whose keep_x / keep_y / keep_sail or pier left blocks
out (the slot counts then differ). A joint record is 128 bytes (RigidWorld checkpoint,
JointRecord: generation, alive, broken, has_constraint as uint32, tension and shear in N, then
the constraint feedback; tension and shear are the last load measured, the one that broke it);
the one-rank checkpoint's rank_0 is read.
"""
import argparse
import sys

import h5py
import numpy as np

RECORD = 128


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("checkpoint")
    ap.add_argument("ridge")
    ap.add_argument("--keep-loose", action="store_true")
    a = ap.parse_args()
    with h5py.File(a.ridge, "r") as f:
        jb = f["ridge/joints/blocks"][:]
        anchor = f["ridge/joints/anchor"][:]
        area = f["ridge/joints/area"][:]
        half = f["ridge/blocks/half_extents"][:]
    jointed = np.zeros(len(half), bool)
    for i, j in jb:
        jointed[i] = True
        if j >= 0:
            jointed[j] = True
    if a.keep_loose:
        jointed[:] = True
    slots = [k for k, (i, j) in enumerate(jb) if j >= 0 and jointed[i] and jointed[j]]
    with h5py.File(a.checkpoint, "r") as c:
        raw = c["checkpoint/rank_0/hybrid/rigid/joints"][:].tobytes()
    if len(raw) % RECORD or len(raw) // RECORD != len(slots):
        sys.exit(f"{len(raw) / RECORD:g} joint slots in the checkpoint but {len(slots)} block joints in the "
                 "ridge file after the loose-block filter: another filter (keep_x, keep_y, keep_sail, the pier) "
                 "or another record size")
    rec = np.frombuffer(raw, dtype=np.uint8).reshape(-1, RECORD)
    flags = rec[:, :16].copy().view(np.uint32).reshape(-1, 4)
    load = rec[:, 16:32].copy().view(np.float64).reshape(-1, 2)
    broken = np.nonzero(flags[:, 2])[0]
    areas = area[slots]
    print(f"{len(slots)} joints, {len(broken)} broken; area of all: median {np.median(areas):.3f} m^2, "
          f"10th percentile {np.percentile(areas, 10):.3f} m^2; of the broken: median "
          f"{np.median(areas[broken]) if len(broken) else float('nan'):.3f} m^2")
    print("ridge_joint  block_a  block_b  area_m2  anchor_x  anchor_y  anchor_z  size_a_m  size_b_m  tension_N  shear_N")
    for s in broken:
        k = slots[s]
        i, j = jb[k]
        print(f"{k:11d}  {i:7d}  {j:7d}  {area[k]:7.3f}  {anchor[k][0]:8.2f}  {anchor[k][1]:8.2f}  "
              f"{anchor[k][2]:8.2f}  {'x'.join(f'{v:.1f}' for v in 2 * half[i]):>8s}  "
              f"{'x'.join(f'{v:.1f}' for v in 2 * half[j]):>8s}  {load[s][0]:9.4g}  {load[s][1]:7.4g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
