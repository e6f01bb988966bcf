#!/usr/bin/python3
"""Generate a shipped ridge scene and check its porosity against the README's claim.

  check_ridge_porosity.py HYBRIDSIM SCENE.json OUT.h5 --min 0.34 --max 0.42

Runs `HYBRIDSIM ridge SCENE.json -o OUT.h5`, reads the ridge's stats (/ridge attribute
"stats", JSON) and checks that the keel porosity and the consolidated-core porosity both lie in
[min, max] (README: "keel porosity 0.34-0.42"; docs/ridge.md lists 0.418 / 0.349 for
ridge_keel_8m). Prints the figures; exit 1 when either is outside.
"""
import argparse
import json
import subprocess
import sys

import h5py


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("hybridsim")
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--min", type=float, default=0.34)
    ap.add_argument("--max", type=float, default=0.42)
    args = ap.parse_args()
    subprocess.run([args.hybridsim, "ridge", args.scene, "-o", args.out], check=True,
                   stdout=subprocess.DEVNULL)
    with h5py.File(args.out, "r") as f:
        stats = json.loads(f["ridge"].attrs["stats"])
    ok = True
    for k in ["keel_porosity", "core_porosity"]:
        v = stats[k]
        inside = args.min <= v <= args.max
        print(f"{k}: {v:.4f} ({'inside' if inside else 'OUTSIDE'} [{args.min}, {args.max}])")
        ok &= inside
    print(f"settled: {stats.get('settled')} at {stats.get('settle_time')} s")
    print("agree" if ok else "DISAGREE")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
