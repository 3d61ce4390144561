#!/usr/bin/env bash
# Quick start 2: set up, build, and run every test.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
ctest --test-dir "$ROOT/build" --output-on-failure -j 2 "$@"
