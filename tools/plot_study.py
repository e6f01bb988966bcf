#!/usr/bin/python3
"""The error-against-cost front of a study (docs/study.md, "Front").

    /usr/bin/python3 tools/plot_study.py STUDY_OUTPUT_DIR [--metric NAME] [-o front.png]

Reads STUDY_OUTPUT_DIR/summary.csv (written by `hybridsim study`) and draws, per variant, the
relative error of one metric against the reference variant's mean (%, with its bootstrap 95 %
interval as a vertical bar) over the mean core-hours (with its interval as a horizontal bar).
The reference sits at zero error with the relative half-width of its own mean's interval. Without
a reference in the study the plot shows each variant's mean of the metric instead.
`hybridsim study` runs this script itself when python3 and matplotlib are found.
"""
import argparse
import csv
import math
import os
import sys


def number(s):
    return float(s) if s not in ("", None) else math.nan


def read_summary(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("output_dir", help="the study's output directory (holds summary.csv)")
    ap.add_argument("--metric", help="the metric to plot (default: the first in summary.csv)")
    ap.add_argument("-o", "--output", help="PNG to write (default: OUTPUT_DIR/front.png)")
    a = ap.parse_args()
    rows = read_summary(os.path.join(a.output_dir, "summary.csv"))
    metrics = [r["quantity"] for r in rows if r["quantity"] != "core_hours"]
    if not metrics:
        sys.exit("plot_study.py: summary.csv has no metric rows (no member done yet?)")
    metric = a.metric or metrics[0]
    if metric not in metrics:
        sys.exit(f"plot_study.py: --metric {metric}: not in summary.csv; there: {', '.join(sorted(set(metrics)))}")
    cost = {r["variant"]: r for r in rows if r["quantity"] == "core_hours"}
    mrows = [r for r in rows if r["quantity"] == metric]
    compared = any(r["rel_error"] != "" for r in mrows)

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in mrows:
        c = cost.get(r["variant"])
        if c is None:
            continue
        x, xl, xh = number(c["mean"]), number(c["mean_ci_low"]), number(c["mean_ci_high"])
        if compared and r["rel_error"] != "":
            y, yl, yh = (100 * number(r[k]) for k in ("rel_error", "rel_error_ci_low", "rel_error_ci_high"))
            marker = "o"
        elif compared:  # the reference: zero error, its mean's relative interval
            m = number(r["mean"])
            y, yl, yh = 0.0, 100 * (number(r["mean_ci_low"]) / m - 1), 100 * (number(r["mean_ci_high"]) / m - 1)
            marker = "s"
        else:
            y, yl, yh = number(r["mean"]), number(r["mean_ci_low"]), number(r["mean_ci_high"])
            marker = "o"
        ax.errorbar([x], [y], xerr=[[x - xl], [xh - x]], yerr=[[y - yl], [yh - y]], fmt=marker, capsize=3,
                    label=f"{r['variant']} (n = {r['n']})")
    unit = mrows[0]["unit"]
    if compared:
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_ylabel(f"error of {metric} against the reference, %")
    else:
        ax.set_ylabel(f"{metric} [{unit}]")
    ax.set_xlabel("core-hours per member (mean)")
    xs = [number(cost[v]["mean"]) for v in cost if number(cost[v]["mean"]) > 0]
    if xs and max(xs) / min(xs) > 10:
        ax.set_xscale("log")
    ax.set_title(f"{os.path.basename(os.path.normpath(a.output_dir))}: {metric}, means with bootstrap 95 % intervals",
                 fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = a.output or os.path.join(a.output_dir, "front.png")
    fig.savefig(out, dpi=120)
    print(out)


if __name__ == "__main__":
    main()
