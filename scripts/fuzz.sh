#!/usr/bin/env bash
# Bounded fuzzing of SurfMesh's core entry points with libFuzzer + ASan + UBSan (clang).
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET]          (default 60)
#   FUZZ_RUNS=500000 scripts/fuzz.sh              (a number of executions per target instead)
#   FUZZ_TARGETS="fuzz_cad_mesh" scripts/fuzz.sh 30
#
# Targets (fuzz/*.cpp): fuzz_surface_mesh (SurfaceMesh arrays on analytic surfaces →
# validate → quality → optimizer), fuzz_cad_mesh (mesh input + node classification on small
# OCC shapes → quality → optimizer). Builds fuzz/ with clang in its own directory (never the
# main build), runs each target for the given time (or FUZZ_RUNS executions) on one core,
# keeps the corpus in $FUZZ_DIR/corpus/<target> between runs, and prints the executions of
# each. Exit status non-zero when a target crashes, leaks or trips a sanitizer: the
# reproducer is $FUZZ_DIR/artifacts/<target>/crash-* (replay: <target> <file>); add it to
# tests/cpp/validation_test.cpp as a regression test.
#
# Environment:
#   FUZZ_DIR        build + corpus + artifacts directory (default: <repo>/build-fuzz)
#   FUZZ_RUNS       executions per target (overrides the time limit when set)
#   FUZZ_TARGETS    space-separated subset of the targets
#   FUZZ_JOBS       parallel compile jobs (default 2)
#   CXX             clang++ to use (default: clang++-14, else clang++)
set -uo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECONDS_PER_TARGET="${1:-60}"
FUZZ_DIR="${FUZZ_DIR:-$REPO/build-fuzz}"
case "$FUZZ_DIR" in /*) ;; *) FUZZ_DIR="$REPO/$FUZZ_DIR" ;; esac
TARGETS=(${FUZZ_TARGETS:-fuzz_surface_mesh fuzz_cad_mesh})
JOBS="${FUZZ_JOBS:-2}"

if [ -z "${CXX:-}" ] || ! "$CXX" --version 2>/dev/null | grep -qi clang; then
  if command -v clang++-14 >/dev/null 2>&1; then CXX=clang++-14; else CXX=clang++; fi
fi
command -v "$CXX" >/dev/null 2>&1 || { echo "fuzz: clang++ not found (apt-get install clang-14 libclang-rt-14-dev)"; exit 2; }

say() { printf '[fuzz] %s\n' "$*"; }

# ---- build ---------------------------------------------------------------------------------
if [ ! -f "$FUZZ_DIR/CMakeCache.txt" ]; then
  say "configuring $FUZZ_DIR with $CXX"
  CXX="$CXX" cmake -S "$REPO/fuzz" -B "$FUZZ_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    || { say "configure failed"; exit 2; }
fi
cmake --build "$FUZZ_DIR" -j "$JOBS" --target "${TARGETS[@]}" || { say "build failed"; exit 2; }

# ---- run -----------------------------------------------------------------------------------
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
# OpenCASCADE's one-time allocations are not ours (same list as the sanitizer test build).
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$REPO/tests/cpp/lsan.supp:print_suppressions=0}"

status=0
total=0
SUMMARY=()
for t in "${TARGETS[@]}"; do
  corpus="$FUZZ_DIR/corpus/$t"
  artifacts="$FUZZ_DIR/artifacts/$t"
  mkdir -p "$corpus" "$artifacts"
  log="$FUZZ_DIR/$t.log"
  if [ -n "${FUZZ_RUNS:-}" ]; then limit=(-runs="$FUZZ_RUNS"); what="$FUZZ_RUNS runs"
  else limit=(-max_total_time="$SECONDS_PER_TARGET"); what="${SECONDS_PER_TARGET} s"; fi
  say "$t: $what (log $log)"
  start=$(date +%s)
  "$FUZZ_DIR/$t" "${limit[@]}" -max_len=4096 -timeout=30 -rss_limit_mb=4096 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" "$corpus" >"$log" 2>&1
  rc=$?
  secs=$(( $(date +%s) - start ))
  execs="$(grep -E '^stat::number_of_executed_units:' "$log" | tail -1 | awk '{print $2}')"
  execs="${execs:-0}"
  total=$((total + execs))
  if [ "$rc" -eq 0 ]; then
    SUMMARY+=("$(printf '%-20s %10s executions in %5s s  ok' "$t" "$execs" "$secs")")
  else
    status=1
    SUMMARY+=("$(printf '%-20s %10s executions in %5s s  FAILED (exit %s): see %s' \
      "$t" "$execs" "$secs" "$rc" "$log")")
    grep -E 'ERROR|SUMMARY|contract violated|crash-|leak-|timeout-|oom-' "$log" | head -20
  fi
done

say "summary"
printf '  %s\n' "${SUMMARY[@]}"
echo "  total: $total executions"
exit "$status"
