#!/usr/bin/env bash
# The --stream benchmark (issue 25): a scene's leaf-on cut into an XYZ tile service (gdal2tiles, Web Mercator, zoom
# 12 to 19; made once into WORK/xyz), served by scripts/tile-server.py with LATENCY ms before each answer, drawn
# streamed and prepared over the same flyover in one run (bench --compare source=prepared,stream). Both are prepared
# first; then the tile cache is emptied, so that the streamed levels fetch their tiles during the run.
# summary.json's "stream" holds the tiles the blocks needed, the tiles fetched and their ratio.
#   scripts/stream-bench.sh [SCENE_DIR (out/demo/scene)] [WORK (/tmp/sv-stream-bench)] [LATENCY_MS (100)] [FRAMES (120)]
# Environment: SV (the binary, default build/seasonview), SIZE (640x360), TILES (png, or webp: gdal2tiles' WebP at
# quality 85, in WORK/xyz_webp, 12× smaller). A tile folder with a file .done in it is used as it is
# (scripts/gpu-bench.sh carries the WebP tiles made here: the GPU machine has no gdal2tiles, and the PNGs are too big).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SCENE="${1:-$ROOT/out/demo/scene}"
WORK="${2:-/tmp/sv-stream-bench}"
LATENCY="${3:-100}"
FRAMES="${4:-120}"
PORT=8766
SV="${SV:-$ROOT/build/seasonview}"
SIZE="${SIZE:-640x360}"
mkdir -p "$WORK"
TILES="${TILES:-png}"
case "$TILES" in
    png) XYZ="$WORK/xyz"; DRIVER=() ;;
    webp) XYZ="$WORK/xyz_webp"; DRIVER=(--tiledriver=WEBP --webp-quality=85) ;;
    *) echo "stream-bench: TILES=$TILES: png or webp" >&2; exit 2 ;;
esac
if [ ! -f "$XYZ/.done" ]; then
    rm -rf "$XYZ"
    gdal2tiles.py --xyz -z 12-19 -r average --processes=2 -w none -q "${DRIVER[@]}" "$SCENE/leafon.tif" "$XYZ"
    touch "$XYZ/.done"
fi
SERVER=
stop() { [ -z "$SERVER" ] || { kill "$SERVER" 2>/dev/null || true; wait "$SERVER" 2>/dev/null || true; SERVER=; }; }
serve() { # the tile server, answering after $1 ms; up once it answers (a server of an earlier run may hold the port)
    stop
    for _ in $(seq 50); do
        python3 "$ROOT/scripts/tile-server.py" "$XYZ" --port "$PORT" --latency-ms "$1" >> "$WORK/server.log" 2>&1 &
        SERVER=$!
        sleep 0.5
        kill -0 "$SERVER" 2>/dev/null && return 0
        SERVER=
    done
    echo "stream-bench: the tile server did not start on port $PORT (see $WORK/server.log)" >&2
    exit 1
}
trap stop EXIT
ARGS=(--leafon "http://127.0.0.1:$PORT/{z}/{x}/{y}.$TILES" --leafoff "$SCENE/leafoff.tif" --dem "$SCENE/dem.tif"
      --cache "$WORK/cache")
serve 0 # preparing is not what is measured: the latency is for the run
"$SV" prepare "${ARGS[@]}"
"$SV" prepare "${ARGS[@]}" --stream
rm -rf "$WORK/cache/web/tiles"
serve "$LATENCY"
"$SV" bench "${ARGS[@]}" --compare source=prepared,stream --size "$SIZE" --frames "$FRAMES" --out "$WORK/bench"
python3 - "$WORK/bench/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print("stream:", json.dumps(s["stream"]))
for name, m in s["modes"].items():
    print(f'{name}: median {m["frame_ms"]["median"]:.2f} ms, worst/median {m["worst_frame_over_median"]:.2f}, '
          f'coverage mean {m["coverage_mean"]:.4f}, stream errors {m["totals"]["stream_errors"]}')
PY
