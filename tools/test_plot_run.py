#!/usr/bin/python3
"""Self-contained test of tools/plot_run.py: writes synthetic run files with h5py (layout of
docs/output.md), runs plot_run.py on them and checks the PNGs and the error paths.

Run: /usr/bin/python3 tools/test_plot_run.py     (exit 0 and "N passed, 0 failed" on success)
"""

import json
import os
import subprocess
import sys
import tempfile
import traceback

sys.dont_write_bytecode = True  # the test imports plot_run; keep tools/ free of __pycache__

import numpy as np
import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "plot_run.py")
PYTHON = "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys.executable
MIN_BYTES = 10 * 1024

TESTS = []


def test(fn):
    TESTS.append(fn)
    return fn


def add_series(f, name, data, units, description=""):
    d = f.create_dataset(name, data=data, maxshape=(None,) + np.shape(data)[1:], chunks=True)
    d.attrs["units"] = units
    d.attrs["description"] = description
    return d


def write_run(path, full=True, n=600, name="synthetic cone"):
    """A run file like `hybridsim run` writes. full=False leaves out the optional series
    (pile_height, parts, /analysis/iso, intact bonds)."""
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 60.0, n)
    # Ice-breaking load: saw-tooth peaks of a few MN plus noise; the walls are pushed along -x.
    saw = (t % 4.0) / 4.0
    fx = -(1.5e6 + 2.0e6 * saw ** 3 + 0.2e6 * rng.standard_normal(n))
    fz = -(0.8e6 + 1.0e6 * saw ** 3 + 0.1e6 * rng.standard_normal(n))
    force = np.column_stack([fx, 0.05e6 * rng.standard_normal(n), fz])
    with h5py.File(path, "w") as f:
        scene = {"name": name, "description": "test scene", "time": {"end": 60.0}}
        f.attrs["scene"] = json.dumps(scene, indent=2)
        f.attrs["program_version"] = "0.1.0-test"
        f.attrs["created"] = "2024-01-01T00:00:00Z"
        f.attrs["file_format"] = "hybridsim-run/1"
        add_series(f, "/series/time", t, "s", "simulated time")
        add_series(f, "/series/step", np.arange(n, dtype=np.int64) * 100, "1", "step number")
        add_series(f, "/series/force", force, "N", "total force on all walls")
        if full:
            add_series(f, "/series/parts/cone/force", 0.9 * force, "N", "force on wall 'cone'")
            add_series(f, "/series/parts/collar/force", 0.1 * force, "N", "force on wall 'collar'")
            add_series(f, "/series/pile_height", 5.0 * (1.0 - np.exp(-t / 20.0)), "m", "pile height")
            add_series(f, "/series/bonds", (20000 - 30 * t).astype(np.int64), "1", "intact bonds")
            iso = f.create_group("/analysis/iso")
            iso.attrs["F_H"] = 2.6e6
            iso.attrs["F_K"] = 0.0
            iso.attrs["F_total"] = 2.6e6
            iso.attrs["H_B"] = 1.1e6
        kin = 4e6 * (1.0 + 0.1 * np.sin(t))
        el = 1e5 * saw
        for en, data in (("kinetic", kin), ("bond_elastic", el), ("contact_elastic", 0.5 * el),
                         ("total", kin + 1.5 * el)):
            add_series(f, "/series/energy/" + en, data, "J", en)
        add_series(f, "/series/bonds_broken", (30 * t + 5 * saw).astype(np.int64), "1", "bonds broken")
        add_series(f, "/series/particles", np.full(n, 20000, dtype=np.int64), "1", "particles")
        f.create_dataset("/snapshots/times", data=np.array([0.0]))
    return path


def run_plot(*args):
    return subprocess.run([PYTHON, SCRIPT] + [str(a) for a in args],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True,
                          timeout=100)


def check_png(path):
    assert os.path.isfile(path), "missing PNG %s" % path
    size = os.path.getsize(path)
    assert size > MIN_BYTES, "%s is only %d bytes" % (path, size)
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] >= 400 and img.shape[1] >= 800, \
        "%s has shape %s" % (path, img.shape)
    # Not a blank image: several distinct colours.
    assert np.unique(img.reshape(-1, img.shape[2])[::7], axis=0).shape[0] > 10, "%s looks blank" % path


@test
def full_file_writes_four_pngs_next_to_it():
    with tempfile.TemporaryDirectory() as d:
        h5 = write_run(os.path.join(d, "cone_run.h5"))
        r = run_plot(h5)
        assert r.returncode == 0, "exit %d, stderr: %s" % (r.returncode, r.stderr)
        expected = [os.path.join(d, "cone_run_%s.png" % k) for k in ("force", "pile_height", "energy", "bonds")]
        listed = [ln.strip() for ln in r.stdout.splitlines() if ln.strip()]
        assert sorted(listed) == sorted(expected), "stdout lists %s" % listed
        for p in expected:
            check_png(p)


@test
def show_parts_and_outdir_created():
    with tempfile.TemporaryDirectory() as d:
        h5 = write_run(os.path.join(d, "run.h5"))
        out = os.path.join(d, "plots", "sub")
        r = run_plot(h5, "-o", out, "--show-parts")
        assert r.returncode == 0, "exit %d, stderr: %s" % (r.returncode, r.stderr)
        for k in ("force", "pile_height", "energy", "bonds"):
            check_png(os.path.join(out, "run_%s.png" % k))
        assert not any(n.endswith(".png") for n in os.listdir(d)), "PNGs written next to the file, not in -o"


@test
def file_without_optional_series():
    with tempfile.TemporaryDirectory() as d:
        h5 = write_run(os.path.join(d, "minimal.h5"), full=False)
        r = run_plot(h5, "--show-parts")
        assert r.returncode == 0, "exit %d, stderr: %s" % (r.returncode, r.stderr)
        for k in ("force", "energy", "bonds"):
            check_png(os.path.join(d, "minimal_%s.png" % k))
        assert not os.path.exists(os.path.join(d, "minimal_pile_height.png")), "pile height plot without series"
        assert "pile_height" not in r.stdout


@test
def missing_file_fails_naming_the_path():
    with tempfile.TemporaryDirectory() as d:
        missing = os.path.join(d, "does_not_exist.h5")
        r = run_plot(missing)
        assert r.returncode != 0, "exit 0 for a missing file"
        assert missing in r.stderr, "stderr does not name the path: %r" % r.stderr
        assert "Traceback" not in r.stderr, r.stderr
        assert not os.listdir(d)


@test
def missing_time_series_fails_naming_it():
    with tempfile.TemporaryDirectory() as d:
        h5 = os.path.join(d, "notime.h5")
        with h5py.File(h5, "w") as f:
            f.attrs["scene"] = json.dumps({"name": "x"})
            add_series(f, "/series/force", np.zeros((3, 3)), "N")
        r = run_plot(h5)
        assert r.returncode != 0, "exit 0 without /series/time"
        assert "/series/time" in r.stderr, "stderr does not name /series/time: %r" % r.stderr
        assert "Traceback" not in r.stderr, r.stderr


@test
def not_hdf5_fails_cleanly():
    with tempfile.TemporaryDirectory() as d:
        bad = os.path.join(d, "bad.h5")
        with open(bad, "w") as fh:
            fh.write("not an HDF5 file\n")
        r = run_plot(bad)
        assert r.returncode != 0, "exit 0 for a non-HDF5 file"
        assert bad in r.stderr and "Traceback" not in r.stderr, r.stderr


@test
def reader_gets_name_and_iso_values():
    sys.path.insert(0, HERE)
    try:
        import plot_run
    finally:
        sys.path.remove(HERE)
    with tempfile.TemporaryDirectory() as d:
        run = plot_run.Run(write_run(os.path.join(d, "a.h5"), name="Confederation Bridge pier"))
        assert run.name == "Confederation Bridge pier", run.name
        assert run.iso == {"F_H": 2.6e6, "F_K": 0.0, "F_total": 2.6e6, "H_B": 1.1e6}, run.iso
        assert run.time.shape == (600,) and run.force.shape == (600, 3)
        assert set(run.parts) == {"cone", "collar"}
        assert set(run.energy) == {"kinetic", "bond_elastic", "contact_elastic", "total"}
        run2 = plot_run.Run(write_run(os.path.join(d, "b.h5"), full=False))
        assert run2.iso == {} and run2.pile_height is None and run2.parts == {}


def main():
    passed = failed = 0
    for fn in TESTS:
        try:
            fn()
        except Exception:  # noqa: BLE001 - report every failure and go on
            failed += 1
            print("FAIL %s" % fn.__name__)
            traceback.print_exc()
        else:
            passed += 1
            print("ok   %s" % fn.__name__)
    print("%d passed, %d failed" % (passed, failed))
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
