#!/usr/bin/env bash
# Fuzzes every loader (tests/fuzz/fuzz_*.cpp) for SECONDS each, after building them with Clang's libFuzzer,
# AddressSanitizer and UndefinedBehaviorSanitizer into build-fuzz/, and seeding each corpus from the project's
# own fixtures (a tiny synthetic scene: its rasters in every compression, manifest, trees, city model, atlas tree,
# pyramid cache) and ../shared/data (real rasters cut to small tiles, real CityGML).
#   scripts/fuzz.sh [SECONDS=600] [TARGET...]      (JOBS=2 targets at a time; DATA=../shared/data)
# Writes build-fuzz/fuzz/summary.tsv (target, seconds, executions, crashes, hangs, leaks/sanitizer reports) and
# keeps findings in build-fuzz/fuzz/findings/TARGET/ (crash-*, timeout-*, leak-*, oom-*): each becomes a
# regression test (tests/FuzzRegressionTest.cpp reads tests/fuzz/regressions/TARGET/*).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
SECONDS_EACH="${1:-600}"
shift || true
JOBS="${JOBS:-2}"
DATA="${DATA:-$ROOT/../shared/data}"
B="$ROOT/build-fuzz"
ALL=(raster scene_json camera_path trees_csv pair_stats pyramid_index pyramid_tile citygml obj atlas_tree blockmap preset
     viewer_script)
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=("${ALL[@]}")

for p in clang-14 libclang-rt-14-dev gdal-bin; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
    { echo "fuzz.sh: needs the Debian package $p (apt-get install $p)" >&2; exit 1; }
done
if [ ! -f "$B/CMakeCache.txt" ]; then
  CC=clang-14 CXX=clang++-14 cmake -S "$ROOT" -B "$B" -DCMAKE_BUILD_TYPE=Release -DSEASONVIEW_FUZZ=ON \
    -DSEASONVIEW_TESTS=OFF >/dev/null
fi
cmake --build "$B" -j "$(nproc)" --target fuzz_all seasonview

# Seeds: made once into build-fuzz/fuzz/seeds/TARGET (a corpus of small valid inputs and the regressions).
S="$B/fuzz/seeds"
if [ ! -f "$S/.done" ]; then
  rm -rf "$S" && mkdir -p "$S"/{raster,scene_json,camera_path,trees_csv,pair_stats,pyramid_index,pyramid_tile,citygml,obj,atlas_tree,blockmap,preset,viewer_script}
  W="$B/fuzz/work" && rm -rf "$W" && mkdir -p "$W"
  SV="$B/seasonview"
  "$SV" synth --preset data/presets/tiny.json --size-m 128 --block-city 2 --facade-size 32 --out "$W/scene" >/dev/null
  "$SV" synth --preset data/presets/tiny.json --size-m 64 --compression jpeg --no-city --out "$W/scene_jpeg" >/dev/null
  "$SV" synth --preset data/presets/tiny.json --size-m 64 --compression deflate --no-city --out "$W/scene_deflate" >/dev/null
  i=0
  for f in "$W"/scene*/*.tif "$W"/scene/*/*.tif; do
    [ -f "$f" ] || continue
    gdal_translate -q -srcwin 0 0 48 40 "$f" "$S/raster/synth_$((i++)).tif" 2>/dev/null || true
  done
  for co in "COMPRESS=LZW" "COMPRESS=DEFLATE PREDICTOR=2" "COMPRESS=JPEG PHOTOMETRIC=YCBCR" "COMPRESS=ZSTD" \
            "TILED=YES BLOCKXSIZE=16 BLOCKYSIZE=16 COMPRESS=PACKBITS" "COMPRESS=NONE"; do
    opts=(); for o in $co; do opts+=(-co "$o"); done
    gdal_translate -q -srcwin 0 0 40 32 -b 1 -b 2 -b 3 "${opts[@]}" "$W/scene/leafon.tif" "$S/raster/co_$((i++)).tif" 2>/dev/null || true
  done
  gdal_translate -q -of PNG -srcwin 0 0 32 32 "$W/scene/leafon.tif" "$S/raster/png_$((i++)).png" 2>/dev/null || true
  if [ -d "$DATA/seasons" ]; then
    for f in "$DATA"/seasons/saclay_w/*.tif "$DATA"/seasons/saclay_w_delivered/*/*_0_0.tif "$DATA"/dem/*.tif; do
      [ -f "$f" ] && gdal_translate -q -srcwin 0 0 40 40 "$f" "$S/raster/real_$((i++)).tif" 2>/dev/null || true
    done
  fi
  cp "$W/scene/scene.json" "$S/scene_json/synth.json"
  cp data/scenes/*.json "$S/scene_json/"
  cp data/paths/*.json "$S/camera_path/"
  printf '[{"time":0,"x":0,"y":0,"z":"+50","yaw":0,"pitch":-30},{"time":2,"x":10,"y":5,"z":60,"yaw":90,"pitch":-10,"fov":50}]' > "$S/camera_path/two.json"
  cp data/presets/*.json "$S/preset/"
  find "$W/scene" -name '*.csv' -exec cp {} "$S/trees_csv/" \;
  printf 'x,y,radius_m,type\n1.5,2.5,3,deciduous\n4,5,2,conifer\n' > "$S/trees_csv/small.csv"
  printf '[{"t":0,"key":"2"},{"t":0.25,"drag":[[100,50],[40,110]],"duration":0.5},{"t":0.7,"set":"blend","value":0.25},{"t":0.4,"wheel":2,"at":[10,20]},{"t":1,"hold":"W","duration":0.25},{"t":1.2,"move":[5,6]}]' > "$S/viewer_script/events.json"
  [ -f "$DATA/city/berlin_lod2/berlin_lod2.gml" ] && cp "$DATA/city/berlin_lod2/berlin_lod2.gml" "$S/citygml/berlin.gml"
  cat > "$S/citygml/one.gml" <<'GML'
<?xml version="1.0" encoding="UTF-8"?>
<core:CityModel xmlns:core="http://www.opengis.net/citygml/2.0" xmlns:bldg="http://www.opengis.net/citygml/building/2.0" xmlns:gml="http://www.opengis.net/gml" xmlns:app="http://www.opengis.net/citygml/appearance/2.0">
<gml:boundedBy><gml:Envelope srsName="urn:ogc:def:crs:EPSG::25833" srsDimension="3"><gml:lowerCorner>390000 5819000 30</gml:lowerCorner><gml:upperCorner>390010 5819010 40</gml:upperCorner></gml:Envelope></gml:boundedBy>
<core:cityObjectMember><bldg:Building gml:id="b1"><bldg:boundedBy><bldg:WallSurface gml:id="w1"><bldg:lod2MultiSurface><gml:MultiSurface><gml:surfaceMember><gml:Polygon gml:id="p1"><gml:exterior><gml:LinearRing><gml:posList>390000 5819000 30 390010 5819000 30 390010 5819000 40 390000 5819000 40 390000 5819000 30</gml:posList></gml:LinearRing></gml:exterior></gml:Polygon></gml:surfaceMember></gml:MultiSurface></bldg:lod2MultiSurface></bldg:WallSurface></bldg:boundedBy></bldg:Building></core:cityObjectMember>
<app:appearanceMember><app:Appearance><app:theme>rgbTexture</app:theme><app:surfaceDataMember><app:ParameterizedTexture><app:imageURI>wall.png</app:imageURI><app:target uri="#p1"><app:TexCoordList><app:textureCoordinates ring="#p1_r">0 0 1 0 1 1 0 1 0 0</app:textureCoordinates></app:TexCoordList></app:target></app:ParameterizedTexture></app:surfaceDataMember></app:Appearance></app:appearanceMember>
</core:CityModel>
GML
  obj=$(find "$W/scene" -name '*.obj' | head -1)
  if [ -n "$obj" ]; then
    mtl="${obj%.obj}.mtl"
    { head -c 30000 "$obj"; printf '\n#MTL\n'; [ -f "$mtl" ] && cat "$mtl"; } > "$S/obj/synth.obj"
  fi
  printf 'mtllib model.mtl\nv 0 0 0\nv 10 0 0\nv 10 0 10\nv 0 0 10\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl wall\nf 1/1 2/2 3/3 4/4\n#MTL\nnewmtl wall\nmap_Kd wall.png\n' > "$S/obj/quad.obj"
  # Atlas trees (both storage formats), a pyramid cache (index, level files) and pair statistics from the scene.
  if [ -n "$obj" ]; then
    for fmt in deflate bc; do
      "$SV" atlas build "$obj" --obj-local --atlas-size 64 --border 2 --format "$fmt" --out "$S/atlas_tree/city_$fmt.atlas" >/dev/null
    done
    # BlockMaps of the same model, small (8² texels, 4 per wall column) so a seed holds several maps.
    "$SV" atlas blockmaps "$obj" --obj-local --size 8 --wall-texels 4 --leaf-texel 4 --out "$S/blockmap/city.svbm" >/dev/null
  fi
  "$SV" prepare "$W/scene/scene.json" --cache "$W/cache" >/dev/null
  for d in "$W"/cache/pyramids/*/; do
    cp "$d/pyramid.json" "$S/pyramid_index/$(basename "$d").json"
    for l in "$d"/level_0[0-2].tif; do [ -f "$l" ] && cp "$l" "$S/pyramid_tile/$(basename "$d")_$(basename "$l")"; done
  done
  cp "$W"/cache/pairstats/*.json "$S/pair_stats/" 2>/dev/null || true
  # The regressions of earlier findings are seeds too.
  for t in "${ALL[@]}"; do
    [ -d "tests/fuzz/regressions/$t" ] && cp tests/fuzz/regressions/"$t"/* "$S/$t/" 2>/dev/null || true
  done
  touch "$S/.done"
fi

OUT="$B/fuzz"
: > "$OUT/summary.tsv.new"
run_one() {
  local t="$1" corpus="$OUT/corpus/$1" findings="$OUT/findings/$1" log="$OUT/logs/$1.log"
  rm -rf "$findings" # this run's findings only (earlier ones live on in tests/fuzz/regressions)
  mkdir -p "$corpus" "$findings" "$OUT/logs"
  local maxlen=65536 started=$SECONDS
  case "$t" in atlas_tree|blockmap|pyramid_tile|raster|citygml) maxlen=1048576 ;; esac
  # GDAL's block cache and ASan's quarantine kept small: RSS then measures the loaders, and -rss_limit_mb catches
  # what they hold; one allocation over 4 GiB is a finding of its own (-malloc_limit_mb).
  ( cd "$findings" && GDAL_CACHEMAX=64 ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1:quarantine_size_mb=64 \
      LSAN_OPTIONS="suppressions=$ROOT/tests/sanitizers/lsan.supp:print_suppressions=0" \
      SEASONVIEW_FUZZ_TMP=/dev/shm "$B/fuzz/fuzz_$t" "$corpus" "$S/$t" -max_total_time="$SECONDS_EACH" \
      -timeout=20 -rss_limit_mb=8192 -malloc_limit_mb=4096 -max_len="$maxlen" -print_final_stats=1 \
      -artifact_prefix="$findings/" > "$log" 2>&1 ) || true
  local execs crashes hangs
  execs=$(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "$log" | awk '{s+=$2} END {print s+0}')
  [ "$execs" = 0 ] && execs=$(grep -Eo '#[0-9]+' "$log" | tail -1 | tr -d '#')
  crashes=$(find "$findings" -name 'crash-*' -o -name 'leak-*' -o -name 'oom-*' | wc -l)
  hangs=$(find "$findings" -name 'timeout-*' | wc -l)
  local ran=$((SECONDS - started))
  printf '%s\t%s\t%s\t%s\t%s\n' "$t" "$ran" "${execs:-0}" "$crashes" "$hangs" >> "$OUT/summary.tsv.new"
  echo "fuzz_$t: ${ran}s, ${execs:-0} executions, $crashes crashes/leaks/OOMs, $hangs hangs"
}
running=0
for t in "${TARGETS[@]}"; do
  # Niced: builds and tests beside a long run keep their speed; the targets run for their time regardless.
  ( renice -n 10 -p "$BASHPID" >/dev/null; run_one "$t" ) &
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then wait -n; running=$((running - 1)); fi
done
wait
{ printf 'target\tseconds\texecutions\tcrashes\thangs\n'; sort "$OUT/summary.tsv.new"; } > "$OUT/summary.tsv"
rm -f "$OUT/summary.tsv.new"
