// What the optimizer's sweeps run on: the node → element incidence, the node colouring, the
// per-thread geometry and the team of worker threads (optimizer internals).
#pragma once

#include "../common/threads.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace surfmesh {
namespace detail {

inline bool isMovable(NodeKind k) { return k == NodeKind::Face || k == NodeKind::Edge; }
/// Node → (element, local index) incidence in CSR form: the compact neighbour data of the
/// sweep (a node's submesh is elem[offset[i] .. offset[i+1]), its place in each element local).
struct Incidence {
  std::vector<std::int64_t> offset;
  std::vector<std::int32_t> elem;
  std::vector<std::int8_t> local;
};
Incidence buildIncidence(const SurfaceMesh& m);

/// `region` (one flag per element) grown by `rings` rings: the elements sharing a node with a
/// flagged element are flagged, `rings` times over.
std::vector<unsigned char> widenByRings(const SurfaceMesh& mesh, std::vector<unsigned char> region,
                                        int rings);

/// Greedy coloring on a given incidence (see colorMovableNodes).
std::vector<std::vector<std::int32_t>> colorNodes(const SurfaceMesh& mesh, const Incidence& inc);

/// Which linear triangles a run holds from standing across their surface (acrossArea): none;
/// those with no node sliding along a CAD edge; all (a valid one with a sliding node too).
enum class HoldAcross { None, ExceptSliding, All };

/// Per-thread geometry: clones of the surfaces and curves (OCC adaptors are not shared), of
/// those the mesh uses only (its elements' faces, its nodes' faces and edges; the others
/// null): a run on a few elements of a part with hundreds of faces (the flip rounds' and the
/// repairs' local runs) clones a few.
struct ThreadGeometry {
  std::vector<std::unique_ptr<Surface>> surfaces;
  std::vector<std::unique_ptr<Curve>> curves;
  explicit ThreadGeometry(const SurfaceMesh& m) {
    std::vector<unsigned char> face(m.surfaces.size(), 0), edge(m.curves.size(), 0);
    auto mark = [](std::vector<unsigned char>& used, std::int32_t k) {
      if (k >= 0 && static_cast<std::size_t>(k) < used.size())
        used[static_cast<std::size_t>(k)] = 1;
    };
    for (std::int32_t f : m.elemFace) mark(face, f);
    for (std::int32_t f : m.nodeFace) mark(face, f);
    for (std::int32_t c : m.nodeEdge) mark(edge, c);
    for (std::size_t f = 0; f < m.surfaces.size(); ++f)
      surfaces.push_back(face[f] && m.surfaces[f] ? m.surfaces[f]->clone() : nullptr);
    for (std::size_t c = 0; c < m.curves.size(); ++c)
      curves.push_back(edge[c] && m.curves[c] ? m.curves[c]->clone() : nullptr);
  }
};

/// A persistent team of worker threads for the whole run: run(job) executes job(tid) on
/// every member (the caller is member 0) and returns when all are done — the barrier between
/// colors. Waiting members spin briefly, then sleep (so an oversubscribed machine is not
/// burnt by spinning).
class Team {
 public:
  explicit Team(int n) : n_(n) {
    for (int t = 1; t < n_; ++t) workers_.emplace_back([this, t] { loop(t); });
  }
  ~Team() {
    {
      std::lock_guard<std::mutex> lock(m_);
      stop_ = true;
      gen_.fetch_add(1, std::memory_order_release);
    }
    cv_.notify_all();
    for (auto& w : workers_) w.join();
  }
  Team(const Team&) = delete;
  Team& operator=(const Team&) = delete;

  int size() const { return n_; }

  template <class F>
  void run(F& job) {
    if (n_ == 1) {
      job(0);
      return;
    }
    job_ = [](void* ctx, int tid) { (*static_cast<F*>(ctx))(tid); };
    ctx_ = &job;
    pending_.store(n_ - 1, std::memory_order_relaxed);
    {
      std::lock_guard<std::mutex> lock(m_);
      gen_.fetch_add(1, std::memory_order_release);
    }
    cv_.notify_all();
    job(0);
    for (int spin = 0; pending_.load(std::memory_order_acquire) != 0; ++spin) {
      if (spin < 4000) continue;
      std::unique_lock<std::mutex> lock(m_);
      doneCv_.wait(lock, [this] { return pending_.load(std::memory_order_acquire) == 0; });
    }
  }

 private:
  void loop(int tid) {
    std::uint64_t seen = 0;
    for (;;) {
      std::uint64_t g = gen_.load(std::memory_order_acquire);
      for (int spin = 0; g == seen && spin < 4000; ++spin) g = gen_.load(std::memory_order_acquire);
      if (g == seen) {
        std::unique_lock<std::mutex> lock(m_);
        cv_.wait(lock, [&] { return gen_.load(std::memory_order_acquire) != seen; });
        g = gen_.load(std::memory_order_acquire);
      }
      seen = g;
      if (stop_) return;
      job_(ctx_, tid);
      if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
        std::lock_guard<std::mutex> lock(m_);
        doneCv_.notify_one();
      }
    }
  }

  int n_;
  std::vector<std::thread> workers_;
  std::mutex m_;
  std::condition_variable cv_, doneCv_;
  std::atomic<std::uint64_t> gen_{0};
  std::atomic<int> pending_{0};
  bool stop_ = false;
  void (*job_)(void*, int) = nullptr;
  void* ctx_ = nullptr;
};

/// Runs `body(begin, end)` over [0, n) in chunks of fixed size taken dynamically by the team
/// (chunk boundaries do not depend on the thread count).
template <class Body>
void parallelChunks(Team& team, std::size_t n, std::size_t chunk, Body&& body,
                    std::exception_ptr& error, std::mutex& errorMutex) {
  std::atomic<std::size_t> next{0};
  auto job = [&](int) {
    try {
      for (;;) {
        const std::size_t a = next.fetch_add(chunk, std::memory_order_relaxed);
        if (a >= n) break;
        body(a, std::min(n, a + chunk));
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(errorMutex);
      if (!error) error = std::current_exception();
    }
  };
  if (n <= chunk)
    job(0);  // one chunk: no worker to wake
  else
    team.run(job);
  if (error) std::rethrow_exception(error);
}
}  // namespace detail
}  // namespace surfmesh
