#!/usr/bin/env bash
# The --stream benchmark (issue 25): a scene's leaf-on cut into an XYZ tile service (gdal2tiles, Web Mercator, zoom
# 12 to 19; made once into WORK/xyz), served by scripts/tile-server.py with LATENCY ms before each answer, drawn
# streamed and prepared over the same flyover in one run (bench --compare source=prepared,stream). Both are prepared
# first; then the tile cache is emptied, so that the streamed levels fetch their tiles during the run.
# summary.json's "stream" holds the tiles the blocks needed, the tiles fetched and their ratio.
#   scripts/stream-bench.sh [SCENE_DIR (out/demo/scene)] [WORK (/tmp/sv-stream-bench)] [LATENCY_MS (100)] [FRAMES (120)]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SCENE="${1:-$ROOT/out/demo/scene}"
WORK="${2:-/tmp/sv-stream-bench}"
LATENCY="${3:-100}"
FRAMES="${4:-120}"
PORT=8766
SV="$ROOT/build/seasonview"
mkdir -p "$WORK"
if [ ! -f "$WORK/xyz/.done" ]; then
    rm -rf "$WORK/xyz"
    gdal2tiles.py --xyz -z 12-19 -r average --processes=2 -w none -q "$SCENE/leafon.tif" "$WORK/xyz"
    touch "$WORK/xyz/.done"
fi
python3 "$ROOT/scripts/tile-server.py" "$WORK/xyz" --port "$PORT" --latency-ms "$LATENCY" > "$WORK/server.log" &
SERVER=$!
trap 'kill $SERVER 2>/dev/null || true' EXIT
sleep 1
ARGS=(--leafon "http://127.0.0.1:$PORT/{z}/{x}/{y}.png" --leafoff "$SCENE/leafoff.tif" --dem "$SCENE/dem.tif"
      --cache "$WORK/cache")
"$SV" prepare "${ARGS[@]}"
"$SV" prepare "${ARGS[@]}" --stream
rm -rf "$WORK/cache/web/tiles"
"$SV" bench "${ARGS[@]}" --compare source=prepared,stream --size 640x360 --frames "$FRAMES" --out "$WORK/bench"
python3 - "$WORK/bench/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print("stream:", json.dumps(s["stream"]))
for name, m in s["modes"].items():
    print(f'{name}: median {m["frame_ms"]["median"]:.2f} ms, worst/median {m["worst_frame_over_median"]:.2f}, '
          f'coverage mean {m["coverage_mean"]:.4f}, stream errors {m["totals"]["stream_errors"]}')
PY
