#!/usr/bin/env bash
# The GPU figures (frame time of the full scene; the city's atlas tree against its originals), on a GPU machine (docs/gpu.md): runs the bundle that
# scripts/gpu-bundle.py made (.gpu/, carried xz-compressed as .gpu-carry/bundle.tar.xz), on the EGL device platform, and leaves everything it measured in
# one archive, $OUT/gpu_results.tgz, plus a summary on stdout.
#   1. the demo scene (synth's 8192² scene, seed 1): `bench --compare scene=terrain,full` at 1920×1080, `flyover`
#      (median and p95 frame time of the full scene, goal ≤ 2 ms median)
#   2. the canopy view against the leaf-on view (`--compare canopy=off,16`, goal ≤ 1.3) and the swipe view alone at
#      $SIZE and 1280×720
#      and the same with --stages finish and --stages issue (where each stage's time goes: stages.csv, summary.json
#      "stages"; the city's too in step 3); the terrain shaded forward against deferred in the canopy and leaf-on
#      views, the canopy ratio with forward shading, the canopy's layers rasterised against marched, and the canopy
#      layer derived by the compute shader against the CPU's loader workers
#   3. the 10,000-building block city: its atlas tree, then `bench --compare city=atlas,original,flat` along the
#      pedestrian-to-overview path at 1920×1080 (goals: atlas ÷ flat ≤ 1.1, original ÷ atlas ≥ 3 at the
#      overview, nodes per frame), the same with `--terrain off` (the city alone, as the paper timed it),
#      `--compare city-flush=off,on` and
#      `--compare city-occlusion=off,on`, and the far field as BlockMaps against the atlas tree alone
#      (`--compare city=atlas,blockmap`: frame time, triangles and draw calls per frame; the BlockMaps' build time
#      in blockmap.log), and again with `--city-capacity 1024`
#   4. streaming (scripts/stream-bench.sh, after step 2 as it needs the demo scene): the demo's leaf-on as zoom 12–19
#      XYZ tiles served with 100 ms latency, `--compare source=prepared,stream` over `flyover` at 640×360 and $SIZE.
#      The GPU machine has no gdal2tiles: WebP tiles made here travel as .stream-carry/xyz_webp.tar (after
#      `TILES=webp scripts/stream-bench.sh` here: tar -cf .stream-carry/xyz_webp.tar -C /tmp/sv-stream-bench
#      xyz_webp); skipped without it
# Environment: OUT (default out/gpu), SIZE (1920x1080), FRAMES (300), CITY_FRAMES (240), WORK (work folder,
# default /tmp/seasonview-gpu), SKIP_STREAM=1 to leave step 4 out, CITY_TREE_WIDTH (the screen width the city's atlas tree is built for; default the
# frame's), SKIP_CITY=1 to stop after step 2, SKIP_DEMO=1 to run step 3 alone (on the H200
# machine steps 1–2 take 1.5 minutes, while step 3's atlas tree for 1920 pixels did not finish in 6.5: give it a
# call of its own). Locally (llvmpipe) the same script checks the
# bundle: SIZE=320x180 FRAMES=6 CITY_FRAMES=6 scripts/gpu-bench.sh
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BUNDLE=$ROOT/.gpu
OUT=${OUT:-$ROOT/out/gpu}
WORK=${WORK:-/tmp/seasonview-gpu}
SIZE=${SIZE:-1920x1080}
FRAMES=${FRAMES:-300}
CITY_FRAMES=${CITY_FRAMES:-240}
# The tool carries the bundle xz-compressed (.gpu-carry/bundle.tar.xz: the bundle itself is over its 64 MiB).
if [[ ! -x $BUNDLE/seasonview && -f $ROOT/.gpu-carry/bundle.tar.xz ]]; then tar -xJf "$ROOT/.gpu-carry/bundle.tar.xz" -C "$ROOT"; fi
[[ -x $BUNDLE/seasonview ]] || { echo "gpu-bench: $BUNDLE/seasonview missing: run scripts/gpu-bundle.py and carry .gpu-carry" >&2; exit 1; }
# PROJ's CRS database travels in the bundle.
[[ -f $BUNDLE/share/proj/proj.db ]] && export PROJ_DATA=$BUNDLE/share/proj
# glvnd finds the NVIDIA EGL vendor library through a JSON file; the driver mount has one where the image has none.
if ! ls /usr/share/glvnd/egl_vendor.d/*.json >/dev/null 2>&1; then
    for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /etc/glvnd/egl_vendor.d/10_nvidia.json; do
        if [[ -f $f ]]; then export __EGL_VENDOR_LIBRARY_FILENAMES=$f; break; fi
    done
fi
# The bundle's libraries for seasonview alone (its stubs would break the machine's own tools), then the driver's.
LIBS=$BUNDLE/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib; do [[ -d $d ]] && LIBS=$LIBS:$d; done
sv() { LD_LIBRARY_PATH=$LIBS "$BUNDLE/seasonview" "$@"; }
mkdir -p "$OUT" "$WORK"
RES=$WORK/results
rm -rf "$RES" && mkdir -p "$RES"
# Whatever happens, what was measured and logged comes back (a stub that was called names itself in a log).
finish() {
    local rc=$?
    tar czf "$OUT/gpu_results.tgz" --exclude="*.png" -C "$WORK" results
    if [[ $rc != 0 ]]; then
        for f in "$RES"/*.log; do [[ -f $f ]] && { echo "--- $f"; tail -5 "$f"; }; done
        echo "gpu-bench: failed (exit $rc); logs in $OUT/gpu_results.tgz" >&2
    fi
}
trap finish EXIT
# Each step begins by archiving what the steps before it measured: a call cut off at its time limit still returns them.
log() {
    tar czf "$OUT/gpu_results.tgz" --exclude="*.png" -C "$WORK" results
    echo "== $(date -u +%H:%M:%S) $*"
}
{ command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv || true; } | tee "$RES/gpu.txt"
nproc | tee -a "$RES/gpu.txt"

if [[ ${SKIP_DEMO:-0} != 1 ]]; then
log "demo scene (synth, prepare, stills, segmentation)"
sv demo --out "$WORK/demo" > "$RES/demo.log" 2>&1
tail -3 "$RES/demo.log"
log "terrain vs full scene, $SIZE, flyover, $FRAMES frames"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view canopy --compare scene=terrain,full --out "$RES/full" 2>&1 | tee "$RES/full.log" | tail -4
log "full scene alone, $SIZE"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view canopy --out "$RES/full_only" 2>&1 | tee "$RES/full_only.log" | tail -3
log "canopy view vs the leaf-on view (canopy=off,16), $SIZE, flyover"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view canopy --compare canopy=off,16 --coverage-every 0 --out "$RES/canopy" 2>&1 | tee "$RES/canopy.log" | tail -3
log "swipe view, $SIZE and 1280x720, flyover"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view swipe --coverage-every 0 --out "$RES/swipe" 2>&1 | tee "$RES/swipe.log" | tail -2
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size 1280x720 \
    --view swipe --coverage-every 0 --out "$RES/swipe720" 2>&1 | tee "$RES/swipe720.log" | tail -2
log "where the canopy view's time goes (--stages: each stage issued, then waited for), $SIZE, 60 frames"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames 60 --warmup 20 --size "$SIZE" \
    --view canopy --compare canopy=off,16 --coverage-every 0 --stages finish --out "$RES/canopy_stages" 2>&1 |
    tee "$RES/canopy_stages.log" | tail -3
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames 60 --warmup 20 --size "$SIZE" \
    --view canopy --compare canopy=off,16 --coverage-every 0 --stages issue --out "$RES/canopy_issue" 2>&1 |
    tee "$RES/canopy_issue.log" | tail -3
log "the terrain shaded forward or deferred (terrain-shading=forward,deferred), canopy and leaf-on views, $SIZE"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view canopy --compare terrain-shading=forward,deferred --coverage-every 0 --out "$RES/shading_canopy" 2>&1 |
    tee "$RES/shading_canopy.log" | tail -3
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view leafon --compare terrain-shading=forward,deferred --coverage-every 0 --out "$RES/shading_leafon" 2>&1 |
    tee "$RES/shading_leafon.log" | tail -3
log "canopy view vs the leaf-on view with forward shading; the canopy rasterised as layers or marched"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view canopy --terrain-shading forward --compare canopy=off,16 --coverage-every 0 --out "$RES/canopy_forward" 2>&1 |
    tee "$RES/canopy_forward.log" | tail -3
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view canopy --compare canopy-draw=layers,march --coverage-every 0 --out "$RES/canopy_draw" 2>&1 |
    tee "$RES/canopy_draw.log" | tail -3
log "the canopy layer derived by the compute shader or on the CPU's loader workers (canopy-derive=gpu,cpu), $SIZE"
sv bench "$WORK/demo/scene/scene.json" --path flyover --frames "$FRAMES" --warmup 20 --size "$SIZE" \
    --view canopy --compare canopy-derive=gpu,cpu --coverage-every 0 --out "$RES/canopy_derive" 2>&1 |
    tee "$RES/canopy_derive.log" | tail -3
fi

if [[ ${SKIP_STREAM:-0} != 1 && ${SKIP_DEMO:-0} != 1 && -f $ROOT/.stream-carry/xyz_webp.tar ]]; then
    log "streaming: the demo's leaf-on from a local XYZ service (100 ms latency) against prepared, 640x360 and $SIZE"
    rm -rf "$WORK/stream" && mkdir -p "$WORK/stream"
    tar -xf "$ROOT/.stream-carry/xyz_webp.tar" -C "$WORK/stream"
    touch "$WORK/stream/xyz_webp/.done"
    # stream-bench.sh runs the binary by path: a wrapper gives it the bundle's libraries (and nothing else).
    printf '#!/bin/sh\nLD_LIBRARY_PATH=%s exec %s "$@"\n' "$LIBS" "$BUNDLE/seasonview" > "$WORK/sv" && chmod +x "$WORK/sv"
    SV=$WORK/sv SIZE=640x360 TILES=webp bash scripts/stream-bench.sh "$WORK/demo/scene" "$WORK/stream" 100 120 \
        > "$RES/stream.log" 2>&1 || echo "stream-bench failed (exit $?)" >> "$RES/stream.log"
    tail -3 "$RES/stream.log"
    cp -r "$WORK/stream/bench" "$RES/stream" 2>/dev/null || true
    rm -rf "$WORK/stream/bench" "$WORK/stream/cache/web/tiles"
    SV=$WORK/sv SIZE=$SIZE TILES=webp bash scripts/stream-bench.sh "$WORK/demo/scene" "$WORK/stream" 100 120 \
        > "$RES/stream_big.log" 2>&1 || echo "stream-bench failed (exit $?)" >> "$RES/stream_big.log"
    tail -3 "$RES/stream_big.log"
    cp -r "$WORK/stream/bench" "$RES/stream_big" 2>/dev/null || true
fi

if [[ ${SKIP_CITY:-0} != 1 ]]; then
    log "block city (synth, atlas tree for the screen width)"
    sv synth --preset data/presets/blockcity.json --out "$WORK/blockcity" > "$RES/city_synth.log" 2>&1
    sv atlas build "$WORK/blockcity/city/city.obj" --obj-local --screen-width "${CITY_TREE_WIDTH:-${SIZE%x*}}" \
        --out "$WORK/blockcity.svat" --report "$RES/city_tree.json" > "$RES/city_tree.log" 2>&1
    tail -1 "$RES/city_tree.log"
    log "city atlas/original/flat, $SIZE, $CITY_FRAMES frames"
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames "$CITY_FRAMES" --warmup 5 --size "$SIZE" \
        --coverage-every 0 --compare city=atlas,original,flat --out "$RES/city" 2>&1 | tee "$RES/city.log" | tail -5
    log "the city alone (--terrain off), atlas/original/flat"
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames "$CITY_FRAMES" --warmup 5 --size "$SIZE" \
        --coverage-every 0 --terrain off --compare city=atlas,original,flat --out "$RES/city_alone" 2>&1 |
        tee "$RES/city_alone.log" | tail -5
    log "the far field as BlockMaps against the atlas tree alone (city=atlas,blockmap; the maps built first)"
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames "$CITY_FRAMES" --warmup 5 --size "$SIZE" \
        --coverage-every 0 --compare city=atlas,blockmap --out "$RES/blockmap" 2>&1 | tee "$RES/blockmap.log" | tail -4
    log "the same with a 1 GiB capacity (the maps' paging against the capacity, apart from their ray casting)"
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames "$CITY_FRAMES" --warmup 5 --size "$SIZE" \
        --coverage-every 0 --city-capacity 1024 --compare city=atlas,blockmap --out "$RES/blockmap_1g" 2>&1 |
        tee "$RES/blockmap_1g.log" | tail -4
    log "where the city's time goes (--stages), atlas/flat, 60 frames"
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames 60 --warmup 5 --size "$SIZE" \
        --coverage-every 0 --stages finish --compare city=atlas,flat --out "$RES/city_stages" 2>&1 |
        tee "$RES/city_stages.log" | tail -3
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames 60 --warmup 5 --size "$SIZE" \
        --coverage-every 0 --stages issue --compare city=atlas,flat --out "$RES/city_issue" 2>&1 |
        tee "$RES/city_issue.log" | tail -3
    log "the city paged with the terrain handed to the GPU first or not (city-flush=off,on)"
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames "$CITY_FRAMES" --warmup 5 --size "$SIZE" \
        --coverage-every 0 --compare city-flush=off,on --out "$RES/flush" 2>&1 | tee "$RES/flush.log" | tail -4
    log "city occlusion culling off/on"
    sv bench "$WORK/blockcity/scene.json" --city-tree "$WORK/blockcity.svat" \
        --path data/paths/blockcity_pedestrian_overview.json --frames "$CITY_FRAMES" --warmup 5 --size "$SIZE" \
        --coverage-every 0 --compare city-occlusion=off,on --out "$RES/occ" 2>&1 | tee "$RES/occ.log" | tail -4
fi
log "writing $OUT/gpu_results.tgz"
