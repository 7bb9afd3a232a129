#!/bin/sh
# Builds the Mesquite peer of bench/peers.py (bench/mesquite/driver.cpp) against an installed
# Mesquite ($MESQUITE_DIR/include, $MESQUITE_DIR/lib; docs/performance.md says how to build
# one). Mesquite is never needed by SurfMesh nor by CI.
#
#   MESQUITE_DIR=/var/cache/mesquite bench/mesquite/build.sh [OUTPUT]
#
# OUTPUT: bench/out/mesquite_driver by default.
set -e
HERE=$(cd "$(dirname "$0")" && pwd)
: "${MESQUITE_DIR:?set MESQUITE_DIR to an installed Mesquite (include/ and lib/)}"
OUT=${1:-$HERE/../out/mesquite_driver}
mkdir -p "$(dirname "$OUT")"
# Mesquite's headers are C++98/11 (std::auto_ptr): C++11 for the driver too.
exec ${CXX:-g++} -std=c++11 -O2 -w -I"$MESQUITE_DIR/include" "$HERE/driver.cpp" \
  -L"$MESQUITE_DIR/lib" -Wl,-rpath,"$MESQUITE_DIR/lib" -lmesquite -o "$OUT"
