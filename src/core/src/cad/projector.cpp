// SurfMesh — the CAD recovery's Projector (see projector.h).
#include "projector.h"

#include <BRep_Tool.hxx>
#include <Extrema_ExtPC.hxx>
#include <Extrema_POnSurf.hxx>
#include <TopAbs_State.hxx>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace surfmesh::cad_detail {

Projector::FaceTools& Projector::tools(int f) {
  FaceTools& ft = tools_[static_cast<std::size_t>(f)];
  if (!ft.used) {
    ft.used = true;
    used_.push_back(f);
  }
  if (ft.ready) return ft;
  ft.ready = true;
  ft.g = Handle(Geom_Surface)::DownCast(BRep_Tool::Surface(s_.face(f))->Copy());
  GeomAdaptor_Surface probe(ft.g);
  switch (probe.GetType()) {
    case GeomAbs_Plane:
    case GeomAbs_Cylinder:
    case GeomAbs_Cone:
    case GeomAbs_Sphere:
    case GeomAbs_Torus:
      ft.sas = std::make_unique<ShapeAnalysis_Surface>(ft.g);
      return ft;
    default:
      break;
  }
  double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
  ft.g->Bounds(u0, u1, v0, v1);
  const ParamBounds& fb = s_.surface(f).faceUVBounds();
  const double mu = 0.5 * (fb.umax - fb.umin) + 1.0, mv = 0.5 * (fb.vmax - fb.vmin) + 1.0;
  if (Precision::IsInfinite(u0)) u0 = fb.umin - mu;
  if (Precision::IsInfinite(u1)) u1 = fb.umax + mu;
  if (Precision::IsInfinite(v0)) v0 = fb.vmin - mv;
  if (Precision::IsInfinite(v1)) v1 = fb.vmax + mv;
  ft.ad = std::make_unique<GeomAdaptor_Surface>(ft.g, u0, u1, v0, v1);
  ft.loc = std::make_unique<Extrema_GenLocateExtPS>(*ft.ad);
  // Start points of the local searches: a grid over the face's (u,v) range, kCells
  // intervals a side, refined along a direction in which the surface's normal turns by more
  // than kSampleTurn between neighbouring samples (a helical sweep, a long corrugated face),
  // so that the nearest sample lies on the same side of the surface as the point.
  // The coarse grid's unit normals (zero where degenerate) measure the turn.
  std::vector<Vec3> normals;
  auto sampleGrid = [&](int nu, int nv, std::vector<Vec3>* sampleNormals) {
    ft.samples.clear();
    ft.sampleUV.clear();
    ft.sampleDegenerate.clear();
    for (int i = 0; i <= nu; ++i)
      for (int j = 0; j <= nv; ++j) {
        const double u = fb.umin + (fb.umax - fb.umin) * i / nu;
        const double v = fb.vmin + (fb.vmax - fb.vmin) * j / nv;
        gp_Pnt q;
        gp_Vec du, dv;
        ft.ad->D1(u, v, q, du, dv);
        ft.samples.emplace_back(q.X(), q.Y(), q.Z());
        ft.sampleUV.emplace_back(u, v);
        const SurfaceD1 d{ft.samples.back(), Vec3(du.X(), du.Y(), du.Z()),
                          Vec3(dv.X(), dv.Y(), dv.Z())};
        const bool degenerate = isDegenerate(d);
        ft.sampleDegenerate.push_back(degenerate ? 1 : 0);
        if (sampleNormals)
          sampleNormals->push_back(degenerate ? Vec3::Zero()
                                              : d.du.cross(d.dv).normalized().eval());
      }
  };
  sampleGrid(kCells, kCells, &normals);
  double turnU = 0.0, turnV = 0.0;  // largest normal turn between neighbouring samples
  auto turn = [&](std::size_t a, std::size_t b) {  // zero next to a degenerate sample
    return std::atan2(normals[a].cross(normals[b]).norm(), normals[a].dot(normals[b]));
  };
  for (int i = 0; i <= kCells; ++i)
    for (int j = 0; j <= kCells; ++j) {
      const std::size_t k = static_cast<std::size_t>(i * (kCells + 1) + j);
      if (i < kCells) turnU = std::max(turnU, turn(k, k + kCells + 1));
      if (j < kCells) turnV = std::max(turnV, turn(k, k + 1));
    }
  auto refined = [](double t) {
    return std::max(kCells, static_cast<int>(std::ceil(kCells * t / kSampleTurn)));
  };
  int nu = refined(turnU), nv = refined(turnV);
  const double total = (nu + 1.0) * (nv + 1.0);
  if (total > static_cast<double>(kMaxSamples)) {  // at most kMaxSamples samples
    const double scale = std::sqrt(static_cast<double>(kMaxSamples) / total);
    nu = std::max(kCells, static_cast<int>(nu * scale));
    nv = std::max(kCells, static_cast<int>(nv * scale));
    const int rest = static_cast<int>(kMaxSamples) / (kCells + 1) - 1;
    if (nu == kCells) nv = std::min(nv, rest);
    if (nv == kCells) nu = std::min(nu, rest);
  }
  if (nu != kCells || nv != kCells) sampleGrid(nu, nv, nullptr);
  // Boxes around the surface over the face's (u,v) range: lower bounds on distances.
  ft.cells = surfacePatchBoxes(*ft.ad, fb, kCells, 1e-9 * s_.diagonal());
  if (!ft.cells.empty()) {
    constexpr int nb = kCells / kBlock;
    ft.blocks.assign(nb * nb, Box{kInf, kInf, kInf, -kInf, -kInf, -kInf});
    for (int i = 0; i < kCells; ++i)
      for (int j = 0; j < kCells; ++j) {
        Box& b = ft.blocks[static_cast<std::size_t>((i / kBlock) * nb + j / kBlock)];
        const Box& c = ft.cells[static_cast<std::size_t>(i * kCells + j)];
        for (std::size_t k = 0; k < 3; ++k) {
          b[k] = std::min(b[k], c[k]);
          b[k + 3] = std::max(b[k + 3], c[k + 3]);
        }
      }
  }
  // Inside a span of any knot vector but a contrived one.
  ft.rest = Vec2(fb.umin + 0.3819660112501051 * (fb.umax - fb.umin),
                 fb.vmin + 0.6180339887498949 * (fb.vmax - fb.vmin));
  rest(ft);
  return ft;
}

double Projector::lowerBound(int f, const Vec3& p, double box) {
  if (box > 0.0) return box;
  const FaceTools& ft = tools(f);
  if (ft.cells.empty()) return box;
  constexpr int nb = kCells / kBlock;
  double best2 = kInf;
  for (int g = 0; g < nb * nb && best2 > 0.0; ++g) {
    if (boxDistance2(ft.blocks[static_cast<std::size_t>(g)], p) >= best2) continue;
    const int i0 = (g / nb) * kBlock, j0 = (g % nb) * kBlock;
    for (int i = i0; i < i0 + kBlock; ++i)
      for (int j = j0; j < j0 + kBlock; ++j)
        best2 =
            std::min(best2, boxDistance2(ft.cells[static_cast<std::size_t>(i * kCells + j)], p));
  }
  return std::max(box, std::sqrt(best2));
}

double Projector::edgeDistance(int e, const Vec3& p, double* t) {
  const OccEdgeCurve& c = s_.curve(e);
  if (c.isDegenerated()) {
    *t = c.tmin();
    return (c.value(c.tmin()) - p).norm();
  }
  auto& ad = curves_[static_cast<std::size_t>(e)];
  if (!ad) ad = std::make_unique<BRepAdaptor_Curve>(s_.edge(e));
  const gp_Pnt P = toPnt(p);
  double param = ad->FirstParameter();
  double d2 = ad->Value(param).SquareDistance(P);
  const double tl = ad->LastParameter();
  const double d2l = ad->Value(tl).SquareDistance(P);
  if (d2l < d2) {
    d2 = d2l;
    param = tl;
  }
  try {
    Extrema_ExtPC ext(P, *ad);
    if (ext.IsDone())
      for (int i = 1; i <= ext.NbExt(); ++i)
        if (ext.IsMin(i) && ext.SquareDistance(i) < d2) {
          d2 = ext.SquareDistance(i);
          param = ext.Point(i).Parameter();
        }
  } catch (const Standard_Failure&) {
  }
  const double d = std::sqrt(d2);
  *t = param;
  return d;
}

double Projector::surfaceProjection(int f, const Vec3& p, FaceHit* hit) {
  const std::size_t fi = static_cast<std::size_t>(f);
  hit->face = f;
  hit->inside = false;
  FaceTools& ft = tools(f);
  const gp_Pnt P = toPnt(p);
  gp_Pnt2d uv;
  double gap = kInf;
  try {
    if (!ft.loc) {
      // Analytic surfaces: closed form (ElSLib) through ShapeAnalysis_Surface.
      uv = ft.sas->ValueOfUV(P, preci_);
      gap = ft.sas->Gap();
    } else {
      localProjection(ft, P, faceSlack_[fi], &uv, &gap);
    }
  } catch (const Standard_Failure&) {
    return kInf;
  }
  if (!std::isfinite(uv.X()) || !std::isfinite(uv.Y())) return kInf;
  const OccFaceSurface& surf = s_.surface(f);
  hit->uv = surf.wrap(Vec2(uv.X(), uv.Y()));
  hit->hasUV = true;
  hit->inside = classify(f, hit->uv);
  if (!hit->inside && (surf.uTurnPeriod() > 0.0 || surf.vTurnPeriod() > 0.0))
    hit->inside = findTurn(surf, f, &hit->uv);
  return gap;
}

void Projector::localProjection(FaceTools& ft, const gp_Pnt& P, double slack, gp_Pnt2d* uv,
                                double* gap) {
  const Vec3 p(P.X(), P.Y(), P.Z());
  // On the surface: within 1e-9 × diagonal, or within the rounding of a node stored in single
  // precision (FreeCAD's Mesh.Mesh; 2^-24 of each coordinate), whatever is larger. No other
  // sheet of a surface comes that close to a foot point, so the global search could only
  // confirm it.
  const double rounding =
      kSinglePrecisionRounding * std::max(s_.diagonal(), p.cwiseAbs().maxCoeff());
  const double enough = std::min(slack, std::max(1e-9 * s_.diagonal() + preci_, rounding));
  double bestGap = kInf;
  auto tryStart = [&](const Vec2& st) {
    const double startD2 = (ft.ad->Value(st.x(), st.y()).XYZ() - P.XYZ()).SquareModulus();
    auto take = [&]() {
      const double g = std::sqrt(ft.loc->SquareDistance());
      if (g < bestGap) {
        bestGap = g;
        double u = 0.0, v = 0.0;
        ft.loc->Point().Parameter(u, v);
        uv->SetCoord(u, v);
      }
    };
    ft.loc->Perform(P, st.x(), st.y(), Standard_False);
    if (ft.loc->IsDone() && ft.loc->SquareDistance() <= startD2 * (1.0 + 1e-12)) take();
    if (bestGap > enough) {
      ft.loc->Perform(P, st.x(), st.y(), Standard_True);
      if (ft.loc->IsDone()) take();
    }
    return bestGap <= enough;
  };
  bool ok = ft.hasLast && tryStart(ft.last);
  if (!ok) {
    // Off the surface from the previous foot point: what that start found depends on the
    // query before this one, so it is dropped, and the fixed starts and the global search
    // decide alone (a node's distance to a face it is not on then does not depend on the
    // order of the nodes).
    bestGap = kInf;
    constexpr int kStarts = 4;
    std::array<std::pair<double, std::size_t>, kStarts> nearest;
    nearest.fill({kInf, 0});
    for (std::size_t k = 0; k < ft.samples.size(); ++k) {
      if (ft.sampleDegenerate[k]) continue;
      const double d = (ft.samples[k] - p).squaredNorm();
      if (d >= nearest[kStarts - 1].first) continue;
      int i = kStarts - 1;
      while (i > 0 && nearest[static_cast<std::size_t>(i) - 1].first > d) {
        nearest[static_cast<std::size_t>(i)] = nearest[static_cast<std::size_t>(i) - 1];
        --i;
      }
      nearest[static_cast<std::size_t>(i)] = {d, k};
    }
    for (const auto& [d, k] : nearest) {
      if (!std::isfinite(d)) break;
      if (tryStart(ft.sampleUV[k])) break;
    }
  }
  // On the surface: done. Off it, even by less than the face's slack (a mesher's node next
  // to a sloppy edge), the local searches may have stopped at a foot point that is not the
  // nearest (a thin face folded close to itself) or on the border of the parameter range;
  // which one they find depends on the start, hence on the nodes queried before. The global
  // search decides, so that a node's faces do not depend on the order of the nodes.
  if (bestGap <= enough) {
    ft.last = Vec2(uv->X(), uv->Y());
    ft.hasLast = true;
    *gap = bestGap;
    return;
  }
  // Not on the surface as far as the local searches tell: the global search.
  if (!ft.sas) {
    ft.sas = std::make_unique<ShapeAnalysis_Surface>(ft.g);
    rest(ft);
  }
  const gp_Pnt2d g = ft.sas->ValueOfUV(P, preci_);
  if (ft.sas->Gap() < bestGap || !std::isfinite(bestGap)) {
    *uv = g;
    bestGap = ft.sas->Gap();
  }
  *gap = bestGap;
}

bool Projector::findTurn(const OccFaceSurface& surf, int f, Vec2* uv) {
  const ParamBounds& b = surf.faceUVBounds();
  const double pu = surf.uTurnPeriod(), pv = surf.vTurnPeriod();
  const Vec2 base = *uv;
  auto range = [](double x, double lo, double hi, double p, int* k0, int* k1) {
    if (p <= 0.0) {
      *k0 = *k1 = 0;
      return;
    }
    *k0 = static_cast<int>(std::ceil((lo - x) / p - 1e-9));
    *k1 = static_cast<int>(std::floor((hi - x) / p + 1e-9));
    if (*k1 - *k0 > 16) *k1 = *k0 + 16;
  };
  int iu0, iu1, iv0, iv1;
  range(base.x(), b.umin, b.umax, pu, &iu0, &iu1);
  range(base.y(), b.vmin, b.vmax, pv, &iv0, &iv1);
  for (int i = iu0; i <= iu1; ++i)
    for (int j = iv0; j <= iv1; ++j) {
      const Vec2 c(base.x() + i * pu, base.y() + j * pv);
      if (classify(f, c)) {
        *uv = c;
        return true;
      }
    }
  return false;
}

FaceHit Projector::faceDistance(int f, const Vec3& p, double bound) {
  FaceHit hit;
  hit.face = f;
  const double gap = surfaceProjection(f, p, &hit);
  const double slack = faceSlack_[static_cast<std::size_t>(f)];
  if (hit.inside && gap <= slack) {
    hit.dist = gap;
    return hit;
  }
  // Outside the trimming loops, or a projection that is not clearly on the face (a local
  // search may miss a point on the face's boundary): the nearest boundary edge too.
  double best = kInf, bestT = 0.0;
  int bestE = -1;
  const double cap = hit.inside ? std::min(bound, gap) : bound;
  for (int e : s_.faceEdges(f)) {
    if (s_.isDegeneratedEdge(e)) continue;
    const double lb = boxDistance(edgeBoxes_[static_cast<std::size_t>(e)], p);
    if (lb > std::min(best, cap)) continue;
    double t = 0.0;
    const double d = edgeDistance(e, p, &t);
    if (d < best) {
      best = d;
      bestE = e;
      bestT = t;
    }
  }
  if (hit.inside && !(best < gap)) {
    hit.dist = gap;
    return hit;
  }
  if (bestE >= 0) {
    try {
      const OccFaceSurface& surf = s_.surface(f);
      hit.uv = surf.wrap(s_.curve(bestE).uvOnFace(f, bestT, hit.uv));
      hit.hasUV = hit.uv.allFinite();
    } catch (const std::exception&) {
    }
  }
  if (!std::isfinite(best) && std::isfinite(gap))  // every edge beyond the bound
    best = std::isfinite(bound) ? std::max(gap, std::nextafter(bound, kInf)) : gap;
  hit.dist = best;
  return hit;
}

double Projector::boundarySlack(int f, const Vec3& p, double base) {
  double best = kInf;
  int be = -1;
  for (int e : s_.faceEdges(f)) {
    if (s_.isDegeneratedEdge(e)) continue;
    if (boxDistance(edgeBoxes_[static_cast<std::size_t>(e)], p) > best) continue;
    double t = 0.0;
    const double d = edgeDistance(e, p, &t);
    if (d < best) {
      best = d;
      be = e;
    }
  }
  double tol = BRep_Tool::Tolerance(s_.face(f));
  if (be >= 0) {
    tol = std::max(tol, BRep_Tool::Tolerance(s_.edge(be)));
    for (int v : s_.edgeVertices(be)) tol = std::max(tol, s_.vertexTolerance(v));
  }
  return std::max(base, 2.0 * tol);
}

void Projector::toleranceHint(const Vec3& p, const BoxGrid& vertexGrid,
                              const std::vector<double>& vertexTol, const BoxGrid& edgeGrid,
                              const std::vector<double>& edgeTol, int* hv, int* he) {
  *hv = *he = -1;
  double best = kInf;
  vertexGrid.forEach(p, [&](int v) {
    const double d = (s_.vertexPoint(v) - p).norm();
    if (d <= vertexTol[static_cast<std::size_t>(v)] && d < best) {
      best = d;
      *hv = v;
    }
  });
  if (*hv >= 0) return;
  int found = 0;
  edgeGrid.forEach(p, [&](int e) {
    if (found > 1 || s_.isDegeneratedEdge(e)) return;
    double t = 0.0;
    if (edgeDistance(e, p, &t) < edgeTol[static_cast<std::size_t>(e)]) {
      ++found;
      *he = e;
    }
  });
  if (found != 1) *he = -1;
}

bool Projector::vertexNearerThan(const Vec3& p, double d, int except) const {
  for (int v = 0; v < s_.vertexCount(); ++v)
    if (v != except && (s_.vertexPoint(v) - p).norm() < d) return true;
  return false;
}

bool Projector::edgeNearerThan(const Vec3& p, double d, int except) {
  for (int e = 0; e < s_.edgeCount(); ++e) {
    if (e == except || s_.isDegeneratedEdge(e)) continue;
    if (boxDistance(edgeBoxes_[static_cast<std::size_t>(e)], p) >= d) continue;
    double t = 0.0;
    if (edgeDistance(e, p, &t) < d) return true;
  }
  return false;
}

double Projector::shapeDistance(const Vec3& p, int* nearestFace) {
  std::vector<std::pair<double, int>> order;
  order.reserve(faceBoxes_.size());
  for (std::size_t f = 0; f < faceBoxes_.size(); ++f)
    order.emplace_back(boxDistance(faceBoxes_[f], p), static_cast<int>(f));
  std::sort(order.begin(), order.end());
  double best = kInf;
  int bf = -1;
  for (const auto& [lb, f] : order) {
    if (lb > best) break;
    const FaceHit h = faceDistance(f, p, kInf);
    if (h.dist < best) {
      best = h.dist;
      bf = f;
    }
  }
  if (nearestFace) *nearestFace = bf;
  return best;
}

double Projector::wholeShapeDistance(const Vec3& p, NodeClass* kind, int* id) {
  int f = -1;
  double best = shapeDistance(p, &f);
  *kind = NodeClass::Face;
  *id = f;
  for (int e = 0; e < s_.edgeCount(); ++e) {
    if (!s_.edgeFaces(e).empty() || s_.isDegeneratedEdge(e)) continue;
    if (boxDistance(edgeBoxes_[static_cast<std::size_t>(e)], p) >= best) continue;
    double t = 0.0;
    const double d = edgeDistance(e, p, &t);
    if (d < best) {
      best = d;
      *kind = NodeClass::Edge;
      *id = e;
    }
  }
  for (int v = 0; v < s_.vertexCount(); ++v) {
    if (!s_.vertexEdges(v).empty()) continue;
    const double d = (s_.vertexPoint(v) - p).norm();
    if (d < best) {
      best = d;
      *kind = NodeClass::Vertex;
      *id = v;
    }
  }
  return best;
}

void Projector::resultDistances(int f, const Vec3& p, double onShape, double* toFace,
                                double* toShape) {
  // `best`, or edge e's 3D curve if nearer (box-pruned).
  auto viaEdge = [&](int e, double best) {
    if (s_.isDegeneratedEdge(e) || boxDistance(edgeBoxes_[static_cast<std::size_t>(e)], p) >= best)
      return best;
    double t = 0.0;
    return std::min(best, edgeDistance(e, p, &t));
  };
  *toFace = kNaN;
  if (f >= 0) {
    double d = faceDistance(f, p, kInf).dist;
    if (d > onShape)
      for (int e : s_.faceEdges(f)) d = viaEdge(e, d);
    *toFace = d;
    // On its face, the point is on the shape: no global search (it cost more than a run's
    // sweeps on small parts). The distance given is the face's, an upper bound.
    if (d <= onShape) {
      *toShape = d;
      return;
    }
  }
  NodeClass kind;
  int id = -1;
  double whole = wholeShapeDistance(p, &kind, &id);
  if (whole > onShape)
    for (int e = 0; e < s_.edgeCount(); ++e) whole = viaEdge(e, whole);
  *toShape = whole;
}

double Projector::locate(const Vec3& p, double close, NodeClass* kind, int* id, double* t) {
  *t = kNaN;
  for (int v = 0; v < s_.vertexCount(); ++v) {
    const double d = (s_.vertexPoint(v) - p).norm();
    if (d <= std::max(close, s_.vertexTolerance(v))) {
      *kind = NodeClass::Vertex;
      *id = v;
      return d;
    }
  }
  double best = kInf;
  for (int e = 0; e < s_.edgeCount(); ++e) {
    if (s_.isDegeneratedEdge(e)) continue;
    const double reach = std::max(close, BRep_Tool::Tolerance(s_.edge(e)));
    if (boxDistance(edgeBoxes_[static_cast<std::size_t>(e)], p) > std::min(reach, best)) continue;
    double te = 0.0;
    const double d = edgeDistance(e, p, &te);
    if (d <= reach && d < best) {
      best = d;
      *kind = NodeClass::Edge;
      *id = e;
      *t = te;
    }
  }
  if (std::isfinite(best)) return best;
  return wholeShapeDistance(p, kind, id);
}

void Projector::facesNear(const Vec3& p, double tol, std::vector<FaceHit>* out, double keep) {
  out->clear();
  const double r1 = std::min(tol, 2.0 * maxSlack_);
  double dmin = kInf;
  std::vector<unsigned char>& seen = seen_;
  seen.assign(faceBoxes_.size(), 0);
  auto project = [&](int f) {
    FaceHit h = faceDistance(f, p, tol);
    if (h.dist <= tol) {
      dmin = std::min(dmin, h.dist);
      out->push_back(h);
    }
  };
  if (keep > 0.0) {
    auto& order = order_;
    order.clear();
    for (std::size_t f = 0; f < faceBoxes_.size(); ++f) {
      const double box = boxDistance(faceBoxes_[f], p);
      if (box > r1) continue;
      seen[f] = 1;
      order.emplace_back(lowerBound(static_cast<int>(f), p, box), static_cast<int>(f));
    }
    std::sort(order.begin(), order.end());
    for (const auto& [lb, f] : order) {
      if (lb > tol) break;
      if (lb <= dmin + std::max(keep, faceSlack_[static_cast<std::size_t>(f)])) project(f);
    }
    std::sort(out->begin(), out->end(),
              [](const FaceHit& a, const FaceHit& b) { return a.face < b.face; });
  }
  auto scan = [&](double radius) {
    for (std::size_t f = 0; f < faceBoxes_.size(); ++f) {
      if (seen[f] || boxDistance(faceBoxes_[f], p) > radius) continue;
      seen[f] = 1;
      project(static_cast<int>(f));
    }
  };
  if (keep <= 0.0) scan(r1);
  if (dmin <= maxSlack_ || r1 >= tol) return;
  scan(std::isfinite(dmin) ? std::min(tol, dmin + maxSlack_) : tol);
}
/// What a Projector works with: the boxes of the shape's faces and edges, and per face how much
/// farther than the nearest face a node may be and still lie on it (the sloppiest tolerance
/// among the face's edges and vertices, at least 1e-6·diag, at most `tol`).
void projectorGeometry(const CadShape& S, double tol, std::vector<Box>* faceBoxes,
                       std::vector<Box>* edgeBoxes, std::vector<double>* faceSlack) {
  const int NF = S.faceCount(), NE = S.edgeCount();
  faceBoxes->assign(static_cast<std::size_t>(NF), Box{});
  edgeBoxes->assign(static_cast<std::size_t>(NE), Box{});
  faceSlack->assign(static_cast<std::size_t>(NF), 0.0);
  for (int f = 0; f < NF; ++f) (*faceBoxes)[static_cast<std::size_t>(f)] = toBox(S.faceBox(f));
  for (int e = 0; e < NE; ++e) (*edgeBoxes)[static_cast<std::size_t>(e)] = toBox(S.edgeBox(e));
  for (int f = 0; f < NF; ++f) {
    double t = BRep_Tool::Tolerance(S.face(f));
    for (int e : S.faceEdges(f)) {
      t = std::max(t, BRep_Tool::Tolerance(S.edge(e)));
      for (int v : S.edgeVertices(e)) t = std::max(t, S.vertexTolerance(v));
    }
    (*faceSlack)[static_cast<std::size_t>(f)] =
        std::min(tol, std::max(1e-6 * S.diagonal(), 2.0 * t));
  }
}

}  // namespace surfmesh::cad_detail
