// SurfMesh — per-element quality of a surface mesh and the statistics of the paper's tables.
#pragma once

#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <vector>

namespace surfmesh {

/// Min, max, mean and standard deviation of the quality q = 1/η (0 for tangled elements), and
/// the number of tangled elements: the columns of the paper's Tables 1–4.
struct QualityStats {
  double min = 0.0;
  double max = 0.0;
  double mean = 0.0;
  double stddev = 0.0;  ///< population standard deviation
  std::size_t tangled = 0;
  std::size_t elements = 0;
  /// Elements standing across their surface (standsAcross), tangled or not, and the untangled
  /// high-order triangles whose Jacobian is not proven positive against the face's normals
  /// interpolated from their nodes (certifyTriangleAgainstNodeNormals): a diagnostic next to
  /// the paper's statistics, which it does not change. Filled by measureQuality.
  std::size_t across = 0;
};

struct MeshQuality {
  std::vector<double> quality;         ///< per element, q ∈ [0, 1], 0 for tangled/degenerate
  std::vector<double> distortion;      ///< per element, η ∈ [1, ∞]
  std::vector<unsigned char> tangled;  ///< per element, 1 when tangled or degenerate
  std::vector<double> minSigma;        ///< per element, smallest scaled det S (≤ 0: tangled)
  std::vector<unsigned char> across;   ///< per element, 1 when standing across its surface
                                       ///< (as QualityStats::across)
  std::vector<unsigned char> edgeOn;   ///< per element, 1 when standing edge-on to its
                                       ///< surface (standsEdgeOn; not in the statistics)
  QualityStats stats;
  /// Element e tangled or standing across: invalid for a solver (as ElementQuality::invalid).
  bool invalid(std::size_t e) const { return tangled[e] || (e < across.size() && across[e]); }
  /// How invalid element e is: 0 valid, 1 standing across or edge-on to its surface but not
  /// tangled (its measured quality positive), 2 tangled (quality 0). keepValidElements puts
  /// back what a run made worse by this grade: a run never stands a triangle edge-on either.
  unsigned char grade(std::size_t e) const {
    if (tangled[e]) return 2;
    return (e < across.size() && across[e]) || (e < edgeOn.size() && edgeOn[e]) ? 1 : 0;
  }
};

/// Statistics of a list of qualities (tangled = number of entries flagged in `tangled`).
QualityStats computeStats(const std::vector<double>& quality,
                          const std::vector<unsigned char>& tangled);

/// One element's entries of MeshQuality.
struct ElementQuality {
  double quality = 0.0;
  double distortion = 0.0;
  bool tangled = false;
  double minSigma = 0.0;
  bool across = false;
  bool edgeOn = false;  ///< standsEdgeOn (as MeshQuality::edgeOn)
  /// Tangled or standing across: invalid for a solver.
  bool invalid() const { return tangled || across; }
};

/// The number of invalid elements of q (tangled or standing across: ElementQuality::invalid).
inline std::size_t invalidCount(const MeshQuality& q) {
  std::size_t n = 0;
  for (std::size_t e = 0; e < q.tangled.size(); ++e) n += q.invalid(e) ? 1 : 0;
  return n;
}

/// Puts element e's entries `eq` into q (its statistics are not updated).
inline void storeElementQuality(MeshQuality& q, std::size_t e, const ElementQuality& eq) {
  q.quality[e] = eq.quality;
  q.distortion[e] = eq.distortion;
  q.tangled[e] = eq.tangled ? 1 : 0;
  q.minSigma[e] = eq.minSigma;
  q.across[e] = eq.across ? 1 : 0;
  q.edgeOn[e] = eq.edgeOn ? 1 : 0;
}

/// Quality of element e of `mesh` with measure `m` (δ = 0), as measureQuality gives it, with
/// the surfaces taken from `surfaces` (mesh.surfaces, or a thread's clones).
ElementQuality elementQuality(const SurfaceMesh& mesh, std::size_t e, const PlanarMeasure& m,
                              const std::vector<const Surface*>& surfaces);

/// Quality of every element of `mesh` with measure `m` (δ = 0). Never throws for finite input;
/// elements with non-finite coordinates are reported as tangled.
MeshQuality measureQuality(const SurfaceMesh& mesh, const PlanarMeasure& m);

}  // namespace surfmesh
