// SurfMesh — the thread count of a run: the one rule for "0 = every hardware thread".
#pragma once

#include <thread>

namespace surfmesh::detail {

/// `requested` when > 0, else the hardware's thread count (1 when it is unknown).
inline int resolveThreads(int requested) {
  if (requested > 0) return requested;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc > 0 ? static_cast<int>(hc) : 1;
}

}  // namespace surfmesh::detail
