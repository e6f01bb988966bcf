#!/usr/bin/python3
"""ISO 19906 reference values for tests/analysis/test_iso19906.cpp, computed independently.

The formulas are typed in again from docs/iso19906.md and /work/shared/reference/validation.md
(Croasdale & Cammaert 1994 for level ice on a cone; Dolgopolov et al. 1975 for the keel), with
Python's math module, without looking at src/analysis/iso19906.cpp. The C++ test compares the
module against these numbers to 1e-9 relative, which catches an error shared by the module and
the test's own Hand struct.

    /usr/bin/python3 tools/iso_reference.py            print the values as C++ lines for the test
    /usr/bin/python3 tools/iso_reference.py --check    compare with the values stored in the test
                                                       (exit 1 if any differs by more than 1e-15: repr() round-trips)
    /usr/bin/python3 tools/iso_reference.py --run OUT.h5
        read the inputs a run used from /analysis/iso/inputs/<key> (value, unit, source), print
        them, recompute the estimate and compare with the results stored in /analysis/iso
        (exit 1 if any differs by more than 3e-15 relative, or an input is missing, not finite
        or has no known source)

The case is the test's paper_case(): h 0.6 m, w 14 m, a 52 deg, sigma_f 0.5 MPa, E 5 GPa,
nu 0.3, mu = mu_i = 0.1, rho_i 910, rho_w 1025, g 9.81, h_r 5 m, e 0.3, th 40 deg, phi 30 deg,
c 3 kPa, h_k 4 m (keel width = w).
"""
import math
import pathlib
import re
import sys

CASE = dict(h=0.6, w=14.0, sigma_f=0.5e6, E=5.0e9, nu=0.3, a_deg=52.0, mu=0.1, mu_i=0.1,
            rho_i=910.0, rho_w=1025.0, g=9.81, h_r=5.0, e=0.3, th_deg=40.0, phi_deg=30.0,
            c=3.0e3, h_k=4.0, w_k=0.0)

# Order of the near(...) lines in the test.
KEYS = ["xi", "L_c", "l", "H_B", "H_P", "P", "H_R", "H_L", "H_T", "F_H", "F_K"]
# The same case with the keel meeting a wider structure than the waterline (keel_width):
# near(rk.F_K, ...) in the test.
KEEL_WIDTH = 17.5


# /analysis/iso/inputs/<key> of a run file -> the argument of iso() (units: SI, degrees).
RUN_KEYS = dict(thickness="h", waterline_diameter="w", flexural_strength="sigma_f", youngs_modulus="E",
                poisson_ratio="nu", cone_angle_deg="a_deg", friction_ice_structure="mu", friction_ice_ice="mu_i",
                ice_density="rho_i", water_density="rho_w", gravity="g", rubble_height="h_r",
                rubble_porosity="e", rubble_cohesion="c", rubble_slope_deg="th_deg",
                rubble_friction_angle_deg="phi_deg", keel_depth="h_k", keel_width="w_k",
                keel_porosity="e_k")
SOURCES = {"scene", "measured", "default", "ridge_file", "calibrated"}
RESULT_KEYS = KEYS + ["F_total"]


def iso(h, w, sigma_f, E, nu, a_deg, mu, mu_i, rho_i, rho_w, g, h_r, e, th_deg, phi_deg, c, h_k, w_k=0.0, e_k=None):
    e_k = e if e_k is None else e_k  # the keel's porosity: ISO's one porosity unless given
    a = math.radians(a_deg)
    th = math.radians(th_deg)
    phi = math.radians(phi_deg)
    sa, ca = math.sin(a), math.cos(a)
    ta, cta = math.tan(a), 1.0 / math.tan(a)
    tt, ctt = math.tan(th), 1.0 / math.tan(th)
    s = 1.0 - tt / ta  # (1 - tan th / tan a)
    r = {}
    r["xi"] = (sa + mu * ca) / (ca - mu * sa)
    r["L_c"] = (E * h ** 3 / (12.0 * rho_w * g * (1.0 - nu ** 2))) ** 0.25
    r["l"] = w + math.pi ** 2 * r["L_c"] / 4.0
    r["H_B"] = 0.68 * r["xi"] * sigma_f * (rho_w * g * h ** 5 / E) ** 0.25 * r["l"]
    r["H_P"] = w * h_r ** 2 * mu_i * rho_i * g * (1.0 - e) * s ** 2 / (2.0 * tt)
    r["P"] = (0.5 * mu_i * (mu_i + mu) * rho_i * g * (1.0 - e) * h_r ** 2 * sa * (ctt - cta) * s
              + 0.5 * (mu_i + mu) * rho_i * g * (1.0 - e) * h_r ** 2 * ca * cta * s
              + h_r * h * rho_i * g * (sa + mu * ca) / sa)
    r["H_R"] = w * r["P"] / (ca - mu * sa)
    r["H_L"] = r["xi"] * w * h_r * s * (0.5 * h_r * rho_i * g * (1.0 - e) * (ctt - cta + math.tan(phi) * s) + c)
    r["H_T"] = 1.5 * w * h ** 2 * rho_i * g * ca / (sa - mu * ca)
    r["F_H"] = ((r["H_B"] + r["H_P"] + r["H_R"] + r["H_L"] + r["H_T"])
                / (1.0 - r["H_B"] / (sigma_f * r["l"] * h)))
    mu_phi = math.tan(math.radians(45.0) + phi / 2.0)
    gamma_e = (1.0 - e_k) * (rho_w - rho_i) * g
    wk = w_k if w_k > 0.0 else w  # the width the keel meets; 0 = the waterline diameter
    r["F_K"] = (mu_phi * h_k * wk * (h_k * mu_phi * gamma_e / 2.0 + 2.0 * c) * (1.0 + h_k / (6.0 * wk))
                if h_k > 0.0 else 0.0)
    r["F_total"] = r["F_H"] + r["F_K"]
    return r


def stored_values(test_file):
    """The near(r.KEY, VALUE) lines of ReferenceValuesFromIndependentScript."""
    text = test_file.read_text()
    body = text[text.index("ReferenceValuesFromIndependentScript"):]
    body = body[:body.index("\n}\n")]
    return {(r + "." + k): float(v) for r, k, v in re.findall(r"near\((r\w*)\.(\w+),\s*([-+0-9.eE]+)\)", body)}


def check_run(path):
    """Recomputes a run's /analysis/iso from the inputs it records; returns the exit code."""
    import h5py  # only this mode needs it
    text = lambda v: v.decode() if isinstance(v, bytes) else str(v)
    with h5py.File(path, "r") as f:
        if "/analysis/iso" not in f:
            print(f"{path}: no /analysis/iso")
            return 1
        g = f["/analysis/iso"]
        if "inputs" not in g:
            print(f"{path}: no /analysis/iso/inputs (a run from before the inputs were recorded)")
            return 1
        args, bad = {}, 0
        for key, arg in RUN_KEYS.items():
            if key not in g["inputs"]:
                print(f"input {key}: missing")
                bad += 1
                continue
            a = g["inputs"][key].attrs
            value, unit, source = float(a["value"]), text(a["unit"]), text(a["source"])
            ok = math.isfinite(value) and source in SOURCES and float(g.attrs[key]) == value
            bad += not ok
            print(f"input {key:26s} {value!r:>22s} {unit:7s} {source:10s} {'ok' if ok else 'BAD'}  {text(a.get('note', ''))}")
            args[arg] = value
        if bad:
            return 1
        ref = iso(**args)
        for k in RESULT_KEYS:
            stored = float(g.attrs[k])
            rel = abs(stored - ref[k]) / max(abs(ref[k]), 1e-300)
            ok = rel <= 3e-15 or stored == ref[k]  # measured at most 1.3e-16 (tests/app pier run)
            bad += not ok
            print(f"{k:7s} script {ref[k]!r:>22s}  run {stored!r:>22s}  rel {rel:.1e}  {'ok' if ok else 'DIFFERS'}")
    return 1 if bad else 0


def main():
    if "--run" in sys.argv[1:]:
        i = sys.argv.index("--run")
        if i + 1 >= len(sys.argv):
            print("usage: iso_reference.py --run OUT.h5")
            return 2
        return check_run(sys.argv[i + 1])
    base = iso(**CASE)
    ref = {"r." + k: base[k] for k in KEYS}
    ref["rk.F_K"] = iso(**dict(CASE, w_k=KEEL_WIDTH))["F_K"]
    if "--check" not in sys.argv[1:]:
        for k in ref:
            print(f"  near({k}, {ref[k]!r});")
        return 0
    test_file = pathlib.Path(__file__).resolve().parent.parent / "tests/analysis/test_iso19906.cpp"
    stored = stored_values(test_file)
    bad = 0
    for k in ref:
        if k not in stored:
            print(f"{k}: missing from {test_file.name}")
            bad += 1
            continue
        rel = abs(stored[k] - ref[k]) / abs(ref[k])
        ok = rel <= 1e-15
        bad += not ok
        print(f"{k:7s} script {ref[k]!r:>22s}  test {stored[k]!r:>22s}  rel {rel:.1e}  {'ok' if ok else 'DIFFERS'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
