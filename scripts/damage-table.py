#!/usr/bin/env python3
"""Damaged-input table: every file type seasonview reads, damaged the ways copies and disks damage files, fed to
the command that reads it; each run's outcome counted. The README's "Damaged input" table is this script's output.

    python3 scripts/damage-table.py [BUILD=build]

Damage per file type: truncations at 10 offsets (k/11 of the file, k = 1..10), 10 single-byte flips (XOR 0x55 at
k/11 and at k/11 + 7), a file of another type renamed (a PNG given as a GeoTIFF and so on). Cache files (pyramid
levels and their index, elevation levels, pair statistics, stretches, cached atlas trees) are damaged in place in the
cache, between an intact run that wrote them and a second run of the same command. The 16-bit LZW rows need
gdal_translate, the viewer-script row a display or xvfb-run; without them those rows are left out. Outcomes:
  refused   exit 1, one line naming the file (or the file a damaged manifest names instead)
  rebuilt   (cache files) exit 0, the intact run's output, and the cache file written again from its source
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
    prefix = XVFB if args and args[0] == "view" else []
    p = subprocess.run(prefix + [SV] + args, capture_output=True, text=True, errors="replace")
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
# A 16-bit, LZW-compressed, striped GeoTIFF (how many national orthophotos come): GDAL's own layout, not the
# project's writer's.
HAVE_GDAL = shutil.which("gdal_translate") is not None
if HAVE_GDAL:
    subprocess.run(["gdal_translate", "-q", "-ot", "UInt16", "-scale", "0", "255", "0", "65535", "-co", "COMPRESS=LZW",
                    "-co", "PREDICTOR=2", f"{S}/leafon.tif", f"{W}/leafon16.tif"], check=True)
# A CityGML building (walls and a roof, one wall textured with a facade photo of the synthetic city).
shutil.copy(f"{S}/city/facades/b0.jpg", f"{W}/wall.jpg")


def ring(pts):
    return " ".join(f"{x} {y} {z}" for x, y, z in pts + pts[:1])


def poly(pid, pts):
    return (f'<gml:surfaceMember><gml:Polygon gml:id="{pid}"><gml:exterior><gml:LinearRing gml:id="{pid}_r">'
            f'<gml:posList srsDimension="3">{ring(pts)}</gml:posList></gml:LinearRing></gml:exterior></gml:Polygon>'
            '</gml:surfaceMember>')


def surface(kind, sid, polygons):
    return (f'<bldg:boundedBy><bldg:{kind} gml:id="{sid}"><bldg:lod2MultiSurface><gml:MultiSurface>{polygons}'
            f'</gml:MultiSurface></bldg:lod2MultiSurface></bldg:{kind}></bldg:boundedBy>')


X0, Y0 = 500000, 5400000
c = [(X0, Y0), (X0 + 10, Y0), (X0 + 10, Y0 + 6), (X0, Y0 + 6)]
walls = "".join(surface("WallSurface", f"w{i}", poly(f"wp{i}", [(*c[i], 0), (*c[(i + 1) % 4], 0), (*c[(i + 1) % 4], 8),
                                                               (*c[i], 8)])) for i in range(4))
roof = surface("RoofSurface", "r0", poly("rp0", [(*p, 8) for p in c]))
open(f"{W}/city.gml", "w").write(f'''<?xml version="1.0" encoding="UTF-8"?>
<CityModel xmlns="http://www.opengis.net/citygml/2.0" xmlns:gml="http://www.opengis.net/gml"
 xmlns:bldg="http://www.opengis.net/citygml/building/2.0" xmlns:app="http://www.opengis.net/citygml/appearance/2.0">
<gml:boundedBy><gml:Envelope srsName="urn:ogc:def:crs:EPSG::32632" srsDimension="3"><gml:lowerCorner>{X0} {Y0} 0</gml:lowerCorner>
<gml:upperCorner>{X0 + 10} {Y0 + 6} 8</gml:upperCorner></gml:Envelope></gml:boundedBy>
<cityObjectMember><bldg:Building gml:id="B1">{walls}{roof}</bldg:Building></cityObjectMember>
<app:appearanceMember><app:Appearance><app:theme>rgbTexture</app:theme><app:surfaceDataMember><app:ParameterizedTexture>
<app:imageURI>wall.jpg</app:imageURI><app:target uri="#wp0"><app:TexCoordList>
<app:textureCoordinates ring="#wp0_r">0 0 1 0 1 1 0 1 0 0</app:textureCoordinates></app:TexCoordList></app:target>
</app:ParameterizedTexture></app:surfaceDataMember></app:Appearance></app:appearanceMember>
</CityModel>
''')
# A viewer script: pan, a season switch, the swipe view with its bar dragged.
open(f"{W}/script.json", "w").write('[{"t":0.1,"drag":[[80,60],[60,50]],"duration":0.2},{"t":0.4,"key":"Tab"},'
                                    '{"t":0.5,"set":"view","value":"swipe"},{"t":0.6,"drag":[[80,60],[40,60]],'
                                    '"duration":0.1}]\n')
XVFB = [] if os.environ.get("DISPLAY") else (["xvfb-run", "-a", "-s", "-screen 0 640x480x24"]
                                                if shutil.which("xvfb-run") else None)


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
    "CityGML model": (f"{W}/city.gml", lambda f, o: ["atlas", "build", f, "--atlas-size", "64", "--border", "2", "--out", o],
                      lambda o: [o], f"{S}/trees.csv"),
    "OBJ material library": (f"{S}/city/city.mtl", lambda f, o: ["atlas", "build", f"{S}/city/city.obj", "--obj-local",
                                                                 "--atlas-size", "64", "--border", "2", "--out", o],
                             lambda o: [o], f"{W}/path.json"),
}
if HAVE_GDAL:
    CASES["GeoTIFF, LZW strips, 16-bit"] = (f"{W}/leafon16.tif", lambda f, o: seg(f, o), lambda o: [o],
                                            f"{S}/truth_deciduous.png")
if XVFB is not None:
    CASES["viewer script"] = (f"{W}/script.json", lambda f, o: ["view", f"{S}/scene.json", "--size", "160x120", "--script", f,
                                                               "--screenshot-at", f"1:{o}", "--quit-at", "1.1",
                                                               "--cache", f"{W}/cache"], lambda o: [o], f"{W}/preset.json")
IN_PLACE = {"JPEG facade texture", "OBJ material library"}  # the model names them: damaged where they are, restored after


def pyramid_file(cache, elevation, name):
    """The leaf-on (or elevation) pyramid's file `name` in a cache."""
    for index in glob.glob(f"{cache}/pyramids/*/pyramid.json"):
        src = json.load(open(index)).get("source_path", "")
        if src.startswith("elevation from") == elevation and (elevation or "leafon" in os.path.basename(src)):
            return os.path.join(os.path.dirname(index), name)
    sys.exit(f"damage-table: no {'elevation' if elevation else 'leaf-on'} pyramid in {cache}")


def one(pattern):
    found = sorted(glob.glob(pattern, recursive=True))
    if not found:
        sys.exit(f"damage-table: nothing matches {pattern}")
    return found[0]


def render(view, extra=()):
    return lambda c, o: ["render", f"{S}/scene.json", "--view", view, "--size", "96x64", "--cache", c, "--out", o] + list(extra)


# Cache files: type -> (command(cache, out), the file in the cache, a foreign file renamed to its name).
CACHE_CASES = {
    "pyramid level (cache)": (render("leafon"), lambda c: pyramid_file(c, False, "level_00.tif"), f"{S}/dem.tif"),
    "pyramid index (cache)": (render("leafon"), lambda c: pyramid_file(c, False, "pyramid.json"), f"{W}/preset.json"),
    "elevation level (cache)": (render("relief"), lambda c: pyramid_file(c, True, "level_00.tif"), f"{S}/leafon.tif"),
    "pair statistics (cache)": (render("canopy"), lambda c: one(f"{c}/pairstats/*.json"), f"{W}/path.json"),
    "atlas tree (cache)": (render("leafon", ["--city", "atlas"]), lambda c: one(f"{c}/atlas/*.svat"), f"{S}/dem.tif"),
}
if HAVE_GDAL:
    CACHE_CASES["stretch (cache)"] = (lambda c, o: ["segment", "--leafon", f"{W}/leafon16.tif", "--leafoff", OFF, "--cache", c,
                                                    "--out", o], lambda c: one(f"{c}/**/stretch-*.json"), f"{W}/path.json")


def damages(data, foreign):
    n = len(data)
    out = [("truncated", data[: n * k // 11]) for k in range(1, 11)]
    for k in range(1, 6):
        for shift in (0, 7):
            at = min(n - 1, n * k // 11 + shift)
            out.append(("byte flip", data[:at] + bytes([data[at] ^ 0x55]) + data[at + 1:]))
    out.append(("foreign file renamed", open(foreign, "rb").read()))
    return out


def outcome(rc, err, outputs, got, want, rebuilt=None):
    lines = [l for l in err.splitlines() if l.strip()]
    if rc == 1 and len(lines) == 1 and lines[0].startswith("seasonview ") and "/" in lines[0] and not (
            outputs and got is not None):
        return "refused"
    if rc == 0 and not outputs:
        return "accepted"  # bench: what it measured is not compared (timings differ run to run)
    if rc == 0 and got == want:
        return "same" if not rebuilt else "rebuilt"
    if rc == 0 and got is not None and rebuilt is None:
        return "changed"
    return "BAD"


def row(kind, counts):
    cells = []
    for how in ("truncated", "byte flip", "foreign file renamed"):
        c = counts.get(how, {})
        cells.append(", ".join(f"{v} {k}" for k, v in sorted(c.items())))
    return f"| {kind} | {cells[0]} | {cells[1]} | {cells[2]} |"

rows, bad = [], []
for kind, (intact, command, outputs, foreign) in CASES.items():
    ext = os.path.splitext(intact)[1]
    # Masks and stills by extension (.tif, .png), folders (synth, bench) and tree files without one.
    first = command("x", "o")[0]
    oext = {"segment": ".tif", "render": ".png", "view": ".png", "atlas": ".atlas"}.get(first, "")
    out0 = f"{W}/intact_{first}{oext}"
    rc, err = run(command(intact, out0))
    if rc != 0:
        sys.exit(f"damage-table: {kind}: the intact file fails: {err}")
    want = digest(outputs(out0))
    data = open(intact, "rb").read()
    counts = {}
    for i, (how, blob) in enumerate(damages(data, foreign)):
        path = f"{W}/damaged_{i}{ext}"
        if kind == "OBJ city model":  # beside its .mtl and textures
            path = f"{S}/city/damaged_{i}.obj"
        if kind == "scene JSON":  # beside the files it names
            path = f"{S}/damaged_{i}.json"
        if kind in IN_PLACE:
            path = intact
        with open(path, "wb") as f:
            f.write(blob)
        out = f"{W}/out_{i}_{first}{oext}"
        rc, err = run(command(path, out))
        got = digest(outputs(out))
        o = outcome(rc, err, outputs(out), got, want)
        if o == "BAD":
            bad.append(f"{kind}, {how} ({i}): exit {rc}, output {got is not None}, stderr: {err.strip()[:300]}")
        counts.setdefault(how, {}).setdefault(o, 0)
        counts[how][o] += 1
        if path == intact:
            with open(intact, "wb") as f:
                f.write(data)
        for p in glob.glob(f"{W}/out_*"):  # everything the run wrote, compared or not
            if os.path.isdir(p):
                shutil.rmtree(p, ignore_errors=True)
            else:
                os.remove(p)
    rows.append(row(kind, counts))

for kind, (command, locate, foreign) in CACHE_CASES.items():
    cache = f"{W}/cache_{len(rows)}"
    out0 = f"{W}/intact.png"
    rc, err = run(command(cache, out0))
    if rc != 0:
        sys.exit(f"damage-table: {kind}: the intact run fails: {err}")
    want = digest([out0])
    target = locate(cache)
    data = open(target, "rb").read()
    counts = {}
    for i, (how, blob) in enumerate(damages(data, foreign)):
        with open(target, "wb") as f:
            f.write(blob)
        out = f"{W}/out_{i}.png"
        rc, err = run(command(cache, out))
        got = digest([out])
        now = open(target, "rb").read() if os.path.exists(target) else None
        o = outcome(rc, err, [out], got, want, rebuilt=now is not None and now != blob)
        if o == "BAD":
            bad.append(f"{kind}, {how} ({i}): exit {rc}, output {got is not None}, cache file rewritten "
                       f"{now is not None and now != blob}, stderr: {err.strip()[:300]}")
        counts.setdefault(how, {}).setdefault(o, 0)
        counts[how][o] += 1
        with open(target, "wb") as f:
            f.write(data)
        for p in glob.glob(f"{W}/out_*"):
            os.remove(p)
    rows.append(row(kind, counts))

print("| file type | truncated at 10 offsets | 10 byte flips | foreign file renamed |")
print("|---|---|---|---|")
print("\n".join(rows))
shutil.rmtree(W, ignore_errors=True)
if bad:
    print("\nBAD outcomes:\n" + "\n".join(bad), file=sys.stderr)
    sys.exit(1)
