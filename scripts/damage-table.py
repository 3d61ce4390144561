#!/usr/bin/env python3
"""Damaged-input table: every file type seasonview reads, damaged the ways copies and disks damage files, fed to
the command that reads it; each run's outcome counted. The README's "Damaged input" table is this script's output.

    python3 scripts/damage-table.py [BUILD=build]

Damage per file type: truncations at 10 offsets (k/11 of the file, k = 1..10), 10 single-byte flips (XOR 0x55 at
k/11 and at k/11 + 7), a file of another type renamed (a PNG given as a GeoTIFF and so on). Outcomes:
  refused   exit 1, one line naming the file (or the file a damaged manifest names instead)
  same      exit 0 and the same output as the intact file (the damage hit bytes the reader does not need)
  accepted  exit 0 (bench: a camera path whose numbers changed is still a path; timings are not compared)
  changed   exit 0, output differs: damage no format check can see (the result is what the damaged bytes say)
  BAD       anything else: a crash, a signal, several lines, exit 0 without output; the script exits 1 then
"""
import glob
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build")
SV = os.path.join(BUILD, "seasonview")
W = tempfile.mkdtemp(prefix="seasonview-damage-")


def run(args):
    p = subprocess.run([SV] + args, capture_output=True, text=True, errors="replace")
    return p.returncode, p.stderr


def without_timings(v):
    if isinstance(v, dict):
        return {k: without_timings(x) for k, x in v.items() if "second" not in k}
    if isinstance(v, list):
        return [without_timings(x) for x in v]
    return v


def digest(paths):
    """Hash of the outputs; metrics JSON without its timings (seconds, megapixels per second)."""
    h = hashlib.sha256()
    for p in paths:
        if not os.path.exists(p):
            return None
        with open(p, "rb") as f:
            data = f.read()
        if p.endswith(".json"):
            data = json.dumps(without_timings(json.loads(data)), sort_keys=True).encode()
        h.update(data)
    return h.hexdigest()


def sv(args):
    rc, err = run(args)
    if rc != 0:
        sys.exit("damage-table: setup failed: seasonview " + " ".join(args) + "\n" + err)


# Fixtures: one small synthetic scene (imagery in every compression, PNG truth, trees, city model, DEM), an atlas tree.
sv(["synth", "--size-m", "128", "--gsd", "0.5", "--seed", "5", "--block-city", "2", "--facade-size", "32",
    "--out", f"{W}/zstd"])
for c in ["deflate", "jpeg"]:
    sv(["synth", "--size-m", "128", "--gsd", "0.5", "--seed", "5", "--no-city", "--compression", c, "--out", f"{W}/{c}"])
sv(["atlas", "build", f"{W}/zstd/city/city.obj", "--obj-local", "--atlas-size", "64", "--border", "2", "--out",
    f"{W}/city.atlas"])
open(f"{W}/path.json", "w").write('[{"time":0,"x":0,"y":0,"z":"+80","yaw":0,"pitch":-40},'
                                  '{"time":1,"x":20,"y":10,"z":"+90","yaw":30,"pitch":-35}]\n')
shutil.copy(os.path.join(ROOT, "data/presets/tiny.json"), f"{W}/preset.json")
S = f"{W}/zstd"
OFF = f"{S}/leafoff.tif"


def seg(leafon, out, extra=()):
    return ["segment", "--leafon", leafon, "--leafoff", OFF, "--cache", f"{W}/cache", "--out", out] + list(extra)


# type: (intact file, command(file, out) -> args, outputs(out) -> files compared, a foreign file renamed to its name)
CASES = {
    "GeoTIFF, Zstandard tiles": (f"{S}/leafon.tif", lambda f, o: seg(f, o), lambda o: [o], f"{S}/truth_deciduous.png"),
    "GeoTIFF, deflate tiles": (f"{W}/deflate/leafon.tif", lambda f, o: seg(f, o), lambda o: [o], f"{S}/trees.csv"),
    "GeoTIFF, JPEG (YCbCr) tiles": (f"{W}/jpeg/leafon.tif", lambda f, o: seg(f, o), lambda o: [o], f"{W}/path.json"),
    "PNG truth mask": (f"{S}/truth_deciduous.png", lambda f, o: seg(f"{S}/leafon.tif", o, ["--truth", f, "--metrics", o + ".json"]),
                       lambda o: [o, o + ".json"], f"{W}/deflate/leafon.tif"),
    "DEM GeoTIFF (float)": (f"{S}/dem.tif", lambda f, o: ["synth", "--dem", f, "--size-m", "64", "--gsd", "1", "--no-city",
                                                          "--out", o], lambda o: [f"{o}/leafon.tif", f"{o}/dem.tif"],
                            f"{S}/truth_deciduous.png"),
    "trees.csv": (f"{S}/trees.csv", lambda f, o: seg(f"{S}/leafon.tif", o, ["--truth-trees", f, "--metrics", o + ".json"]),
                  lambda o: [o + ".json"], f"{W}/path.json"),
    "scene JSON": (f"{S}/scene.json", lambda f, o: ["segment", f, "--cache", f"{W}/cache", "--out", o], lambda o: [o],
                   f"{W}/preset.json"),
    "preset JSON": (f"{W}/preset.json", lambda f, o: ["synth", "--preset", f, "--size-m", "32", "--out", o],
                    lambda o: [f"{o}/leafon.tif"], f"{W}/path.json"),
    "OBJ city model": (f"{S}/city/city.obj", lambda f, o: ["atlas", "build", f, "--obj-local", "--atlas-size", "64",
                                                           "--border", "2", "--out", o], lambda o: [o], f"{S}/trees.csv"),
    "JPEG facade texture": (f"{S}/city/facades/b0.jpg", lambda f, o: ["atlas", "build", f"{S}/city/city.obj", "--obj-local",
                                                                      "--atlas-size", "64", "--border", "2", "--out", o],
                            lambda o: [o], f"{S}/truth_deciduous.png"),
    "atlas tree": (f"{W}/city.atlas", lambda f, o: ["render", f"{S}/scene.json", "--city", "atlas", "--city-tree", f, "--size", "96x64",
                                                    "--cache", f"{W}/cache", "--out", o], lambda o: [o], f"{S}/dem.tif"),
    "camera path JSON": (f"{W}/path.json", lambda f, o: ["bench", f"{S}/scene.json", "--path", f, "--frames", "2",
                                                         "--size", "64x48", "--cache", f"{W}/cache", "--out", o],
                         lambda o: [], f"{W}/preset.json"),
}

rows, bad = [], []
for kind, (intact, command, outputs, foreign) in CASES.items():
    ext = os.path.splitext(intact)[1]
    # Masks and stills by extension (.tif, .png), folders (synth, bench) and tree files without one.
    first = command("x", "o")[0]
    oext = {"segment": ".tif", "render": ".png", "atlas": ".atlas"}.get(first, "")
    out0 = f"{W}/intact_{first}{oext}"
    rc, err = run(command(intact, out0))
    if rc != 0:
        sys.exit(f"damage-table: {kind}: the intact file fails: {err}")
    want = digest(outputs(out0))
    data = open(intact, "rb").read()
    n = len(data)
    damaged = []
    for k in range(1, 11):
        damaged.append(("truncated", data[: n * k // 11]))
    for k in range(1, 6):
        for shift in (0, 7):
            at = min(n - 1, n * k // 11 + shift)
            damaged.append(("byte flip", data[:at] + bytes([data[at] ^ 0x55]) + data[at + 1:]))
    damaged.append(("foreign file renamed", open(foreign, "rb").read()))
    counts = {}
    for i, (how, blob) in enumerate(damaged):
        path = f"{W}/damaged_{i}{ext}"
        if kind == "OBJ city model":  # beside its .mtl and textures
            path = f"{S}/city/damaged_{i}.obj"
        if kind == "scene JSON":  # beside the files it names
            path = f"{S}/damaged_{i}.json"
        if kind == "JPEG facade texture":  # in place: the model names it (restored below)
            path = intact
        with open(path, "wb") as f:
            f.write(blob)
        out = f"{W}/out_{i}_{first}{oext}"
        rc, err = run(command(path, out))
        lines = [l for l in err.splitlines() if l.strip()]
        got = digest(outputs(out))
        # One line naming a file: the damaged one, or the one a damaged manifest now names instead.
        if rc == 1 and len(lines) == 1 and lines[0].startswith("seasonview ") and "/" in lines[0] and not (
                outputs(out) and got is not None):
            outcome = "refused"
        elif rc == 0 and not outputs(out):
            outcome = "accepted"  # bench: what it measured is not compared (timings differ run to run)
        elif rc == 0 and got == want:
            outcome = "same"
        elif rc == 0 and got is not None:
            outcome = "changed"
        else:
            outcome = "BAD"
            bad.append(f"{kind}, {how} ({i}): exit {rc}, {len(lines)} lines, output {got is not None}, stderr: {err.strip()[:300]}")
        counts.setdefault(how, {}).setdefault(outcome, 0)
        counts[how][outcome] += 1
        if path == intact:
            with open(intact, "wb") as f:
                f.write(data)
        for o in glob.glob(f"{W}/out_*"):  # everything the run wrote, compared or not
            if os.path.isdir(o):
                shutil.rmtree(o, ignore_errors=True)
            else:
                os.remove(o)
    cells = []
    for how in ("truncated", "byte flip", "foreign file renamed"):
        c = counts.get(how, {})
        cells.append(", ".join(f"{v} {k}" for k, v in sorted(c.items())))
    rows.append(f"| {kind} | {cells[0]} | {cells[1]} | {cells[2]} |")

print("| file type | truncated at 10 offsets | 10 byte flips | foreign file renamed |")
print("|---|---|---|---|")
print("\n".join(rows))
shutil.rmtree(W, ignore_errors=True)
if bad:
    print("\nBAD outcomes:\n" + "\n".join(bad), file=sys.stderr)
    sys.exit(1)
