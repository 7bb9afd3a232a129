// A node's safeguarded Newton step: in (u,v) for a node on a face, along t for a node sliding
// on a CAD edge, with its line search, its fallback directions and the targets it tries when
// a fold stalls it (kernel centre, neighbours' centroid, the edge's interval).
#include "node_updater.h"

namespace surfmesh {
namespace detail {

/// A node whose submesh holds an element with η above this tries fallback directions when its
/// Newton step fails (quality below 1/4).
constexpr double kFallbackEta = 4.0;

/// The line search stops halving once the step's first-order 3D length is below this fraction
/// of moveTol × the node's local size (moveTol = 0: it always runs maxLineSearch halvings).
constexpr double kMinStepFraction = 0.1;

namespace {

/// The tangent basis of a Face node's (u,v) from its surface derivatives.
Tangent tangentOf(const NodeD2& d) {
  Tangent T;
  T.du = d.du;
  T.dv = d.dv;
  T.metric(0, 0) = d.du.squaredNorm();
  T.metric(0, 1) = T.metric(1, 0) = d.du.dot(d.dv);
  T.metric(1, 1) = d.dv.squaredNorm();
  return T;
}

/// The fallback steps of a Face node (updateFaceNode) in (u,v): along ±φ_u, ±φ_v and the
/// diagonals, a quarter of the local size L long. False at a degenerate point.
bool compassSteps(const NodeD2& d, double L, Vec2* dirs) {
  const double lu = d.du.norm(), lv = d.dv.norm();
  if (!(lu > 0.0 && lv > 0.0)) return false;
  const Vec2 eu(0.25 * L / lu, 0.0), ev(0.0, 0.25 * L / lv);
  dirs[0] = eu;
  dirs[1] = -eu;
  dirs[2] = ev;
  dirs[3] = -ev;
  dirs[4] = (eu + ev) * 0.7071067811865476;
  dirs[5] = (eu - ev) * 0.7071067811865476;
  dirs[6] = (ev - eu) * 0.7071067811865476;
  dirs[7] = -(eu + ev) * 0.7071067811865476;
  return true;
}

}  // namespace

double NodeUpdater::updateFaceNode(std::size_t i) {
  const int face = s_.mesh.nodeFace[i];
  const Surface& surf = *w_.geo.surfaces[static_cast<std::size_t>(face)];
  if (s_.end(i) == s_.begin(i)) return 0.0;
  const double L = s_.localSize(i);
  if (!(L > 0.0)) return 0.0;
  const double orient = static_cast<double>(
      s_.mesh.faceOrientation[static_cast<std::size_t>(face)] * surf.normalSign());
  const bool monotone = s_.opt.monotone;
  auto zero = [](std::size_t) { return Vec3::Zero().eval(); };
  double moved = 0.0;
  for (int it = 0; it < s_.opt.innerIterations; ++it) {
    const Vec2 uv0 = s_.uv[i];
    if (!s_.d2Valid[i]) {
      const SurfaceD2 d = surf.d2(uv0.x(), uv0.y());
      s_.d2[i] = {d.du, d.dv, d.duu, d.duv, d.dvv};
      s_.d2Valid[i] = 1;
    }
    const NodeD2& d = s_.d2[i];
    if (isDegenerate(d.du, d.dv)) return moved;  // a pole: stays fixed
    const Vec3 n0 = s_.nodeNormal[i];
    const Tangent T = tangentOf(d);
    Vec3 gx, hJ;
    const Vec3 x0 = s_.xyz[i];
    const LocalEval cur = evalLocal(
        i, x0, [&](std::size_t) { return n0; }, zero, monotone, nullptr, &gx, nullptr, &T, &hJ);
    if (!cur.finite || cur.f == 0.0) return moved;
    // Chain rule to (u,v): g_u = Jᵀ g, H_u = Jᵀ H J + Σ g·∇²φ (JᵀHJ assembled in evalLocal).
    const Vec2 gu(d.du.dot(gx), d.dv.dot(gx));
    Mat2 Hu;
    Hu(0, 0) = hJ.x() + gx.dot(d.duu);
    Hu(0, 1) = Hu(1, 0) = hJ.y() + gx.dot(d.duv);
    Hu(1, 1) = hJ.z() + gx.dot(d.dvv);
    if (!gu.allFinite() || !Hu.allFinite()) return moved;
    Vec2 dir = newtonDirection(gu, Hu);
    if (gu.dot(dir) >= 0.0) dir = -gu;  // not a descent direction: use the gradient
    // Cap the step so that its first-order 3D length is at most the local size.
    double len3 = (d.du * dir.x() + d.dv * dir.y()).norm();
    if (len3 > L) {
      dir *= L / len3;
      len3 = L;
    }
    const bool wantQ = monotone && cur.tangled == 0 && !s_.mode.relaxTangled;
    Vec2 uvNew;
    SurfaceD2 dn;
    Vec3 nn;
    LocalEval best = cur;      // acceptance threshold: a trial must beat it
    bool lostQuality = false;  // the last trial was rejected for lowering the minimum quality
    Vec2 acceptedStep = Vec2::Zero();  // the Newton step (or its multiple) accepted
    auto tryStep = [&](const Vec2& step) {
      lostQuality = false;
      const Vec2 uvT = surf.wrap(uv0 + step);
      // A node untangling a fold may go where OCC counts it on a tolerant edge of its face;
      // smoothing keeps nodes out of those zones (see OccFaceSurface::contains).
      if (!(cur.tangled > 0 ? surf.containsNearBoundary(uvT.x(), uvT.y())
                            : surf.contains(uvT.x(), uvT.y())))
        return false;
      const SurfaceD2 dT = surf.d2(uvT.x(), uvT.y());
      if (isDegenerate(dT.du, dT.dv)) return false;
      const Vec3 c = dT.du.cross(dT.dv);
      const Vec3 nT = (orient / c.norm()) * c;
      const LocalEval tr = evalLocal(
          i, dT.p, [&](std::size_t) { return nT; }, zero, wantQ, &best, nullptr, nullptr);
      lostQuality = tr.byQuality;
      if (!acceptable(best, tr)) return false;
      keepTrial();
      best = tr;
      uvNew = uvT;
      dn = dT;
      nn = nT;
      acceptedStep = step;
      return true;
    };
    bool accepted = false;
    // Smoothing sweeps (δ = 0) try the over-relaxed step ω × dir first when the node keeps
    // moving the way it did (see OptimizeOptions::overRelaxation), then the step and its
    // halvings.
    const bool over = overRelaxes(len3, L) && sameWay(s_.lastStep[i].cast<double>(), dir, T.metric);
    // Halvings stop below a tenth of the activity threshold moveTol × L: a shorter step
    // would not count as a move (the direction fails: e.g. it lowers the submesh's minimum
    // quality in monotone mode, or the node sits at its local minimum).
    // In monotone mode, when the submesh's minimum is the bar (qualityBar: it is at or below
    // the sweep's floor), a step that lowered it is not halved further when the worst
    // element's η grows along the direction: every shorter step lowers it too (to first
    // order). Above the floor, the element that fell below it need not be the worst.
    const double minStep = kMinStepFraction * s_.opt.moveTol * L;
    const bool worstGrows = wantQ && qualityBar(cur) == cur.minQuality &&
                            cur.gradWorst.dot(d.du * dir.x() + d.dv * dir.y()) > 0.0;
    for (int ls = over ? -1 : 0; ls < s_.opt.maxLineSearch && !accepted; ++ls) {
      const double alpha = stepFactor(ls);
      if (ls > 0 && (alpha * len3 < minStep || (lostQuality && worstGrows))) break;
      accepted = tryStep(alpha * dir);
    }
    const Vec2 newtonStep = accepted ? acceptedStep : Vec2::Zero();
    if ((!accepted || best.f > 0.5 * cur.f) && s_.mode.deltaHat == 0.0 &&
        cur.maxEta > kFallbackEta) {
      // A badly shaped submesh where the Newton direction fails or barely helps (e.g. three
      // nearly collinear nodes on a curved surface, whose element plane stands across the
      // surface: its orientation flips under any step along the gradient; or a needle left
      // by untangling, where the barrier's curvature makes Newton steps tiny). Try steps
      // along ±φ_u, ±φ_v and the diagonals, a quarter of the local size long, and keep the
      // best acceptable (it must beat the Newton step's result).
      Vec2 dirs[8];
      if ((s_.opt.escapes & kEscapeCompass) && compassSteps(d, L, dirs))
        for (double scale : {1.0, 0.5, 0.25})
          for (const Vec2& dd : dirs)
            if (tryStep(scale * dd)) accepted = true;
    }
    const bool creeping =
        accepted && best.tangled >= cur.tangled && (dn.p - x0).norm() < s_.opt.moveTol * L;
    if (s_.mode.deltaHat > 0.0 && cur.tangled > 0 && (!accepted || creeping) &&
        (s_.opt.escapes & kEscapeFoldTarget)) {
      // A fold the local Newton step cannot open (every step that lowers f̂ tangles another
      // element of the submesh, or the steps only creep towards a local minimum of f̂ with
      // an element still tangled — e.g. the node pulled onto the face boundary next to a
      // tangled sliver): try the centre of the node's kernel in (u,v) (where all its
      // elements are wound right in the parameter plane) and the parametric centroid of its
      // neighbours (a Laplacian step, as Gmsh's Laplace2D), and the points halfway and a
      // quarter of the way there. The candidate leaving the fewest elements of the submesh
      // tangled (then the lowest f̂) is taken when it leaves fewer tangled than the current
      // position and the Newton step — strict progress, so it cannot cycle.
      if (foldTarget(i, face, surf, uv0, d, orient, accepted ? best.tangled : cur.tangled, &uvNew,
                     &dn, &nn)) {
        accepted = true;
        acceptedStep = Vec2::Zero();
      }
    }
    const bool newton = accepted && acceptedStep == newtonStep;
    s_.lastStep[i] = newton ? Eigen::Vector2f(newtonStep.cast<float>()) : Eigen::Vector2f::Zero();
    if (!accepted) return moved;
    const double step = (dn.p - x0).norm();
    moved += step;
    s_.uv[i] = uvNew;
    s_.xyz[i] = dn.p;
    s_.nodeNormal[i] = nn;
    s_.d2[i] = {dn.du, dn.dv, dn.duu, dn.duv, dn.dvv};
    commitElements(i);
    if (step < 1e-14 * L) break;
  }
  return moved;
}

bool NodeUpdater::foldTarget(std::size_t i, int face, const Surface& surf, const Vec2& uv0,
                             const NodeD2& d, double orient, int threshold, Vec2* uv, SurfaceD2* dn,
                             Vec3* nn) {
  auto zero = [](std::size_t) { return Vec3::Zero().eval(); };
  Vec2 targets[2];
  int nt = 0;
  if (kernelCenter(i, face, surf, uv0, d, orient, &targets[nt])) ++nt;
  if (neighbourCentroid(i, face, surf, uv0, &targets[nt])) ++nt;
  int bestTangled = threshold;
  double bestF = kInf;
  bool found = false;
  for (int k = 0; k < nt; ++k)
    for (double a : {1.0, 0.5, 0.25}) {
      const Vec2 uvT = surf.wrap(uv0 + a * (targets[k] - uv0));
      if (!surf.containsNearBoundary(uvT.x(), uvT.y())) continue;
      const SurfaceD2 dT = surf.d2(uvT.x(), uvT.y());
      if (isDegenerate(dT.du, dT.dv)) continue;
      const Vec3 cr = dT.du.cross(dT.dv);
      const Vec3 nT = (orient / cr.norm()) * cr;
      const LocalEval tr = evalLocal(
          i, dT.p, [&](std::size_t) { return nT; }, zero, false, nullptr, nullptr, nullptr);
      if (!tr.finite) continue;
      if (tr.tangled < bestTangled || (tr.tangled == bestTangled && tr.f < bestF && bestF < kInf)) {
        bestTangled = tr.tangled;
        bestF = tr.f;
        found = true;
        *uv = uvT;
        *dn = dT;
        *nn = nT;
      }
    }
  return found;
}

double NodeUpdater::updateEdgeNode(std::size_t i) {
  const int edge = s_.mesh.nodeEdge[i];
  const Curve& curve = *w_.geo.curves[static_cast<std::size_t>(edge)];
  if (s_.end(i) == s_.begin(i)) return 0.0;
  const double L = s_.localSize(i);
  if (!(L > 0.0)) return 0.0;
  // The node stays between its neighbours on the same edge (and inside the edge's range).
  const double t0 = s_.t[i];
  double lo = curve.tmin(), hi = curve.tmax();
  const bool periodic = curve.isPeriodic();
  for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
    const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
    const std::int32_t* nd = s_.mesh.elementNodes(e);
    for (int k = 0; k < s_.mesh.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (j == i || s_.mesh.nodeEdge.empty() || s_.mesh.nodeEdge[j] != edge) continue;
      double tj = s_.t[j];
      if (periodic) tj = tj - std::round((tj - t0) / curve.period()) * curve.period();
      if (tj < t0) lo = std::max(lo, tj);
      if (tj > t0) hi = std::min(hi, tj);
    }
  }
  if (periodic) {
    // Without two neighbours on the edge a closed edge gives no interval: stay put.
    if (lo == curve.tmin() || hi == curve.tmax()) return 0.0;
  }
  const CurveD2 d = curve.d2(t0);
  if (!(d.dt.norm() > 0.0)) return 0.0;
  const Vec3* oldN = s_.edgeNormal.data() + s_.edgeSlot[i];
  auto old = [&](std::size_t j) { return oldN[j]; };
  Vec3 gx;
  Mat3 Hx;
  const Vec3 x0 = s_.xyz[i];
  const bool monotone = s_.opt.monotone;
  const LocalEval cur = evalLocal(i, x0, old, old, monotone, nullptr, &gx, &Hx);
  if (!cur.finite || cur.f == 0.0) return 0.0;
  double gt, Ht;
  chainToCurve(d, gx, Hx, &gt, &Ht);
  if (!std::isfinite(gt) || !std::isfinite(Ht) || gt == 0.0) return 0.0;
  double dt = (Ht > 0.0) ? -gt / Ht : -gt / (std::abs(Ht) + 1e-12);
  if (dt * gt > 0.0) dt = -dt;
  double len3 = std::abs(dt) * d.dt.norm();
  if (len3 > L) {
    dt *= L / len3;
    len3 = L;
  }
  const double margin = 1e-3 * (hi - lo);
  const bool wantQ = monotone && cur.tangled == 0;
  Vec3* trialN = w_.normals.data();
  const bool over = overRelaxes(len3, L) && s_.lastStep[i].x() * dt > 0.0;  // as for Face nodes
  s_.lastStep[i].setZero();
  const double minStep = kMinStepFraction * s_.opt.moveTol * L;  // as for Face nodes
  for (int ls = over ? -1 : 0; ls < s_.opt.maxLineSearch; ++ls) {
    const double alpha = stepFactor(ls);
    if (ls > 0 && alpha * len3 < minStep) break;
    const double tn = t0 + alpha * dt;
    if (!(tn > lo + margin && tn < hi - margin)) continue;
    const Vec3 xn = curve.value(tn);
    edgeTrialNormals(i, curve, tn);
    const LocalEval tr = evalLocal(
        i, xn, [&](std::size_t j) { return trialN[j]; }, old, wantQ, &cur, nullptr, nullptr);
    if (!acceptable(cur, tr)) continue;
    keepTrial();
    double tb = tn;
    if (s_.mode.deltaHat > 0.0 && cur.tangled > 0 && tr.tangled >= cur.tangled &&
        (xn - x0).norm() < s_.opt.moveTol * L && (s_.opt.escapes & kEscapeSlide))
      slideEscape(i, curve, lo + margin, hi - margin, tr.tangled, &tb);
    if (tb == tn) s_.lastStep[i].x() = static_cast<float>(tn - t0);
    return commitEdgeMove(i, curve, tb, x0);
  }
  double tb = t0;
  if (s_.mode.deltaHat > 0.0 && cur.tangled > 0 && (s_.opt.escapes & kEscapeSlide) &&
      slideEscape(i, curve, lo + margin, hi - margin, cur.tangled, &tb))
    return commitEdgeMove(i, curve, tb, x0);
  return 0.0;
}

void NodeUpdater::edgeTrialNormals(std::size_t i, const Curve& curve, double t) {
  for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
    const std::size_t pp = static_cast<std::size_t>(p);
    const std::size_t e = static_cast<std::size_t>(s_.inc.elem[pp]);
    const std::size_t slot = static_cast<std::size_t>(s_.mesh.elemOffset[e]) + s_.inc.local[pp];
    const int f = s_.mesh.elemFace[e];
    const Vec2 uvf = curve.uvOnFace(f, t, s_.mesh.cornerUV[slot]);
    const Surface& sf = *w_.geo.surfaces[static_cast<std::size_t>(f)];
    w_.normals[static_cast<std::size_t>(p - s_.begin(i))] =
        (s_.mesh.faceOrientation[static_cast<std::size_t>(f)] * sf.normal(uvf.x(), uvf.y())).eval();
  }
}

double NodeUpdater::commitEdgeMove(std::size_t i, const Curve& curve, double t, const Vec3& x0) {
  edgeTrialNormals(i, curve, t);
  const Vec3 xn = curve.value(t);
  s_.t[i] = t;
  s_.xyz[i] = xn;
  Vec3* slotN = s_.edgeNormal.data() + s_.edgeSlot[i];
  for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
    const std::size_t j = static_cast<std::size_t>(p - s_.begin(i));
    const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
    const int local = s_.inc.local[static_cast<std::size_t>(p)];
    if (local < cornerCount(s_.mesh.elemType[e])) {
      s_.fixedNormal[e] += w_.normals[j] - slotN[j];
      slotN[j] = w_.normals[j];
      const std::int64_t slot = s_.cornerSlot(e);
      if (slot >= 0) s_.cornerN[static_cast<std::size_t>(slot + local)] = w_.normals[j];
    }
  }
  commitElements(i);
  return (xn - x0).norm();
}

bool NodeUpdater::slideEscape(std::size_t i, const Curve& curve, double a, double b, int threshold,
                              double* tOut) {
  if (!(b > a)) return false;
  const Vec3* oldN = s_.edgeNormal.data() + s_.edgeSlot[i];
  auto old = [&](std::size_t j) { return oldN[j]; };
  const Vec3* trialN = w_.normals.data();
  int bestTangled = threshold;
  double bestF = kInf;
  bool found = false;
  auto tryT = [&](double t) {
    edgeTrialNormals(i, curve, t);
    const LocalEval tr = evalLocal(
        i, curve.value(t), [&](std::size_t j) { return trialN[j]; }, old, false, nullptr, nullptr,
        nullptr);
    if (!tr.finite) return;
    if (tr.tangled < bestTangled || (found && tr.tangled == bestTangled && tr.f < bestF)) {
      bestTangled = tr.tangled;
      bestF = tr.f;
      *tOut = t;
      found = true;
    }
  };
  constexpr int kUniform = 32;
  for (int k = 1; k < kUniform; ++k) tryT(a + (b - a) * k / kUniform);
  for (double r = 1.0 / kUniform; r > 1e-4; r *= 0.3) {
    tryT(a + (b - a) * r);
    tryT(b - (b - a) * r);
  }
  return found;
}

bool NodeUpdater::neighbourCentroid(std::size_t i, int face, const Surface& surf, const Vec2& uv0,
                                    Vec2* c) {
  Vec2 sum = Vec2::Zero();
  int cnt = 0;
  for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
    const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
    const int nc = cornerCount(s_.mesh.elemType[e]);
    for (int k = 0; k < nc; ++k) {
      if (static_cast<std::size_t>(s_.mesh.elementNodes(e)[k]) == i) continue;
      sum += cornerOnFace(e, k, face, surf, uv0);
      ++cnt;
    }
  }
  if (cnt == 0 || !sum.allFinite()) return false;
  *c = sum / cnt;
  return true;
}

bool NodeUpdater::kernelCenter(std::size_t i, int face, const Surface& surf, const Vec2& uv0,
                               const NodeD2& d, double orient, Vec2* centre) {
  // Metric: q = R (uv − uv0) with RᵀR = JᵀJ (Cholesky, R upper triangular, det R > 0).
  const double g11 = d.du.squaredNorm(), g12 = d.du.dot(d.dv), g22 = d.dv.squaredNorm();
  const double r11 = std::sqrt(g11);
  if (!(r11 > 0.0)) return false;
  const double r12 = g12 / r11, r22sq = g22 - r12 * r12;
  if (!(r22sq > 0.0)) return false;
  const double r22 = std::sqrt(r22sq);
  auto toQ = [&](const Vec2& uv) {
    const Vec2 w = uv - uv0;
    return Vec2(r11 * w.x() + r12 * w.y(), r22 * w.y());
  };
  // Lines a·q ≥ b with ‖a‖ = 1 (inner side).
  constexpr int kMaxLines = 64;
  Vec2 A[kMaxLines];
  double B[kMaxLines];
  int n = 0;
  auto addLine = [&](const Vec2& x, const Vec2& y) {  // node on the left of x → y
    const Vec2 qx = toQ(x), qy = toQ(y);
    const Vec2 t = qy - qx;
    const double len = t.norm();
    if (!(len > 0.0) || n >= kMaxLines) return;
    // orient · (y − x) × (q − x) > 0  ⇔  a·q > b with a = orient · (−t_y, t_x)
    const Vec2 a = orient * Vec2(-t.y(), t.x()) / len;
    A[n] = a;
    B[n] = a.dot(qx);
    ++n;
  };
  for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
    const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
    const int local = s_.inc.local[static_cast<std::size_t>(p)];
    const int nc = cornerCount(s_.mesh.elemType[e]);
    if (local >= nc) return false;  // an edge or interior node of a high-order element
    const Vec2 nx = cornerOnFace(e, (local + 1) % nc, face, surf, uv0);
    const Vec2 pv = cornerOnFace(e, (local + nc - 1) % nc, face, surf, uv0);
    addLine(nx, pv);  // the corner triangle at i (i, next, prev)
    if (nc == 4) {
      // The corner triangles at next (next, next², i) and at prev (prev, i, prev²).
      const Vec2 nn = cornerOnFace(e, (local + 2) % nc, face, surf, uv0);
      addLine(nx, nn);
      addLine(nn, pv);
    }
  }
  if (n < 3) return false;
  double bestR = 0.0;
  bool found = false;
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b)
      for (int c = b + 1; c < n; ++c) {
        // a_k·q − r = b_k for k in {a, b, c}.
        Eigen::Matrix3d M;
        M << A[a].x(), A[a].y(), -1.0, A[b].x(), A[b].y(), -1.0, A[c].x(), A[c].y(), -1.0;
        const double det = M.determinant();
        if (!(std::abs(det) > 1e-14)) continue;
        const Eigen::Vector3d x = M.partialPivLu().solve(Eigen::Vector3d(B[a], B[b], B[c]));
        const double r = x.z();
        if (!(r > bestR)) continue;
        const Vec2 q(x.x(), x.y());
        bool ok = true;
        for (int k = 0; k < n && ok; ++k) ok = A[k].dot(q) - B[k] >= r - 1e-9 * std::abs(r);
        if (!ok) continue;
        bestR = r;
        // Back to (u,v): w = R⁻¹ q.
        const double wy = q.y() / r22;
        *centre = uv0 + Vec2((q.x() - r12 * wy) / r11, wy);
        found = true;
      }
  return found && centre->allFinite();
}

}  // namespace detail
}  // namespace surfmesh
