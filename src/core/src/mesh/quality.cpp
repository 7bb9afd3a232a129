#include "surfmesh/mesh/quality.h"

#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/element_measure.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <memory>
#include <thread>

namespace surfmesh {

QualityStats computeStats(const std::vector<double>& quality,
                          const std::vector<unsigned char>& tangled) {
  QualityStats s;
  s.elements = quality.size();
  if (quality.empty()) return s;
  s.min = quality.front();
  s.max = quality.front();
  double sum = 0.0;
  for (double q : quality) {
    s.min = std::min(s.min, q);
    s.max = std::max(s.max, q);
    sum += q;
  }
  s.mean = sum / static_cast<double>(quality.size());
  double var = 0.0;
  for (double q : quality) var += (q - s.mean) * (q - s.mean);
  s.stddev = std::sqrt(var / static_cast<double>(quality.size()));
  s.tangled = static_cast<std::size_t>(std::count(tangled.begin(), tangled.end(), 1));
  return s;
}

ElementQuality elementQuality(const SurfaceMesh& mesh, std::size_t e, const PlanarMeasure& m,
                              const std::vector<const Surface*>& surfaces) {
  const int n = mesh.elementSize(e);
  const std::int32_t* nd = mesh.elementNodes(e);
  Vec3 x[kMaxElementNodes];
  for (int k = 0; k < n; ++k) x[k] = mesh.xyz[static_cast<std::size_t>(nd[k])];
  Vec3 corners[4];
  const Vec3 normal = elementReferenceNormal(mesh, e, surfaces, corners);
  const ElementEval ev = elementDistortion(m, mesh.elemType[e], x, normal, 0.0);
  const bool bad = ev.tangled || !std::isfinite(ev.eta) || !(ev.eta > 0.0);
  bool across = standsAcross(mesh.elemType[e], x, corners);
  if (!across && !bad && isHighOrderTriangle(mesh.elemType[e])) {
    // Its tangent plane turned across the surface's inside the element (certificate.h).
    // Where the face's normal turns too fast within the element for the interpolation of
    // its nodes' normals, the face's own normals on pieces of the element decide.
    Vec3 nodeNormals[kMaxElementNodes];
    elementNodeNormals(mesh, e, surfaces, nodeNormals);
    across =
        !curvedTriangleAlongFace(mesh, e, *surfaces[static_cast<std::size_t>(mesh.elemFace[e])], x,
                                 nodeNormals, mesh.elementUV(e));
  }
  ElementQuality q;
  q.tangled = bad;
  q.across = across;
  q.edgeOn = standsEdgeOn(mesh.elemType[e], x, corners);
  q.distortion = bad ? std::numeric_limits<double>::infinity() : ev.eta;
  q.quality = bad ? 0.0 : std::min(1.0, 1.0 / ev.eta);
  q.minSigma = ev.minSigma;
  return q;
}

MeshQuality measureQuality(const SurfaceMesh& mesh, const PlanarMeasure& m) {
  const std::size_t E = mesh.elementCount();
  MeshQuality r;
  r.quality.resize(E);
  r.distortion.resize(E);
  r.tangled.resize(E);
  r.minSigma.resize(E);
  r.across.resize(E);
  r.edgeOn.resize(E);
  // Elements [begin, end) with the surfaces `surfaces` (mesh.surfaces or a thread's clones).
  auto range = [&](std::size_t begin, std::size_t end,
                   const std::vector<const Surface*>& surfaces) {
    for (std::size_t e = begin; e < end; ++e)
      storeElementQuality(r, e, elementQuality(mesh, e, m, surfaces));
  };
  // Elements are independent: big meshes are cut into one contiguous block per hardware
  // thread; the threads after the first evaluate clones of the surfaces (not thread-safe).
  constexpr std::size_t kPerThread = 20000;
  const std::size_t hc = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t T = std::min<std::size_t>({hc, 16, std::max<std::size_t>(1, E / kPerThread)});
  if (T <= 1) {
    range(0, E, mesh.surfaces);
  } else {
    std::vector<std::vector<std::unique_ptr<Surface>>> owned(T - 1);
    std::vector<std::vector<const Surface*>> views(T - 1);
    for (std::size_t t = 0; t + 1 < T; ++t)
      for (const Surface* sf : mesh.surfaces) {
        owned[t].push_back(sf ? sf->clone() : nullptr);
        views[t].push_back(owned[t].back().get());
      }
    std::vector<std::exception_ptr> errors(T);
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < T; ++t)
      pool.emplace_back([&, t]() {
        try {
          range(E * t / T, E * (t + 1) / T, views[t - 1]);
        } catch (...) {
          errors[t] = std::current_exception();
        }
      });
    try {
      range(0, E / T, mesh.surfaces);
    } catch (...) {
      errors[0] = std::current_exception();
    }
    for (auto& th : pool) th.join();
    for (const auto& err : errors)
      if (err) std::rethrow_exception(err);
  }
  r.stats = computeStats(r.quality, r.tangled);
  r.stats.across = static_cast<std::size_t>(std::count(r.across.begin(), r.across.end(), 1));
  return r;
}

}  // namespace surfmesh
