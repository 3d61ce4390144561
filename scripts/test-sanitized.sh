#!/usr/bin/env bash
# The whole suite built with AddressSanitizer + UndefinedBehaviorSanitizer into build-asan/ and run with leak checks
# on: the unit tests (seasonview_tests), the GL tests (seasonview_gl_tests) and the CLI tests (seasonview_cli_tests,
# which run a sanitized seasonview). The GL and CLI tests' processes get Mesa's driver (swrast_dri.so) preloaded: EGL
# otherwise unloads it at exit, and what it allocated for the process's life is then reported from an unknown module
# that no suppression can name (a preloaded library is never unloaded, so its leaks are named and suppressed in
# tests/sanitizers/lsan.supp). A sanitizer report makes the process exit 86, which fails its test. Left out: the
# CrashSafety tests that SIGKILL seasonview at random moments (a killed process reports nothing to the sanitizers,
# and its runs to completion are the commands the other CLI tests run sanitized); under the sanitizers they took a
# seventh of this suite's time. The Release suite of scripts/test.sh runs them.
# Run by .ci/run after scripts/test.sh (which installs the packages).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# -O1: a third of -O3's build time under the sanitizers, and stack traces that name the right lines. Warnings are
# not errors here: GCC's instrumented builds warn falsely (-Wmaybe-uninitialized, -Wstringop-overflow); the Release
# build of scripts/test.sh holds the code to -Werror.
cmake -S "$ROOT" -B "$ROOT/build-asan" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" \
  -DSEASONVIEW_SANITIZE=ON -DSEASONVIEW_WERROR=OFF >/dev/null
cmake --build "$ROOT/build-asan" -j "$(nproc 2>/dev/null || echo 2)" --target seasonview seasonview_tests seasonview_gl_tests \
  seasonview_cli_tests
SAN="exitcode=86:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:exitcode=86"
export LSAN_OPTIONS="suppressions=$ROOT/tests/sanitizers/lsan.supp:print_suppressions=0:exitcode=86"
ASAN_OPTIONS="detect_leaks=1:$SAN" ctest --test-dir "$ROOT/build-asan" --output-on-failure -j 2 -L unit "$@"
DRIVER="$(ls /usr/lib/*/dri/swrast_dri.so 2>/dev/null | head -1)"
[[ -n "$DRIVER" ]] || { echo "test-sanitized.sh: Mesa's swrast_dri.so not found (libgl1-mesa-dri)" >&2; exit 1; }
# verify_asan_link_order=0: the preloaded driver comes before the ASan runtime in the library list.
LD_PRELOAD="$DRIVER" ASAN_OPTIONS="detect_leaks=1:verify_asan_link_order=0:$SAN" \
  ctest --test-dir "$ROOT/build-asan" --output-on-failure -j 2 -L 'gl|cli' -E '^CrashSafety\.[A-Za-z]*Killed' "$@"
