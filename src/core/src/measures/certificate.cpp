// A proof of the sign of a Lagrange triangle's Jacobian determinant D = (x_ξ × x_η)·n over the
// whole reference triangle (certificate.h; Johnen, Remacle, Geuzaine, JCP 2013).
//
// Bernstein basis of degree d on a triangle with barycentric coordinates (λ0, λ1, λ2):
//     B_{ijk} = d!/(i! j! k!) λ0^i λ1^j λ2^k,  i + j + k = d,
// with λ0 = 1 − ξ − η, λ1 = ξ, λ2 = η on the reference triangle. Coefficients are stored in the
// order k = 0…d, then j = 0…d − k (position k(d + 1) − k(k − 1)/2 + j). The coefficient c_{ijk}
// belongs to the domain point (i v0 + j v1 + k v2)/d of a piece with corners v0, v1, v2;
// c_{d00}, c_{0d0}, c_{00d} are D's values at the corners.
//
// First expansion: D at the domain points of the reference triangle (the equispaced points of
// order d), c = V⁻¹ D with V(a, b) = B_b(ξ_a), precomputed per order (45 × 45 for p = 5).
// Subdivision: the piece is split at its edge midpoints m01, m12, m20 into (v0, m01, m20),
// (m01, v1, m12), (m20, m12, v2) and (m12, m20, m01). A child with corners u0, u1, u2 (in the
// parent's barycentric coordinates) has the coefficients c'_{ijk} = blossom of the parent at
// (u0 × i, u1 × j, u2 × k), i.e. d de Casteljau steps; as every u has coordinates in {0, ½, 1},
// the four matrices mapping parent to child coefficients are computed once, exactly (dyadic
// entries, nonnegative, rows summing to 1), and applied as matrix–vector products.
#include "surfmesh/measures/certificate.h"

#include "surfmesh/measures/lagrange_triangle.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace surfmesh {

namespace {

/// Coefficients of the largest degree (d = 13: p = 5 against the nodes' normals): 105.
constexpr int kMaxCoefficients = 105;

int position(int d, int j, int k) { return k * (d + 1) - k * (k - 1) / 2 + j; }

using Bary = std::array<double, 3>;

/// Everything the certificate of order p needs, precomputed once.
struct CertificateBasis {
  int order = 0;
  int nodes = 0;                        ///< shape functions of the element
  bool field = false;                   ///< against the interpolated nodal normals
  int degree = 0;                       ///< d = 2(p − 1), or 3p − 2 for the normal field
  int count = 0;                        ///< (d + 1)(d + 2)/2 coefficients
  std::vector<Eigen::Vector3i> index;   ///< (i, j, k) of each coefficient
  std::vector<Eigen::Vector2d> points;  ///< the domain points (j/d, k/d) of the reference triangle
  /// grad[a * nodes + i] = ∇N_i(points[a]).
  std::vector<Eigen::Vector2d> grad;
  /// shape[a * nodes + i] = N_i(points[a]) (the normal field's interpolation; field only).
  std::vector<double> shape;
  /// Row-major count × count: coefficients = fromValues · (D at points).
  std::vector<double> fromValues;
  /// Row-major count × count per child: child coefficients = child[c] · parent coefficients.
  std::array<std::vector<double>, 4> child;
  int corner[3] = {0, 0, 0};  ///< positions of c_{d00}, c_{0d0}, c_{00d}
};

/// Row of the linear map parent coefficients → the blossom at `args` (d barycentric points).
std::vector<double> blossomRow(int d, int count, const std::vector<Bary>& args) {
  // level[L] coefficients, each a row over the parent's coefficients (symbolic de Casteljau).
  std::vector<std::vector<double>> level(static_cast<std::size_t>(count),
                                         std::vector<double>(static_cast<std::size_t>(count), 0));
  for (int a = 0; a < count; ++a)
    level[static_cast<std::size_t>(a)][static_cast<std::size_t>(a)] = 1;
  for (int L = d; L > 0; --L) {
    const Bary& u = args[static_cast<std::size_t>(d - L)];
    const int m = L * (L + 1) / 2;  // coefficients of degree L − 1
    std::vector<std::vector<double>> next(static_cast<std::size_t>(m),
                                          std::vector<double>(static_cast<std::size_t>(count), 0));
    for (int k = 0; k <= L - 1; ++k)
      for (int j = 0; j <= L - 1 - k; ++j) {
        auto& row = next[static_cast<std::size_t>(position(L - 1, j, k))];
        const auto& r0 = level[static_cast<std::size_t>(position(L, j, k))];  // i + 1
        const auto& r1 = level[static_cast<std::size_t>(position(L, j + 1, k))];
        const auto& r2 = level[static_cast<std::size_t>(position(L, j, k + 1))];
        for (int c = 0; c < count; ++c) {
          const std::size_t s = static_cast<std::size_t>(c);
          row[s] = u[0] * r0[s] + u[1] * r1[s] + u[2] * r2[s];
        }
      }
    level.swap(next);
  }
  return level[0];
}

double binomial(int n, int k) {
  double r = 1.0;
  for (int s = 1; s <= k; ++s) r = r * (n - k + s) / s;
  return r;
}

CertificateBasis makeBasis(int order, bool field) {
  CertificateBasis b;
  const LagrangeTriangle& lt = lagrangeTriangle(order);
  b.order = order;
  b.nodes = lt.nodeCount();
  b.field = field;
  const int d = field ? 3 * order - 2 : 2 * (order - 1);
  b.degree = d;
  b.count = (d + 1) * (d + 2) / 2;
  const std::size_t m = static_cast<std::size_t>(b.count);
  for (int k = 0; k <= d; ++k)
    for (int j = 0; j <= d - k; ++j) {
      b.index.emplace_back(d - j - k, j, k);
      // d = 0 (p = 1): one point, D constant; take the first corner.
      b.points.emplace_back(d > 0 ? static_cast<double>(j) / d : 0.0,
                            d > 0 ? static_cast<double>(k) / d : 0.0);
    }
  b.corner[0] = position(d, 0, 0);
  b.corner[1] = position(d, d, 0);
  b.corner[2] = position(d, 0, d);
  const std::size_t nn = static_cast<std::size_t>(b.nodes);
  b.grad.resize(m * nn);
  for (std::size_t a = 0; a < m; ++a) lt.gradients(b.points[a], b.grad.data() + a * nn);
  if (field) {
    b.shape.resize(m * nn);
    for (std::size_t a = 0; a < m; ++a) lt.shape(b.points[a], b.shape.data() + a * nn);
  }
  // V(a, b) = B_b(points[a]).
  Eigen::MatrixXd V(b.count, b.count);
  for (int a = 0; a < b.count; ++a) {
    const double l[3] = {
        1.0 - b.points[static_cast<std::size_t>(a)].x() - b.points[static_cast<std::size_t>(a)].y(),
        b.points[static_cast<std::size_t>(a)].x(), b.points[static_cast<std::size_t>(a)].y()};
    for (int c = 0; c < b.count; ++c) {
      const Eigen::Vector3i& e = b.index[static_cast<std::size_t>(c)];
      V(a, c) = binomial(d, e(0)) * binomial(d - e(0), e(1)) * std::pow(l[0], e(0)) *
                std::pow(l[1], e(1)) * std::pow(l[2], e(2));
    }
  }
  const Eigen::MatrixXd inv = V.fullPivLu().inverse();
  b.fromValues.resize(m * m);
  for (int r = 0; r < b.count; ++r)
    for (int c = 0; c < b.count; ++c)
      b.fromValues[static_cast<std::size_t>(r) * m + static_cast<std::size_t>(c)] = inv(r, c);
  // Children corners in the parent's barycentric coordinates.
  const Bary e0 = {1, 0, 0}, e1 = {0, 1, 0}, e2 = {0, 0, 1};
  const Bary m01 = {0.5, 0.5, 0}, m12 = {0, 0.5, 0.5}, m20 = {0.5, 0, 0.5};
  const std::array<std::array<Bary, 3>, 4> kids = {{{e0, m01, m20},  //
                                                    {m01, e1, m12},
                                                    {m20, m12, e2},
                                                    {m12, m20, m01}}};
  for (int c = 0; c < 4; ++c) {
    auto& M = b.child[static_cast<std::size_t>(c)];
    M.resize(m * m);
    for (int r = 0; r < b.count; ++r) {
      const Eigen::Vector3i& e = b.index[static_cast<std::size_t>(r)];
      std::vector<Bary> args;
      for (int v = 0; v < 3; ++v)
        for (int t = 0; t < e(v); ++t)
          args.push_back(kids[static_cast<std::size_t>(c)][static_cast<std::size_t>(v)]);
      const std::vector<double> row = blossomRow(d, b.count, args);
      std::copy(row.begin(), row.end(), M.begin() + static_cast<std::ptrdiff_t>(r * b.count));
    }
  }
  return b;
}

const CertificateBasis& basis(int order) {
  static const CertificateBasis b[5] = {makeBasis(1, false), makeBasis(2, false),
                                        makeBasis(3, false), makeBasis(4, false),
                                        makeBasis(5, false)};
  if (order < 1 || order > 5)
    throw std::invalid_argument("certifyTriangleJacobian: order must be 1..5, got " +
                                std::to_string(order));
  return b[order - 1];
}

/// The bases against the nodes' normals (degree 3p − 2), built on first use.
const CertificateBasis& fieldBasis(int order) {
  if (order < 1 || order > 5)
    throw std::invalid_argument("certifyTriangleAgainstNodeNormals: order must be 1..5, got " +
                                std::to_string(order));
  static const CertificateBasis b[5] = {makeBasis(1, true), makeBasis(2, true), makeBasis(3, true),
                                        makeBasis(4, true), makeBasis(5, true)};
  return b[order - 1];
}

/// The quick proof of a Positive verdict: D's Bernstein coefficients on the whole triangle,
/// computed exactly from the element's Bézier control points instead of from samples. With
/// λ = (1 − ξ − η, ξ, η) and the control points P_α (|α| = p) of x (P = toControl · nodes),
///     x_ξ = Σ_{|α|=p−1} p (P_{α+e1} − P_{α+e0}) B_α,   x_η = Σ p (P_{α+e2} − P_{α+e0}) B_α,
/// and a product of Bernstein polynomials is one too: Σ_α f_α B_α^m · Σ_β g_β B_β^n =
/// Σ_γ (Σ_{α+β=γ} C(m,α) C(n,β) / C(m+n,γ) f_α g_β) B_γ^{m+n}, C the multinomial coefficients.
/// Every coefficient of the degree-2(p − 1) (or, against the interpolated normals N_δ, degree
/// 3p − 2) product above τ' proves D > τ' everywhere. τ' bounds the certificate's τ from above
/// (‖x_ξ‖ ≤ max ‖a_α‖ on the whole triangle, and so on), so this proof implies the
/// certificate's at depth 0; where it does not conclude, the certificate decides.
struct ProductBasis {
  int order = 0;
  int nodes = 0;
  /// Row-major nodes × nodes: control point of index position(p, j, k) from the nodes.
  std::vector<double> toControl;
  /// For each α of degree p − 1 (position(p − 1, ·)): positions of α + e0, α + e1, α + e2.
  std::vector<std::array<int, 3>> deriv;
  struct Term {
    int f, g, out;
    double w;
  };
  std::vector<Term> cross;  ///< (p − 1) × (p − 1) → 2(p − 1)
  std::vector<Term> field;  ///< 2(p − 1) × p → 3p − 2
  int crossCount = 0, fieldCount = 0;
};

double multinomial(int d, int i, int j) { return binomial(d, i) * binomial(d - i, j); }

/// The products' terms of two degrees (m, n): each pair of indices and its weight.
std::vector<ProductBasis::Term> productTerms(int m, int n) {
  std::vector<ProductBasis::Term> t;
  for (int k1 = 0; k1 <= m; ++k1)
    for (int j1 = 0; j1 <= m - k1; ++j1)
      for (int k2 = 0; k2 <= n; ++k2)
        for (int j2 = 0; j2 <= n - k2; ++j2) {
          const int i1 = m - j1 - k1, i2 = n - j2 - k2;
          const double w = multinomial(m, i1, j1) * multinomial(n, i2, j2) /
                           multinomial(m + n, i1 + i2, j1 + j2);
          t.push_back(
              {position(m, j1, k1), position(n, j2, k2), position(m + n, j1 + j2, k1 + k2), w});
        }
  return t;
}

ProductBasis makeProductBasis(int order) {
  ProductBasis b;
  const LagrangeTriangle& lt = lagrangeTriangle(order);
  const int p = order, nn = lt.nodeCount();
  b.order = p;
  b.nodes = nn;
  // M(node, α) = B_α^p at the node; control points = M⁻¹ · nodes.
  Eigen::MatrixXd M(nn, nn);
  for (int r = 0; r < nn; ++r) {
    const Eigen::Vector2d& xi = lt.nodes()[static_cast<std::size_t>(r)];
    const double l[3] = {1.0 - xi.x() - xi.y(), xi.x(), xi.y()};
    for (int k = 0; k <= p; ++k)
      for (int j = 0; j <= p - k; ++j) {
        const int i = p - j - k;
        M(r, position(p, j, k)) =
            multinomial(p, i, j) * std::pow(l[0], i) * std::pow(l[1], j) * std::pow(l[2], k);
      }
  }
  const Eigen::MatrixXd inv = M.fullPivLu().inverse();
  b.toControl.resize(static_cast<std::size_t>(nn * nn));
  for (int r = 0; r < nn; ++r)
    for (int c = 0; c < nn; ++c) b.toControl[static_cast<std::size_t>(r * nn + c)] = inv(r, c);
  for (int k = 0; k <= p - 1; ++k)
    for (int j = 0; j <= p - 1 - k; ++j)
      b.deriv.push_back({position(p, j, k), position(p, j + 1, k), position(p, j, k + 1)});
  b.cross = productTerms(p - 1, p - 1);
  b.field = productTerms(2 * (p - 1), p);
  b.crossCount = (2 * p - 1) * 2 * p / 2;
  b.fieldCount = (3 * p - 1) * 3 * p / 2;
  return b;
}

const ProductBasis& productBasis(int order) {
  static const ProductBasis b[5] = {makeProductBasis(1), makeProductBasis(2), makeProductBasis(3),
                                    makeProductBasis(4), makeProductBasis(5)};
  return b[order - 1];
}

/// Control points (order p, position order) of the nodal values v (Gmsh order).
void controlPoints(const ProductBasis& B, const Vec3* v, Vec3* out) {
  for (int r = 0; r < B.nodes; ++r) {
    const double* row = B.toControl.data() + static_cast<std::size_t>(r * B.nodes);
    double s0 = 0, s1 = 0, s2 = 0;
    for (int c = 0; c < B.nodes; ++c) {
      s0 += row[c] * v[c].x();
      s1 += row[c] * v[c].y();
      s2 += row[c] * v[c].z();
    }
    out[r] = Vec3(s0, s1, s2);
  }
}

/// The Bézier coefficients of x_ξ and x_η (degree p − 1) of nodes x, and the largest norms.
void derivativeControls(const ProductBasis& B, const Vec3* x, Vec3* a, Vec3* b, double* scale) {
  Vec3 P[kMaxElementNodes];
  controlPoints(B, x, P);
  double ma = 0.0, mb = 0.0;
  const double p = B.order;
  for (std::size_t q = 0; q < B.deriv.size(); ++q) {
    const std::array<int, 3>& d = B.deriv[q];
    a[q] = p * (P[d[1]] - P[d[0]]);
    b[q] = p * (P[d[2]] - P[d[0]]);
    ma = std::max(ma, a[q].norm());
    mb = std::max(mb, b[q].norm());
  }
  *scale = ma * mb;
}

CoefficientBound productBound(int order, const Vec3* x, const Vec3& n) {
  const ProductBasis& B = productBasis(order);
  Vec3 a[kMaxElementNodes], b[kMaxElementNodes];
  double scale = 0.0;
  derivativeControls(B, x, a, b, &scale);
  // (a_α × b_β)·n = a_α · (b_β × n)
  Vec3 bn[kMaxElementNodes];
  for (std::size_t q = 0; q < B.deriv.size(); ++q) bn[q] = b[q].cross(n);
  double c[kMaxCoefficients] = {};
  for (const ProductBasis::Term& t : B.cross) c[t.out] += t.w * a[t.f].dot(bn[t.g]);
  CoefficientBound r;
  r.tolerance = kPerpendicularTol * n.norm() * scale;
  r.minCoefficient = *std::min_element(c, c + B.crossCount);
  return r;
}

/// productBound against node normals already with the poles' replaced (fillPoleNormals).
CoefficientBound productBoundAgainstNodeNormals(int order, const Vec3* x, const Vec3* nodeNormals) {
  const ProductBasis& B = productBasis(order);
  Vec3 a[kMaxElementNodes], b[kMaxElementNodes];
  double scale = 0.0;
  derivativeControls(B, x, a, b, &scale);
  Vec3 N[kMaxElementNodes];
  controlPoints(B, nodeNormals, N);
  double mn = 0.0;
  for (int i = 0; i < B.nodes; ++i) mn = std::max(mn, N[i].norm());
  Vec3 c[kMaxCoefficients];
  for (int i = 0; i < B.crossCount; ++i) c[i] = Vec3::Zero();
  for (const ProductBasis::Term& t : B.cross) c[t.out] += t.w * a[t.f].cross(b[t.g]);
  double d[kMaxCoefficients] = {};
  for (const ProductBasis::Term& t : B.field) d[t.out] += t.w * c[t.f].dot(N[t.g]);
  CoefficientBound r;
  r.tolerance = kPerpendicularTol * scale * mn;
  r.minCoefficient = *std::min_element(d, d + B.fieldCount);
  return r;
}

/// Whether the bound proves D > τ' (false on anything not finite).
bool proves(const CoefficientBound& r) {
  return std::isfinite(r.tolerance) && r.minCoefficient > r.tolerance;
}

/// The node normals the certificate against them takes: a node at a pole (zero normal) takes
/// the direction of the others' sum. *sumNorm: the length of that sum; false when a normal is
/// not finite.
bool fillPoleNormals(const Vec3* in, int nn, Vec3* out, double* sumNorm) {
  bool finite = true;
  Vec3 sum = Vec3::Zero();
  for (int i = 0; i < nn; ++i) {
    finite = finite && in[i].allFinite();
    sum += in[i];
  }
  const double normals = sum.norm();
  for (int i = 0; i < nn; ++i)
    out[i] = in[i].squaredNorm() > 0.0 || normals == 0.0 ? in[i] : Vec3(sum / normals);
  *sumNorm = normals;
  return finite;
}

/// Σ_i N_i n_i from the shape function values at one point.
inline Vec3 interpolate(const Vec3* n, const double* N, int nn) {
  Vec3 r = Vec3::Zero();
  for (int i = 0; i < nn; ++i) r += N[i] * n[i];
  return r;
}

/// x_ξ, x_η from the nodes and the gradients of their shape functions at one point.
inline void tangents(const Vec3* x, const Eigen::Vector2d* g, int nn, Vec3* a, Vec3* b) {
  double a0 = 0, a1 = 0, a2 = 0, b0 = 0, b1 = 0, b2 = 0;
  for (int i = 0; i < nn; ++i) {
    a0 += g[i].x() * x[i].x();
    a1 += g[i].x() * x[i].y();
    a2 += g[i].x() * x[i].z();
    b0 += g[i].y() * x[i].x();
    b1 += g[i].y() * x[i].y();
    b2 += g[i].y() * x[i].z();
  }
  *a = Vec3(a0, a1, a2);
  *b = Vec3(b0, b1, b2);
}

/// One piece of the reference triangle: its corners (ξ, η) and D's coefficients on it.
struct Piece {
  Eigen::Vector2d v[3];
  double c[kMaxCoefficients];
};

}  // namespace

const char* jacobianSignName(JacobianSign s) {
  switch (s) {
    case JacobianSign::Positive:
      return "positive";
    case JacobianSign::NonPositive:
      return "non_positive";
    default:
      return "undecided";
  }
}

double triangleJacobianDeterminant(int order, const Vec3* x, const Vec3& n,
                                   const Eigen::Vector2d& xi) {
  const LagrangeTriangle& lt = lagrangeTriangle(order);
  Eigen::Vector2d g[kMaxElementNodes];
  lt.gradients(xi, g);
  Vec3 a, b;
  tangents(x, g, lt.nodeCount(), &a, &b);
  return a.cross(b).dot(n);
}

namespace {

/// The certificate proper: D's values at B's sample points, its margin τ, `direct(ξ)` D at any
/// reference point (evaluated from the nodes), `zero`: D ≡ 0 (no direction to judge against).
template <class Direct>
JacobianCertificate certify(const CertificateBasis& B, const double* values, double tol, bool zero,
                            const Direct& direct, int maxDepth) {
  const int m = B.count, d = B.degree;
  const std::size_t mm = static_cast<std::size_t>(m);
  JacobianCertificate r;
  r.tolerance = tol;
  int lowest = 0;
  for (int a = 1; a < m; ++a)
    if (values[a] < values[lowest]) lowest = a;
  r.minSampled = values[lowest];

  Piece root;
  root.v[0] = Eigen::Vector2d(0, 0);
  root.v[1] = Eigen::Vector2d(1, 0);
  root.v[2] = Eigen::Vector2d(0, 1);
  for (int i = 0; i < m; ++i) {
    double s = 0.0;
    const double* row = B.fromValues.data() + static_cast<std::size_t>(i) * mm;
    for (int j = 0; j < m; ++j) s += row[j] * values[j];
    root.c[i] = s;
  }
  if (d == 0) root.c[0] = values[0];  // exact: D is constant
  r.minCoefficient = *std::min_element(root.c, root.c + m);
  r.ratio = r.minCoefficient / r.minSampled;

  auto nonPositive = [&](const Eigen::Vector2d& p, double value, int depth) {
    r.sign = JacobianSign::NonPositive;
    r.point = p;
    r.value = value;
    r.depth = depth;
    return r;
  };
  if (zero) return nonPositive(Eigen::Vector2d(1.0 / 3.0, 1.0 / 3.0), 0.0, 0);
  if (values[lowest] <= tol)
    return nonPositive(B.points[static_cast<std::size_t>(lowest)], values[lowest], 0);

  // A point of a piece where D ≤ τ, evaluated from the nodes (the coefficients only point to
  // it: a corner coefficient equals D there up to rounding).
  double lowerBound = std::numeric_limits<double>::infinity();
  bool undecided = false;
  std::vector<Piece> level{root}, next;
  for (int depth = 0; !level.empty(); ++depth) {
    r.depth = depth;
    next.clear();
    for (const Piece& P : level) {
      ++r.pieces;
      const int lo = static_cast<int>(std::min_element(P.c, P.c + m) - P.c);
      if (P.c[lo] > tol) {
        lowerBound = std::min(lowerBound, P.c[lo]);
        continue;
      }
      for (int k = 0; k < 3; ++k)
        if (P.c[B.corner[k]] <= tol) {
          const double v = direct(P.v[k]);
          if (v <= tol) return nonPositive(P.v[k], v, depth);
        }
      if (d > 0) {
        const Eigen::Vector3i& e = B.index[static_cast<std::size_t>(lo)];
        const Eigen::Vector2d p = (e(0) * P.v[0] + e(1) * P.v[1] + e(2) * P.v[2]) / d;
        const double v = direct(p);
        if (v <= tol) return nonPositive(p, v, depth);
      }
      if (depth >= maxDepth || r.pieces + static_cast<int>(next.size()) >= kCertificateMaxPieces) {
        undecided = true;
        continue;
      }
      const Eigen::Vector2d m01 = 0.5 * (P.v[0] + P.v[1]), m12 = 0.5 * (P.v[1] + P.v[2]),
                            m20 = 0.5 * (P.v[2] + P.v[0]);
      const Eigen::Vector2d corners[4][3] = {
          {P.v[0], m01, m20}, {m01, P.v[1], m12}, {m20, m12, P.v[2]}, {m12, m20, m01}};
      for (int c = 0; c < 4; ++c) {
        next.emplace_back();
        Piece& C = next.back();
        for (int k = 0; k < 3; ++k) C.v[k] = corners[c][k];
        const double* M = B.child[static_cast<std::size_t>(c)].data();
        for (int i = 0; i < m; ++i) {
          double s = 0.0;
          const double* row = M + static_cast<std::size_t>(i) * mm;
          for (int j = 0; j < m; ++j) s += row[j] * P.c[j];
          C.c[i] = s;
        }
      }
    }
    level.swap(next);
  }
  if (undecided) return r;
  r.sign = JacobianSign::Positive;
  r.lowerBound = lowerBound;
  return r;
}

}  // namespace

JacobianCertificate certifyTriangleJacobian(int order, const Vec3* x, const Vec3& n, int maxDepth) {
  const CertificateBasis& B = basis(order);
  const int nn = B.nodes, m = B.count;
  if (!n.allFinite()) return JacobianCertificate{};  // Undecided
  const double nNorm = n.norm();
  // D at the sample points, and the scale of τ.
  double values[kMaxCoefficients] = {};
  double scale = 0.0;
  bool finite = true;
  for (int a = 0; a < m; ++a) {
    Vec3 xa, xb;
    tangents(x, B.grad.data() + static_cast<std::size_t>(a) * static_cast<std::size_t>(nn), nn, &xa,
             &xb);
    values[a] = xa.cross(xb).dot(n);
    scale = std::max(scale, xa.norm() * xb.norm());
    finite = finite && std::isfinite(values[a]) && std::isfinite(scale);
  }
  if (!finite) return JacobianCertificate{};  // Undecided
  auto direct = [&](const Eigen::Vector2d& p) {
    return triangleJacobianDeterminant(order, x, n, p);
  };
  return certify(B, values, kPerpendicularTol * nNorm * scale, nNorm == 0.0, direct, maxDepth);
}

double triangleJacobianAgainstNodeNormals(int order, const Vec3* x, const Vec3* nodeNormals,
                                          const Eigen::Vector2d& xi) {
  const LagrangeTriangle& lt = lagrangeTriangle(order);
  Eigen::Vector2d g[kMaxElementNodes];
  double N[kMaxElementNodes];
  lt.gradients(xi, g);
  lt.shape(xi, N);
  Vec3 a, b;
  tangents(x, g, lt.nodeCount(), &a, &b);
  return a.cross(b).dot(interpolate(nodeNormals, N, lt.nodeCount()));
}

JacobianCertificate certifyTriangleAgainstNodeNormals(int order, const Vec3* x,
                                                      const Vec3* nodeNormalsIn, int maxDepth) {
  const CertificateBasis& B = fieldBasis(order);
  const int nn = B.nodes, m = B.count;
  double values[kMaxCoefficients] = {};
  double scale = 0.0;
  Vec3 nodeNormals[kMaxElementNodes];
  double normals = 0.0;
  bool finite = fillPoleNormals(nodeNormalsIn, nn, nodeNormals, &normals);
  for (int a = 0; a < m && finite; ++a) {
    const std::size_t o = static_cast<std::size_t>(a) * static_cast<std::size_t>(nn);
    Vec3 xa, xb;
    tangents(x, B.grad.data() + o, nn, &xa, &xb);
    const Vec3 na = interpolate(nodeNormals, B.shape.data() + o, nn);
    values[a] = xa.cross(xb).dot(na);
    scale = std::max(scale, xa.norm() * xb.norm() * na.norm());
    finite = std::isfinite(values[a]) && std::isfinite(scale);
  }
  if (!finite) return JacobianCertificate{};  // Undecided
  auto direct = [&](const Eigen::Vector2d& p) {
    return triangleJacobianAgainstNodeNormals(order, x, nodeNormals, p);
  };
  return certify(B, values, kPerpendicularTol * scale, normals == 0.0, direct, maxDepth);
}

JacobianCertificate certifyElementJacobian(ElementType type, const Vec3* x, const Vec3& n) {
  if (isQuad(type))
    throw std::invalid_argument(std::string("certifyElementJacobian: ") + elementTypeName(type) +
                                " is not a triangle (see elementCertifiedValid)");
  return certifyTriangleJacobian(elementOrder(type), x, n);
}

bool markUncertifiedFold(ElementType type, const Vec3* x, const Vec3& n, double delta,
                         ElementEval* r, Vec3* grad, Mat3* hess, double* eta0,
                         const PlanarMeasure* m, int freeLocal) {
  if (r->tangled || !isHighOrderTriangle(type)) return false;
  const int p = elementOrder(type);
  if (proves(productBound(p, x, n))) return false;
  const JacobianCertificate c = certifyTriangleJacobian(p, x, n);
  if (c.sign == JacobianSign::Positive) return false;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  r->tangled = true;
  r->minSigma = std::min(r->minSigma, 0.0);
  if (eta0) *eta0 = kInf;
  if (delta == 0.0) {
    r->eta = kInf;
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return true;
  }
  if (!m || !c.point.allFinite() || !std::isfinite(r->eta) || !(r->eta > 0.0)) return true;
  // The fold's point ξ* as one more sample of the mean, with its derivatives.
  const LagrangeTriangle& lt = lagrangeTriangle(p);
  const int nn = lt.nodeCount();
  Eigen::Vector2d g[kMaxElementNodes];
  lt.gradients(c.point, g);
  Jacobian32 J = Jacobian32::Zero();
  for (int i = 0; i < nn; ++i) {
    J.col(0) += g[i].x() * x[i];
    J.col(1) += g[i].y() * x[i];
  }
  const bool derivs = freeLocal >= 0 && freeLocal < nn && grad != nullptr;
  Vec3 gs = Vec3::Zero();
  Mat3 Hs = Mat3::Zero();
  const ElementEval e =
      jacobianDistortion(*m, J, equilateralWinv(), n, delta, derivs ? &g[freeLocal] : nullptr,
                         derivs ? &gs : nullptr, derivs && hess ? &Hs : nullptr);
  if (!std::isfinite(e.eta)) return true;
  const double w = 1.0 / nn;
  const double eta = r->eta;
  const double etaNew = std::sqrt(eta * eta + w * e.eta * e.eta);
  if (derivs) {
    const Vec3 g0 = *grad;
    const Vec3 gNew = (eta * g0 + w * e.eta * gs) / etaNew;
    if (hess) {
      // ½∇²(η̂²) = η̂ ∇²η̂ + ∇η̂ ∇η̂ᵀ, summed with the point's, then ∇²η̂_new from it.
      const Mat3 half =
          eta * (*hess) + g0 * g0.transpose() + w * (e.eta * Hs + gs * gs.transpose());
      *hess = (half - gNew * gNew.transpose()) / etaNew;
    }
    *grad = gNew;
  } else {
    if (grad) grad->setZero();
    if (hess) hess->setZero();
  }
  r->eta = etaNew;
  return true;
}

CoefficientBound bezierCoefficientBound(int order, const Vec3* x, const Vec3& n) {
  basis(order);  // (the order's check)
  return productBound(order, x, n);
}

CoefficientBound bezierCoefficientBoundAgainstNodeNormals(int order, const Vec3* x,
                                                          const Vec3* nodeNormals) {
  const CertificateBasis& B = fieldBasis(order);  // (the order's check)
  Vec3 filled[kMaxElementNodes];
  double normals = 0.0;
  if (!fillPoleNormals(nodeNormals, B.nodes, filled, &normals)) return CoefficientBound{};
  return productBoundAgainstNodeNormals(order, x, filled);
}

bool triangleJacobianPositive(int order, const Vec3* x, const Vec3& n) {
  return proves(bezierCoefficientBound(order, x, n)) ||
         certifyTriangleJacobian(order, x, n).sign == JacobianSign::Positive;
}

bool triangleJacobianPositiveAgainstNodeNormals(int order, const Vec3* x, const Vec3* nodeNormals) {
  return proves(bezierCoefficientBoundAgainstNodeNormals(order, x, nodeNormals)) ||
         certifyTriangleAgainstNodeNormals(order, x, nodeNormals).sign == JacobianSign::Positive;
}

bool elementCertifiedValid(ElementType type, const Vec3* x, const Vec3& n) {
  if (!isQuad(type)) return triangleJacobianPositive(elementOrder(type), x, n);
  // Quad4 and quad8: their own proofs, inside their distortion (any measure: validity only).
  return !elementDistortion(measureByName("shape"), type, x, n, 0.0).tangled;
}

}  // namespace surfmesh
