#!/usr/bin/python3
"""The run metrics of a hybridsim run file (docs/metrics.md), for notebooks and scripts.

    /usr/bin/python3 tools/metrics.py RUN.h5 [--json] [--windows W.json] [--moving-window S]

    import sys; sys.path.insert(0, "tools"); from metrics import run_metrics
    m = run_metrics("out.h5")            # {"load_h_p95": {"value": .., "unit": "N", "description": ..}, ...}

The formulas are not repeated here: the metrics come from /analysis/metrics when the file has
it (and no window or width is asked for), else from `hybridsim metrics --json`, which computes
them with the one definition in src/sim/metrics.h. A value without data is None (NaN in the file).
"""
import argparse
import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_EXE = os.path.join(HERE, "..", "build", "hybridsim")


def _stored(path):
    """/analysis/metrics as the dict `hybridsim metrics --json` prints, or None when absent."""
    os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
    import h5py

    with h5py.File(path, "r") as f:
        if "analysis/metrics" not in f:
            return None
        g = f["analysis/metrics"]
        order = g.attrs.get("order")
        names = order.decode().split() if isinstance(order, bytes) else (order.split() if order else sorted(g))
        out = {}
        for n in names:
            d = g[n]
            v = float(d[()])
            text = lambda a: a.decode() if isinstance(a, bytes) else str(a)
            out[n] = {"value": None if math.isnan(v) else v, "unit": text(d.attrs.get("unit", "")),
                      "description": text(d.attrs.get("description", ""))}
        return out


def run_metrics(path, windows=None, moving_window=None, exe=None):
    """The metrics of the run file `path`: {name: {"value", "unit", "description"}}.

    windows: a path to a JSON file of windows, or a list of {"name", "t0", "t1"} / {"name", "x0", "x1"}.
    """
    if windows is None and moving_window is None:
        stored = _stored(path)
        if stored is not None:
            return stored
    cmd = [exe or os.environ.get("HYBRIDSIM", DEFAULT_EXE), "metrics", path, "--json"]
    tmp = None
    if windows is not None:
        if not isinstance(windows, str):
            import tempfile

            tmp = tempfile.NamedTemporaryFile("w", suffix=".json", delete=False)
            json.dump(windows, tmp)
            tmp.close()
            windows = tmp.name
        cmd += ["--windows", windows]
    if moving_window is not None:
        cmd += ["--moving-window", repr(float(moving_window))]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True)
    finally:
        if tmp:
            os.unlink(tmp.name)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()}")
    return json.loads(r.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run")
    ap.add_argument("--json", action="store_true", help="print JSON instead of a table")
    ap.add_argument("--windows", help="JSON file of windows (docs/metrics.md, \"Windows\")")
    ap.add_argument("--moving-window", type=float, help="s, width of the moving mean (default 1)")
    ap.add_argument("--exe", help="the hybridsim binary (default: $HYBRIDSIM or build/hybridsim)")
    a = ap.parse_args()
    try:
        m = run_metrics(a.run, a.windows, a.moving_window, a.exe)
    except (OSError, RuntimeError) as e:
        sys.exit(f"metrics.py: {e}")
    if a.json:
        print(json.dumps(m, indent=2))
        return
    w = max(map(len, m)) if m else 0
    for n, v in m.items():
        val = "NaN" if v["value"] is None else f"{v['value']:.5g}"
        print(f"{n:<{w}}  {val:>11} {v['unit']}")


if __name__ == "__main__":
    main()
