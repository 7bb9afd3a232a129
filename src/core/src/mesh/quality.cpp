#include "surfmesh/mesh/quality.h"

#include "surfmesh/measures/element_measure.h"

#include <algorithm>
#include <cmath>

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

MeshQuality measureQuality(const SurfaceMesh& mesh, const PlanarMeasure& m) {
  const std::size_t E = mesh.elementCount();
  MeshQuality r;
  r.quality.resize(E);
  r.distortion.resize(E);
  r.tangled.resize(E);
  r.minSigma.resize(E);
  std::vector<Vec3> x;
  for (std::size_t e = 0; e < E; ++e) {
    const int n = mesh.elementSize(e);
    const std::int32_t* nd = mesh.elementNodes(e);
    x.resize(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) x[static_cast<std::size_t>(k)] = mesh.xyz[nd[k]];
    const Vec3 normal = elementReferenceNormal(mesh, e);
    const ElementEval ev = elementDistortion(m, mesh.elemType[e], x.data(), normal, 0.0);
    const bool bad = ev.tangled || !std::isfinite(ev.eta) || !(ev.eta > 0.0);
    r.tangled[e] = bad ? 1 : 0;
    r.distortion[e] = bad ? std::numeric_limits<double>::infinity() : ev.eta;
    r.quality[e] = bad ? 0.0 : std::min(1.0, 1.0 / ev.eta);
    r.minSigma[e] = ev.minSigma;
  }
  r.stats = computeStats(r.quality, r.tangled);
  return r;
}

}  // namespace surfmesh
