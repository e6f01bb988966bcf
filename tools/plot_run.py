#!/usr/bin/python3
"""Plot the time series of one hybridsim run file (HDF5, layout in docs/output.md).

Usage: tools/plot_run.py RUN.h5 [-o OUTDIR] [--show-parts]

Writes, next to RUN.h5 (or in OUTDIR):
  <stem>_force.png        horizontal (F_x) and vertical (F_z) force on the structure, MN;
                          ISO 19906 estimates (F_H, F_total, F_K, H_B, and F_total with the keel
                          frozen at the cone base, labelled with its depth) as horizontal lines if stored;
                          with --show-parts also the force on each part (/series/parts/<part>/force)
  <stem>_pile_height.png  rubble pile height, only if /series/pile_height exists
  <stem>_energy.png       every /series/energy/<name>
  <stem>_bonds.png        bonds broken (and intact bonds, if /series/bonds exists)
  <stem>_blocks.png       only for runs with rigid blocks (/series/blocks): rigid blocks left,
                          conversions and particle count; the blocks' share of F_x
and prints the paths written, one a line. Exit status 0 on success, 1 on a missing/unreadable
file or a missing required dataset (/series/time), 2 on bad arguments.

Runs with Debian's /usr/bin/python3 (python3-h5py, python3-matplotlib, python3-numpy).
"""

import argparse
import json
import os
import sys

# Allow looking at the last flushed state of a running simulation (docs/output.md); must be
# set before h5py loads the HDF5 library.
os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")

import numpy as np  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

try:
    import h5py  # noqa: E402
except ImportError:  # pragma: no cover - depends on the interpreter
    sys.exit("plot_run.py: h5py is not installed for %s; run with /usr/bin/python3 "
             "(Debian package python3-h5py)" % sys.executable)


class RunFileError(Exception):
    """A problem with the input file; the message names what is missing."""


# ISO 19906 results drawn on the horizontal-force panel: name -> (line style, colour, label).
ISO_LINES = [
    ("F_H", "--", "tab:red", "ISO 19906 $F_H$ (level ice)"),
    ("F_total", "-.", "tab:purple", "ISO 19906 $F_H + F_K$"),
    ("F_K", ":", "tab:brown", "ISO 19906 $F_K$ (keel)"),
    ("H_B", ":", "tab:gray", "ISO 19906 $H_B$ (breaking)"),
    ("keel_frozen_F_total", (0, (5, 1)), "tab:olive", "ISO 19906 $F_H + F_K$ (keel frozen at %s m)"),
]


def _text(value):
    """HDF5 string attribute (str, bytes, numpy bytes or 0-d/1-element array) -> str."""
    if isinstance(value, np.ndarray):
        value = value.item() if value.size == 1 else value.tolist()
    if isinstance(value, (bytes, np.bytes_)):
        return value.decode("utf-8", errors="replace")
    return str(value)


def _units(dset, default=""):
    return _text(dset.attrs["units"]) if "units" in dset.attrs else default


def _scalar(value):
    """Attribute -> float, or None if it is not a single number."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.size != 1 or not np.isfinite(arr.item()):
        return None
    return float(arr.item())


def _scale(values, base_unit):
    """Pick a display factor/prefix so the numbers stay readable: (factor, unit string)."""
    peak = float(np.nanmax(np.abs(values))) if np.size(values) else 0.0
    for factor, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if peak >= factor:
            return factor, prefix + base_unit
    return 1.0, base_unit


class Run:
    """The parts of a run file that the plots need, read eagerly so the file can be closed."""

    def __init__(self, path):
        self.path = path
        if not os.path.exists(path):
            raise RunFileError("no such file: %s" % path)
        if not os.path.isfile(path):
            raise RunFileError("not a file: %s" % path)
        try:
            f = h5py.File(path, "r")
        except OSError as e:
            raise RunFileError("cannot open %s as HDF5: %s" % (path, e))
        with f:
            self._read(f)

    def _read(self, f):
        if "series/time" not in f:
            raise RunFileError("%s has no dataset /series/time (required)" % self.path)
        self.time = np.asarray(f["series/time"][...], dtype=float).reshape(-1)
        self.time_units = _units(f["series/time"], "s")
        if self.time.size == 0:
            raise RunFileError("%s: /series/time has no rows (no flush yet?)" % self.path)
        n = self.time.size

        def series(name):
            """Dataset under /series as float array truncated to n rows, plus its units."""
            key = "series/" + name
            if key not in f or not isinstance(f[key], h5py.Dataset):
                return None, ""
            data = np.asarray(f[key][...], dtype=float)
            return data[:n], _units(f[key])

        self.force, self.force_units = series("force")
        self.parts = {}
        if "series/parts" in f and isinstance(f["series/parts"], h5py.Group):
            for part, grp in f["series/parts"].items():
                if isinstance(grp, h5py.Group) and "force" in grp:
                    data, units = series("parts/%s/force" % part)
                    self.parts[part] = (data, units)
        self.energy = {}
        if "series/energy" in f and isinstance(f["series/energy"], h5py.Group):
            for name, dset in f["series/energy"].items():
                if isinstance(dset, h5py.Dataset):
                    self.energy[name] = series("energy/" + name)
        self.bonds_broken, _ = series("bonds_broken")
        self.bonds, _ = series("bonds")
        self.particles, _ = series("particles")
        self.pile_height, self.pile_units = series("pile_height")
        self.blocks = {}
        for name in ("count", "conversions", "kinetic_energy", "structure_force", "joints_broken"):
            data, units = series("blocks/" + name)
            if data is not None:
                self.blocks[name] = data

        self.scene = {}
        if "scene" in f.attrs:
            try:
                self.scene = json.loads(_text(f.attrs["scene"]))
            except ValueError:
                self.scene = {}
        if not isinstance(self.scene, dict):
            self.scene = {}
        self.version = _text(f.attrs["program_version"]) if "program_version" in f.attrs else ""
        self.iso = self._read_iso(f)

    @staticmethod
    def _read_iso(f):
        """ISO 19906 estimates in N from /analysis/iso, /analysis or the root attributes
        (also accepted there with an "iso_" prefix); the first place holding a name wins."""
        places = []
        if "analysis/iso" in f:
            places.append(f["analysis/iso"].attrs)
        if "analysis" in f:
            places.append(f["analysis"].attrs)
        places.append(f.attrs)
        found = {}
        for name, _, _, _ in ISO_LINES:
            for attrs in places:
                for key in (name, "iso_" + name):
                    if key in attrs and name not in found:
                        value = _scalar(attrs[key])
                        if value is not None:
                            found[name] = value
        if "analysis/iso" in f and "keel_frozen_depth" in f["analysis/iso"].attrs:
            found["keel_frozen_depth"] = _scalar(f["analysis/iso"].attrs["keel_frozen_depth"])
        return found

    @property
    def name(self):
        name = self.scene.get("name")
        return str(name) if name else os.path.splitext(os.path.basename(self.path))[0]


def _finish(fig, run, path):
    if run.version:
        fig.text(0.995, 0.005, "hybridsim %s - %s" % (run.version, os.path.basename(run.path)),
                 ha="right", va="bottom", fontsize=7, color="0.4")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _time_label(run):
    return "time [%s]" % run.time_units


def _force_components(data):
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or data.shape[1] < 3:
        return None
    return data[:, 0], data[:, 2]


def plot_force(run, out, show_parts):
    t = run.time
    total = _force_components(run.force) if run.force is not None else None
    units = run.force_units or "N"
    if total is None and run.parts:
        # No total series: use the sum of the parts.
        arrays = [np.asarray(d, dtype=float) for d, _ in run.parts.values()
                  if _force_components(d) is not None]
        if arrays:
            m = min(a.shape[0] for a in arrays)
            total = _force_components(sum(a[:m] for a in arrays))
            units = next(iter(run.parts.values()))[1] or "N"
    if total is None:
        return None
    fx, fz = total
    if units == "N":
        factor, shown = 1e6, "MN"
    else:
        factor, shown = 1.0, units
    # The load on the structure is in the ice-drift direction; show it positive so that it can be
    # compared with the ISO estimates (which are magnitudes).
    sign = -1.0 if np.nanmean(fx) < 0 else 1.0
    hname = "$-F_x$" if sign < 0 else "$F_x$"

    fig, (ax_h, ax_v) = plt.subplots(2, 1, sharex=True, figsize=(10, 7))
    m = min(t.size, fx.size)
    ax_h.plot(t[:m], sign * fx[:m] / factor, color="k", lw=1.4, label="total " + hname)
    ax_v.plot(t[:m], fz[:m] / factor, color="k", lw=1.4, label="total $F_z$")
    if show_parts:
        for i, (part, (data, _)) in enumerate(sorted(run.parts.items())):
            comps = _force_components(data)
            if comps is None:
                continue
            px, pz = comps
            k = min(t.size, px.size)
            colour = "C%d" % (i % 10)
            ax_h.plot(t[:k], sign * px[:k] / factor, lw=0.7, color=colour, label=part)
            ax_v.plot(t[:k], pz[:k] / factor, lw=0.7, color=colour, label=part)
    if units == "N":
        for name, style, colour, label in ISO_LINES:
            if name in run.iso and run.iso[name] != 0.0:
                if name == "F_total" and np.isclose(run.iso[name], run.iso.get("F_H", np.nan)):
                    continue  # no keel: F_total = F_H, one line is enough
                if "%s" in label:  # the frozen keel's line names its depth
                    label = label % ("%.3g" % run.iso.get("keel_frozen_depth", float("nan")))
                value = run.iso[name] / factor
                ax_h.axhline(value, ls=style, color=colour, lw=1.3,
                             label="%s = %.3g %s" % (label, value, shown))
    ax_h.set_ylabel("horizontal force %s [%s]" % (hname, shown))
    ax_v.set_ylabel("vertical force $F_z$ [%s]" % shown)
    ax_v.set_xlabel(_time_label(run))
    for ax in (ax_h, ax_v):
        ax.grid(True, alpha=0.3)
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.legend(loc="best", fontsize=8)
    ax_h.set_title("%s: force on the structure" % run.name)
    fig.tight_layout()
    return _finish(fig, run, os.path.join(out, run.stem + "_force.png"))


def plot_pile_height(run, out):
    if run.pile_height is None:
        return None
    t = run.time
    h = np.asarray(run.pile_height, dtype=float)
    h = h.reshape(h.shape[0], -1)
    k = min(t.size, h.shape[0])
    units = run.pile_units or "m"
    fig, ax = plt.subplots(figsize=(10, 4.5))
    for j in range(h.shape[1]):
        ax.plot(t[:k], h[:k, j], lw=1.2, color="k" if h.shape[1] == 1 else "C%d" % (j % 10),
                label=None if h.shape[1] == 1 else "column %d" % j)
    if h.shape[1] > 1:
        ax.legend(fontsize=8)
    ax.set_xlabel(_time_label(run))
    ax.set_ylabel("pile height [%s]" % units)
    ax.set_title("%s: rubble pile height" % run.name)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return _finish(fig, run, os.path.join(out, run.stem + "_pile_height.png"))


def plot_energy(run, out):
    if not run.energy:
        return None
    t = run.time
    all_values = np.concatenate([np.asarray(d, dtype=float).reshape(-1) for d, _ in run.energy.values()])
    units = {u for _, u in run.energy.values()} - {""}
    base = units.pop() if len(units) == 1 else "J"
    factor, shown = _scale(all_values[np.isfinite(all_values)], base) if base == "J" else (1.0, base)
    fig, ax = plt.subplots(figsize=(10, 5))
    names = sorted(run.energy, key=lambda s: (s == "total", s))
    for i, name in enumerate(names):
        data = np.asarray(run.energy[name][0], dtype=float).reshape(-1)
        k = min(t.size, data.size)
        if name == "total":
            ax.plot(t[:k], data[:k] / factor, color="k", lw=1.8, label=name)
        else:
            ax.plot(t[:k], data[:k] / factor, lw=1.0, color="C%d" % (i % 10), label=name.replace("_", " "))
    ax.set_xlabel(_time_label(run))
    ax.set_ylabel("energy [%s]" % shown)
    ax.set_title("%s: energy" % run.name)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    return _finish(fig, run, os.path.join(out, run.stem + "_energy.png"))


def plot_bonds(run, out):
    if run.bonds_broken is None:
        return None
    t = run.time
    b = np.asarray(run.bonds_broken, dtype=float).reshape(-1)
    k = min(t.size, b.size)
    fig, ax = plt.subplots(figsize=(10, 4.5))
    lines = ax.plot(t[:k], b[:k], color="tab:red", lw=1.4, label="bonds broken (cumulative)")
    ax.set_xlabel(_time_label(run))
    ax.set_ylabel("bonds broken")
    ax.grid(True, alpha=0.3)
    if run.bonds is not None:
        intact = np.asarray(run.bonds, dtype=float).reshape(-1)
        kk = min(t.size, intact.size)
        ax2 = ax.twinx()
        lines += ax2.plot(t[:kk], intact[:kk], color="tab:blue", lw=1.0, ls="--", label="intact bonds")
        ax2.set_ylabel("intact bonds", color="tab:blue")
        ax2.tick_params(axis="y", colors="tab:blue")
    ax.legend(lines, [ln.get_label() for ln in lines], fontsize=8, loc="center right")
    ax.set_title("%s: bond breakage" % run.name)
    fig.tight_layout()
    return _finish(fig, run, os.path.join(out, run.stem + "_bonds.png"))


def plot_blocks(run, out):
    if "count" not in run.blocks:
        return None
    t = run.time
    fig, (ax_n, ax_f) = plt.subplots(2, 1, sharex=True, figsize=(10, 7))
    cnt = np.asarray(run.blocks["count"], dtype=float).reshape(-1)
    k = min(t.size, cnt.size)
    lines = ax_n.plot(t[:k], cnt[:k], color="tab:blue", lw=1.4, label="rigid blocks")
    if "conversions" in run.blocks:
        conv = np.asarray(run.blocks["conversions"], dtype=float).reshape(-1)
        lines += ax_n.plot(t[:k], conv[:k], color="tab:red", lw=1.4, label="conversions")
    ax_n.set_ylabel("blocks")
    if run.particles is not None:
        p = np.asarray(run.particles, dtype=float).reshape(-1)
        ax2 = ax_n.twinx()
        lines += ax2.plot(t[:k], p[:k], color="k", lw=1.0, ls="--", label="particles")
        ax2.set_ylabel("particles")
    ax_n.legend(lines, [ln.get_label() for ln in lines], fontsize=8, loc="center right")
    ax_n.grid(True, alpha=0.3)
    ax_n.set_title("%s: rigid blocks and conversions" % run.name)
    comps = _force_components(run.force) if run.force is not None else None
    if comps is not None:
        fx = comps[0]
        sign = -1.0 if np.nanmean(fx) < 0 else 1.0
        ax_f.plot(t[:k], sign * fx[:k] / 1e6, color="k", lw=1.2, label="total (particles + blocks)")
        if "structure_force" in run.blocks:
            bf = _force_components(run.blocks["structure_force"])
            if bf is not None:
                ax_f.plot(t[:k], sign * bf[0][:k] / 1e6, color="tab:blue", lw=1.0, label="rigid blocks' share")
        ax_f.set_ylabel("horizontal force on the structure [MN]")
        ax_f.legend(fontsize=8)
    ax_f.grid(True, alpha=0.3)
    ax_f.set_xlabel(_time_label(run))
    fig.tight_layout()
    return _finish(fig, run, os.path.join(out, run.stem + "_blocks.png"))


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="plot_run.py",
        description="Plot force, pile height, energy and bond breakage of a hybridsim run file.")
    parser.add_argument("run", help="run file (HDF5) written by hybridsim")
    parser.add_argument("-o", "--outdir", help="directory for the PNGs (default: next to RUN)")
    parser.add_argument("--show-parts", action="store_true",
                        help="also draw the force on each part (/series/parts/<part>/force)")
    args = parser.parse_args(argv)

    try:
        run = Run(args.run)
    except RunFileError as e:
        print("plot_run.py: error: %s" % e, file=sys.stderr)
        return 1
    run.stem = os.path.splitext(os.path.basename(args.run))[0]
    out = args.outdir if args.outdir else (os.path.dirname(os.path.abspath(args.run)))
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as e:
        print("plot_run.py: error: cannot create output directory %s: %s" % (out, e), file=sys.stderr)
        return 1

    written = []
    for plot in (lambda: plot_force(run, out, args.show_parts),
                 lambda: plot_pile_height(run, out),
                 lambda: plot_energy(run, out),
                 lambda: plot_bonds(run, out),
                 lambda: plot_blocks(run, out)):
        try:
            path = plot()
        except OSError as e:
            print("plot_run.py: error: cannot write plot: %s" % e, file=sys.stderr)
            return 1
        if path:
            written.append(path)
    if run.force is None and not run.parts:
        print("plot_run.py: warning: %s has no /series/force nor /series/parts/*/force; "
              "no force plot" % args.run, file=sys.stderr)
    if not written:
        print("plot_run.py: warning: nothing to plot in %s" % args.run, file=sys.stderr)
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
