#!/usr/bin/env bash
# The far-field city benchmark (issue 27): a block city of BUILDINGS buildings (synth, made once into WORK/city), its
# atlas tree for an 800-px screen (timed: WORK/atlas.time), then `--city atlas` against `--city blockmap` over PATH,
# interleaved (its first run builds the BlockMaps into the cache, timed in its output). Figures in WORK/bench
# (summary.json, frames.csv: triangles, draw calls, resident bytes, frame time per frame).
#   scripts/blockmap-bench.sh [BUILDINGS (100000)] [WORK (/tmp/sv-blockmap-bench)] [PATH (the 100k street-to-overview)]
#       [SIZE_M (8192)] [FRAMES (48)]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
N="${1:-100000}"
WORK="${2:-/tmp/sv-blockmap-bench}"
CAMERAS="${3:-$ROOT/data/paths/blockcity100k_street_overview.json}"
SIZE_M="${4:-8192}"
FRAMES="${5:-48}"
SV="${SV:-$ROOT/build/seasonview}" # another binary: SV=PATH
mkdir -p "$WORK"
if [ ! -f "$WORK/city/.done" ]; then
    rm -rf "$WORK/city"
    /usr/bin/time -v -o "$WORK/synth.time" "$SV" synth --out "$WORK/city" --size-m "$SIZE_M" --gsd 2 \
        --block-city "$N" --facade-size 64
    touch "$WORK/city/.done"
fi
if [ ! -f "$WORK/tree.svat" ]; then
    /usr/bin/time -v -o "$WORK/atlas.time" "$SV" atlas build "$WORK/city/city/city.obj" --obj-local \
        --screen-width 800 --out "$WORK/tree.svat"
fi
"$SV" bench "$WORK/city/scene.json" --city-tree "$WORK/tree.svat" --cache "$WORK/cache" --path "$CAMERAS" \
    --frames "$FRAMES" --warmup 2 --size 640x360 --coverage-every 0 --compare city=atlas,blockmap --out "$WORK/bench"
grep -h -E "Elapsed|Maximum resident" "$WORK"/synth.time "$WORK"/atlas.time 2>/dev/null || true
