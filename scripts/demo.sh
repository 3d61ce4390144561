#!/usr/bin/env bash
# Quick start 1: set up, build, and run the demo (writes out/demo/index.html and stills).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
"$ROOT/build/seasonview" demo --out "$ROOT/out/demo" "$@"
