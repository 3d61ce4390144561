#!/usr/bin/env bash
# A synthetic two-season scene cropped around the centre of the real Mount Rainier SRTM DEM (4 km, 1 m/px).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
DATA="${SEASONVIEW_DATA:-$ROOT/../shared/data}"
"$ROOT/build/seasonview" synth --out "$ROOT/out/rainier" --size-m 4096 --gsd 1 --dem "$DATA/dem/mt_rainier_90m.tif"
