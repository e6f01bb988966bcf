#!/usr/bin/python3
"""Cost model of hybridsim's MPI decomposition (docs/parallel.md).

Per step, on the busiest rank:
    T(P) = f_imb * (N / P) * t_p                    compute (particles, contacts, bonds)
         + G(P) * t_g                               ghost traffic: forward (x, v, w, q: 104 B)
                                                    + reverse (f, torque: 48 B) per ghost, packing
                                                    included; migration amortised into it
         + 2 * n_nb(P) * alpha                      two messages per neighbour rank
         + 3 * ceil(log2 P) * alpha_ar              three small allreduces (rebuild decision,
                                                    structure loads, blow-up check)
    speed-up S(P) = T(1) / T(P),  efficiency E(P) = S(P) / P.
G(P): particles within the halo w = 2 r_max + skin of the box's cut faces (both sides of each cut
axis; edges and corners added), for the grid hybridsim itself chooses (least cut area).

  parallel_model.py fit BENCH_1RANK.json BENCH_2RANK.json      t_p, t_g from a benchmark pair
  parallel_model.py check                                      the model against measured 2-rank runs
  parallel_model.py predict [--t-p S] [--t-g S] ...            the paper-size ridge at 64..1024 ranks
The measured figures below are this machine's (docs/parallel.md quotes the runs they come from).
"""
import argparse
import json
import math
import sys

# Halo and interconnect assumptions for a cluster (cf. measured shared-memory figures in the doc).
ALPHA_NET = 2.0e-6      # s per point-to-point message (InfiniBand HDR-class latency, incl. MPI)
ALPHA_AR = 3.0e-6       # s per allreduce stage
BETA_NET = 10.0e9       # B/s per rank link
GHOST_BYTES = 152.0     # forward 104 + reverse 48 per ghost and step


def choose_dims(p, ext):
    """Same rule as par::Decomposition::choose_dims: least internal cut area, ties -> x."""
    best, best_cost = (p, 1, 1), math.inf
    for px in range(p, 0, -1):
        if p % px:
            continue
        for py in range(1, p // px + 1):
            if (p // px) % py:
                continue
            pz = p // px // py
            cost = (px - 1) * ext[1] * ext[2] + (py - 1) * ext[0] * ext[2] + (pz - 1) * ext[0] * ext[1]
            if cost < best_cost * (1 - 1e-9):
                best, best_cost = (px, py, pz), cost
    return best


def ghosts(n_density, ext, dims, w):
    """Ghost particles of an interior box (the busiest case)."""
    a = [ext[k] / dims[k] for k in range(3)]
    cut = [dims[k] > 1 for k in range(3)]
    g = 0.0
    for k in range(3):
        if not cut[k]:
            continue
        i, j = [m for m in range(3) if m != k]
        # two faces; the face grows by w along the other cut axes (edges/corners)
        fi = a[i] + (2 * w if cut[i] else 0.0)
        fj = a[j] + (2 * w if cut[j] else 0.0)
        g += (2 if dims[k] > 2 else 1) * w * fi * fj  # an interior box has two cut faces per axis
    # a cut box never holds more ghosts than the rest of the domain holds particles
    return n_density * g


def neighbours(dims):
    n = 1
    for d in dims:
        n *= 3 if d > 2 else (2 if d == 2 else 1)
    return n - 1


def step_time(p, N, ext, w, t_p, t_g, f_imb, alpha, alpha_ar, density=None):
    dims = choose_dims(p, ext)
    if density is None:
        density = N / (ext[0] * ext[1] * ext[2])
    G = ghosts(density, ext, dims, w) if p > 1 else 0.0
    G = min(G, N - N / p)
    T = (f_imb if p > 1 else 1.0) * N / p * t_p + G * t_g
    if p > 1:
        T += 2 * neighbours(dims) * alpha + 3 * math.ceil(math.log2(p)) * alpha_ar
    return T, dims, G


def load(path):
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line.startswith("{"):
                return json.loads(line)
    raise SystemExit(f"{path}: no JSON line")


def fit(b1, b2):
    """t_p from the 1-rank run; t_g from the 2-rank run's communication time per ghost."""
    t_p = b1["wall_s"] / (b1["particles"] * b1["steps"])
    comm_per_step = b2["comm_fraction"] * b2["wall_s"] / b2["steps"]
    ghosts_per_rank = b2["ghosts"] / b2["ranks"]
    t_g = comm_per_step / ghosts_per_rank
    return t_p, t_g


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fit")
    f.add_argument("one")
    f.add_argument("two")
    c = sub.add_parser("check")
    c.add_argument("pairs", nargs="+", help="NAME:ONE.json:TWO.json ... (the first pair gives t_g)")
    pr = sub.add_parser("predict")
    pr.add_argument("--particles", type=float, default=5.0e5, help="the paper's ridge: half a million")
    pr.add_argument("--extent", type=float, nargs=3, default=[100.0, 200.0, 10.0],
                    help="m: across the ridge (drift), along it, depth (keel 7.9 m + sail + ice)")
    pr.add_argument("--fill", type=float, default=0.5, help="fraction of the box the keel/ice occupy")
    pr.add_argument("--diameter", type=float, default=0.5, help="m")
    pr.add_argument("--t-p", type=float, default=4.5e-7, help="s per particle-step, one core (bonded benchmark: 1/2.2e6)")
    pr.add_argument("--t-g", type=float, default=2.6e-7, help="s per ghost-step, measured (2-rank granular, shared memory)")
    pr.add_argument("--imbalance", type=float, default=1.05, help="max/mean compute time")
    args = ap.parse_args()

    if args.cmd == "fit":
        t_p, t_g = fit(load(args.one), load(args.two))
        print(json.dumps({"t_p": t_p, "t_g": t_g}))
        return 0

    if args.cmd == "check":
        t_g = None
        print(f"{'case':<12} {'N':>7} {'ghosts/rank':>11} {'imbal':>6} {'measured S(2)':>14} {'model S(2)':>11}")
        for k, spec in enumerate(args.pairs):
            name, one, two = spec.split(":")
            b1, b2 = load(one), load(two)
            t_p, tg = fit(b1, b2)
            if t_g is None:
                t_g = tg  # calibrate on the first pair only; the others are predictions
            N = b1["particles"]
            G = b2["ghosts"] / 2
            T1 = N * t_p
            T2 = b2["load_imbalance"] * N / 2 * t_p + G * t_g + 2 * 1e-6 + 3e-6
            meas = (b1["wall_s"] / b1["steps"]) / (b2["wall_s"] / b2["steps"])
            print(f"{name:<12} {N:>7} {G:>11.0f} {b2['load_imbalance']:>6.3f} {meas:>14.3f} {T1 / T2:>11.3f}"
                  + ("   (t_g calibrated here)" if k == 0 else ""))
        print(f"t_g = {t_g:.3e} s per ghost-step (shared memory, this machine)")
        return 0

    N = args.particles
    ext = args.extent
    density = N / (ext[0] * ext[1] * ext[2] * args.fill)
    w = 1.1 * args.diameter  # 2 r_max + skin (0.1 D)
    # On a cluster the ghost cost is this machine's packing cost plus the wire time.
    t_g_net = args.t_g + GHOST_BYTES / BETA_NET
    T1, _, _ = step_time(1, N, ext, w, args.t_p, t_g_net, 1.0, ALPHA_NET, ALPHA_AR, density)
    print(f"paper-size ridge: N = {N:.3g} particles in {ext[0]:g} x {ext[1]:g} x {ext[2]:g} m "
          f"(fill {args.fill:g}), D = {args.diameter:g} m, halo {w:.2f} m")
    print(f"t_p = {args.t_p:.3g} s, t_g = {t_g_net:.3g} s (incl. {GHOST_BYTES:.0f} B at {BETA_NET / 1e9:g} GB/s), "
          f"latency {ALPHA_NET * 1e6:g} us, allreduce {ALPHA_AR * 1e6:g} us/stage, imbalance {args.imbalance:g}")
    print(f"{'P':>5} {'grid':>12} {'N/P':>8} {'ghosts':>8} {'halo frac':>9} {'comm frac':>9} "
          f"{'step ms':>8} {'speed-up':>9} {'eff.':>6}")
    for p in [1, 2, 8, 64, 128, 256, 512, 1024]:
        T, dims, G = step_time(p, N, ext, w, args.t_p, t_g_net, args.imbalance, ALPHA_NET, ALPHA_AR, density)
        comm = T - (args.imbalance if p > 1 else 1.0) * N / p * args.t_p
        print(f"{p:>5} {'x'.join(map(str, dims)):>12} {N / p:>8.0f} {G:>8.0f} {G / (N / p):>9.3f} "
              f"{comm / T:>9.3f} {T * 1e3:>8.3f} {T1 / T:>9.1f} {T1 / T / p:>6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
