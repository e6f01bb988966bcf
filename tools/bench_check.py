#!/usr/bin/python3
"""Runs one built-in benchmark and says whether it meets the README's target.

    /usr/bin/python3 tools/bench_check.py build/hybridsim granular
    /usr/bin/python3 tools/bench_check.py build/hybridsim bonded
    /usr/bin/python3 tools/bench_check.py --line '{"name": "granular", ...}'   (judge a JSON line)

Prints the benchmark's JSON line, then one line per target, e.g.
    PASS granular particle_steps_per_s 7.39e+06 >= 4.5e+06
and a final `granular: PASS` or `granular: FAIL`; the exit status is 0 on PASS, 1 on FAIL,
2 when the benchmark could not run. The targets are the README's ("Benchmarks"): single core,
quiet machine. A busy machine fails them; that is what the check is for (CTest label
`benchmark`, not in the default suite).
"""
import json
import subprocess
import sys

# name -> list of (JSON key, "min" or "max", limit)
TARGETS = {
    "granular": [("particle_steps_per_s", "min", 4.5e6), ("peak_rss_mb", "max", 40.0)],
    "bonded": [("particle_steps_per_s", "min", 2.0e6)],
}


def judge(j):
    name = j.get("name", "?")
    if name not in TARGETS:
        print(f"{name}: no target stated")
        return 0
    ok = True
    for key, kind, limit in TARGETS[name]:
        value = float(j[key])
        good = value >= limit if kind == "min" else value <= limit
        ok &= good
        print(f"{'PASS' if good else 'FAIL'} {name} {key} {value:.3g} {'>=' if kind == 'min' else '<='} {limit:.3g}")
    print(f"{name}: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


def main(argv):
    if len(argv) == 2 and argv[0] == "--line":
        return judge(json.loads(argv[1]))
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    exe, name = argv
    p = subprocess.run([exe, "bench", name], capture_output=True, text=True)
    if p.returncode != 0:
        print(p.stdout + p.stderr, file=sys.stderr)
        print(f"error: {exe} bench {name} exited with {p.returncode}", file=sys.stderr)
        return 2
    line = p.stdout.strip().splitlines()[-1]
    print(line)
    return judge(json.loads(line))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
