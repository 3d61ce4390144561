#!/usr/bin/env bash
# The far-field city benchmark (issue 27): a block city of BUILDINGS buildings (synth, made once into WORK/city), its
# atlas tree for an 800-px screen (timed: WORK/atlas.time), then `--city atlas` against `--city blockmap` over PATH,
# interleaved (its first run builds the BlockMaps into the cache, timed in its output). Figures in WORK/bench
# (summary.json, frames.csv: triangles, draw calls, resident bytes, frame time per frame); then the picture's PSNR at
# the overview cameras (WORK/quality).
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
# The picture at the overview end of the path: `--city blockmap` against `--city atlas` over the city's pixels (the
# terrain off), at the path's keyframes at +1,500 m and +5,000 m and three cameras between them and the ones either
# side, one sample a pixel and 4 x 4 (antialiased; the same maps and atlases): WORK/quality/*.json.
mkdir -p "$WORK/quality"
for cam in 0,-2400,+850,0,-42 0,-2000,+1500,0,-55 0,-1000,+3250,0,-72 0,0,+5000,0,-89 400,400,+2800,225,-62; do
    for k in 1 4; do
        q="$WORK/quality/$cam.$k"
        "$SV" render "$WORK/city/scene.json" --city-tree "$WORK/tree.svat" --cache "$WORK/cache" --terrain off \
            --city blockmap --camera "$cam" --size 640x360 --supersample "$k" --city-accuracy "$q.json" \
            --city-accuracy-against atlas --out "$q.png" > /dev/null
        printf 'overview %s, %d x %d samples a pixel: blockmap against atlas %.2f dB\n' "$cam" "$k" "$k" \
            "$(grep -o '"psnr_db": [0-9.]*' "$q.json" | cut -d' ' -f2)"
    done
done
grep -h -E "Elapsed|Maximum resident" "$WORK"/synth.time "$WORK"/atlas.time 2>/dev/null || true
