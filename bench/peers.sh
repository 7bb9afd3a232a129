#!/bin/sh
# Every peer on the same inputs, judged by one judge (bench/peers.py; docs/performance.md,
# "Against every peer").
#
#   bench/peers.sh [quick|medium|full] [peers.py options]   (from anywhere; quick by default)
#   bench/peers.sh gmsh-only --manifest M --label L          (inside a Debian root)
#
# quick (< 2 minutes, run by scripts/test.sh): the paper's torus perturbed, the bottle's raw
# order-2 mesh, a 10³-triangle sphere. Raw JSON: bench/out/peers-MODE.json unless --json, or
# $SURFMESH_TEST_OUTPUT_DIR/peers-quick.json when that is set (scripts/test.sh). Exit status
# non-zero when the suite is broken, never on speed or on a peer's results.
set -e
ROOT=$(cd "$(dirname "$0")/.." && pwd)
MODE=${1:-quick}
[ $# -gt 0 ] && shift
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
if [ "$MODE" != "gmsh-only" ] && [ -n "${SURFMESH_TEST_OUTPUT_DIR:-}" ]; then
  mkdir -p "$SURFMESH_TEST_OUTPUT_DIR/peers"
  exec "$PY" "$ROOT/bench/peers.py" "$MODE" --json "$SURFMESH_TEST_OUTPUT_DIR/peers-$MODE.json" \
    --work "$SURFMESH_TEST_OUTPUT_DIR/peers" "$@"
fi
exec "$PY" "$ROOT/bench/peers.py" "$MODE" "$@"
