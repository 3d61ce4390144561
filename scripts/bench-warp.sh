#!/usr/bin/env bash
# The warp's throughput and memory (docs/benchmarks.md, "prepare" rows): one synthetic season pair delivered three ways and
# prepared (pyramids of both seasons and the pair statistics, cache emptied each time):
#   grid    the seasons as one GeoTIFF each, already on the working grid (no warp: the direct path);
#   mosaic  each season as 4 tiles in Web Mercator, warped by `seasonview prepare` onto the original UTM grid;
#   gdal    the same tiles first warped onto that grid by `gdalwarp -multi -wo NUM_THREADS=ALL_CPUS` (deflate, tiled),
#           then prepared as in `grid`: the two-step a user would otherwise run.
# Prints wall time, MP/s of output grid pixels (both seasons) and peak RSS per way. Usage:
#   scripts/bench-warp.sh [SIZE_M=2048] [GSD=0.25] [WORK=/tmp/sv-bench-warp] [TILES=2] [WAYS="grid mosaic gdal"]
# SIZE_M / GSD = pixels per side (2048 m at 0.25 m: 8192²); TILES per side of each season's mosaic. The memory
# figure: scripts/bench-warp.sh 8192 0.25 /tmp/sv-bench-32k 8 mosaic (32768² per season as 64 tiles).
# Needs build/seasonview and gdal-bin (installed if missing).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SV="$ROOT/build/seasonview"
SIZE_M="${1:-2048}"
GSD="${2:-0.25}"
WORK="${3:-/tmp/sv-bench-warp}"
TILES="${4:-2}"
WAYS="${5:-grid mosaic gdal}"
if ! command -v gdalwarp >/dev/null; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get install -y -qq --no-install-recommends gdal-bin >/dev/null
fi
mkdir -p "$WORK"
cd "$WORK"
if [ ! -f scene/scene.json ]; then
  "$SV" synth --out scene --size-m "$SIZE_M" --gsd "$GSD" --no-city >/dev/null
fi
read -r XMIN YMAX PX < <(gdalinfo -json scene/leafon.tif | python3 -c '
import json, sys; g = json.load(sys.stdin)["geoTransform"]; print(g[0], g[3], g[1])')
W=$(gdalinfo -json scene/leafon.tif | python3 -c 'import json,sys; print(json.load(sys.stdin)["size"][0])')
XMAX=$(python3 -c "print($XMIN + $W * $PX)"); YMIN=$(python3 -c "print($YMAX - $W * $PX)")
CRS=$(gdalsrsinfo -o epsg scene/leafon.tif | tr -d '[:space:]')
GRID=(--grid-crs "$CRS" --grid-res "$PX" --extent "$XMIN,$YMIN,$XMAX,$YMAX")
for s in leafon leafoff; do
  if [ ! -d "tiles_$s" ]; then
    mkdir -p "tiles_$s"
    gdalwarp -q -multi -wo NUM_THREADS=ALL_CPUS -t_srs EPSG:3857 -r bilinear -dstalpha \
      -co TILED=YES -co COMPRESS=DEFLATE -co BIGTIFF=IF_SAFER "scene/$s.tif" "merc_$s.tif"
    read -r MW MH < <(gdalinfo -json "merc_$s.tif" | python3 -c '
import json, sys; s = json.load(sys.stdin)["size"]; print(s[0], s[1])')
    for ty in $(seq 0 $((TILES - 1))); do
      for tx in $(seq 0 $((TILES - 1))); do
        X0=$((MW * tx / TILES)); X1=$((MW * (tx + 1) / TILES)); Y0=$((MH * ty / TILES)); Y1=$((MH * (ty + 1) / TILES))
        gdal_translate -q -srcwin "$X0" "$Y0" $((X1 - X0)) $((Y1 - Y0)) -co TILED=YES -co COMPRESS=DEFLATE \
          "merc_$s.tif" "tiles_$s/t_${tx}_${ty}.tif"
      done
    done
    rm "merc_$s.tif"
  fi
done
MP=$(python3 -c "print(2 * $W * $W / 1e6)")
run() { # name, then the command; prints seconds and peak RSS
  local name="$1"; shift
  rm -rf cache
  /usr/bin/time -f "%e %M" -o time.txt "$@" >/dev/null
  read -r SEC KB < time.txt
  echo "$name: $SEC s, $(python3 -c "print(round($MP / $SEC, 1))") MP/s of output, peak RSS $(python3 -c "print(round($KB / 1048576, 2))") GB"
}
case " $WAYS " in *" grid "*) run grid "$SV" prepare --leafon scene/leafon.tif --leafoff scene/leafoff.tif --cache cache;; esac
case " $WAYS " in *" mosaic "*)
  echo "mosaic: $(ls tiles_leafon | wc -l) tiles per season"
  run mosaic "$SV" prepare --leafon tiles_leafon --leafoff tiles_leafoff "${GRID[@]}" --cache cache;; esac
case " $WAYS " in *" gdal "*) ;; *) exit 0;; esac
T0=$(date +%s.%N)
for s in leafon leafoff; do
  rm -f "gdal_$s.tif"
  gdalwarp -q -multi -wo NUM_THREADS=ALL_CPUS -t_srs "$CRS" -tr "$PX" "$PX" -te "$XMIN" "$YMIN" "$XMAX" "$YMAX" \
    -r bilinear -co TILED=YES -co COMPRESS=DEFLATE -co BIGTIFF=IF_SAFER "tiles_$s"/*.tif "gdal_$s.tif"
done
T1=$(date +%s.%N)
echo "gdalwarp alone (both seasons): $(python3 -c "print(round($T1 - $T0, 2))") s"
run "gdal two-step, its prepare" "$SV" prepare --leafon gdal_leafon.tif --leafoff gdal_leafoff.tif --cache cache
