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
// First expansion: exactly from the element's Bézier control points, as products of Bernstein
// polynomials (ProductBasis below), no sampling.
// Subdivision: a piece is bisected at the midpoint P of its longest edge (v_a, v_b) (in the
// reference triangle's (ξ, η): the halves of a right isosceles triangle are right isosceles
// triangles again, so two bisections halve a piece's size). One de Casteljau pyramid at
// λ(P) = ½ e_a + ½ e_b, b^r_α = ½ b^{r−1}_{α+e_a} + ½ b^{r−1}_{α+e_b} (|α| = d − r), gives both
// halves (the blossom): the half whose corner a is replaced by P has c'_α = b^{α_a}_{α − α_a e_a},
// likewise for b. That is O(d³) work for both halves, instead of the O(d⁴) of the four dense
// matrices of a split in four. The pieces are examined depth first, the half with the smaller
// coefficient first (a fold is found without visiting the rest).
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

/// The largest degree (p = 5 against the nodes' normals: 3p − 2 = 13) and its coefficients.
constexpr int kMaxDegree = 13;
constexpr int kMaxCoefficients = (kMaxDegree + 1) * (kMaxDegree + 2) / 2;
/// The coefficients of a de Casteljau pyramid of degree kMaxDegree (every level).
constexpr int kMaxPyramid = (kMaxDegree + 1) * (kMaxDegree + 2) * (kMaxDegree + 3) / 6;

int position(int d, int j, int k) { return k * (d + 1) - k * (k - 1) / 2 + j; }

/// The sample points of the certificate's diagnostics (minSampled), precomputed once.
struct CertificateBasis {
  int order = 0;
  int nodes = 0;                        ///< shape functions of the element
  bool field = false;                   ///< against the interpolated nodal normals
  int degree = 0;                       ///< d = 2(p − 1), or 3p − 2 for the normal field
  int count = 0;                        ///< (d + 1)(d + 2)/2 coefficients
  std::vector<Eigen::Vector2d> points;  ///< the domain points (j/d, k/d) of the reference triangle
  /// grad[a * nodes + i] = ∇N_i(points[a]).
  std::vector<Eigen::Vector2d> grad;
  /// shape[a * nodes + i] = N_i(points[a]) (the normal field's interpolation; field only).
  std::vector<double> shape;
};

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
    for (int j = 0; j <= d - k; ++j)
      // d = 0 (p = 1): one point, D constant; take the first corner.
      b.points.emplace_back(d > 0 ? static_cast<double>(j) / d : 0.0,
                            d > 0 ? static_cast<double>(k) / d : 0.0);
  const std::size_t nn = static_cast<std::size_t>(b.nodes);
  b.grad.resize(m * nn);
  for (std::size_t a = 0; a < m; ++a) lt.gradients(b.points[a], b.grad.data() + a * nn);
  if (field) {
    b.shape.resize(m * nn);
    for (std::size_t a = 0; a < m; ++a) lt.shape(b.points[a], b.shape.data() + a * nn);
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

/// D's Bernstein coefficients on the whole triangle, computed exactly from the element's Bézier
/// control points. With
/// λ = (1 − ξ − η, ξ, η) and the control points P_α (|α| = p) of x (P = toControl · nodes),
///     x_ξ = Σ_{|α|=p−1} p (P_{α+e1} − P_{α+e0}) B_α,   x_η = Σ p (P_{α+e2} − P_{α+e0}) B_α,
/// and a product of Bernstein polynomials is one too: Σ_α f_α B_α^m · Σ_β g_β B_β^n =
/// Σ_γ (Σ_{α+β=γ} C(m,α) C(n,β) / C(m+n,γ) f_α g_β) B_γ^{m+n}, C the multinomial coefficients.
/// Every coefficient of the degree-2(p − 1) (or, against the interpolated normals N_δ, degree
/// 3p − 2) product above τ proves D > τ everywhere; τ = kPerpendicularTol ‖n‖ max_α ‖a_α‖
/// max_β ‖b_β‖ (against the nodes' normals, times max ‖N_δ‖) bounds ‖x_ξ‖ ‖x_η‖ ‖n‖ on the
/// whole triangle from above.
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

/// D's coefficients c (degree 2(p − 1)) against the direction n, with their smallest and τ.
CoefficientBound referenceCoefficients(int order, const Vec3* x, const Vec3& n, double* c) {
  const ProductBasis& B = productBasis(order);
  Vec3 a[kMaxElementNodes], b[kMaxElementNodes];
  double scale = 0.0;
  derivativeControls(B, x, a, b, &scale);
  // (a_α × b_β)·n = a_α · (b_β × n)
  Vec3 bn[kMaxElementNodes];
  for (std::size_t q = 0; q < B.deriv.size(); ++q) bn[q] = b[q].cross(n);
  std::fill(c, c + B.crossCount, 0.0);
  for (const ProductBasis::Term& t : B.cross) c[t.out] += t.w * a[t.f].dot(bn[t.g]);
  CoefficientBound r;
  r.tolerance = kPerpendicularTol * n.norm() * scale;
  r.minCoefficient = *std::min_element(c, c + B.crossCount);
  return r;
}

/// D_h's coefficients d (degree 3p − 2) against node normals already with the poles' replaced
/// (fillPoleNormals), with their smallest and τ.
CoefficientBound fieldCoefficients(int order, const Vec3* x, const Vec3* nodeNormals, double* d) {
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
  std::fill(d, d + B.fieldCount, 0.0);
  for (const ProductBasis::Term& t : B.field) d[t.out] += t.w * c[t.f].dot(N[t.g]);
  CoefficientBound r;
  r.tolerance = kPerpendicularTol * scale * mn;
  r.minCoefficient = *std::min_element(d, d + B.fieldCount);
  return r;
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

/// One piece of the reference triangle: its corners (ξ, η), D's coefficients on it, and its
/// number of bisections from the whole triangle.
struct Piece {
  Eigen::Vector2d v[3];
  double c[kMaxCoefficients];
  int level;
};

/// The pieces still to examine (a depth-first stack: at most one per level and the current
/// one), kept by each thread from one certificate to the next.
std::vector<Piece>& pieceStack(std::size_t size) {
  thread_local std::vector<Piece> stack;
  if (stack.size() < size) stack.resize(size);
  return stack;
}

/// The two halves of piece P (degree d) bisected at the midpoint of its longest edge.
void bisect(const Piece& P, int d, Piece* h0, Piece* h1) {
  // The edge (a, b) opposite corner o, the longest (the first of equal ones).
  int o = 0;
  double longest = -1.0;
  for (int k = 0; k < 3; ++k) {
    const double l = (P.v[(k + 1) % 3] - P.v[(k + 2) % 3]).squaredNorm();
    if (l > longest) {
      longest = l;
      o = k;
    }
  }
  const int a = (o + 1) % 3, b = (o + 2) % 3;
  // The de Casteljau pyramid at λ = ½ e_a + ½ e_b: level r (degree d − r) from offset off[r].
  double pyr[kMaxPyramid];
  int off[kMaxDegree + 1];
  off[0] = 0;
  const int m = (d + 1) * (d + 2) / 2;
  std::copy(P.c, P.c + m, pyr);
  for (int r = 1; r <= d; ++r) {
    const int up = d - r + 1;  // degree of level r − 1
    off[r] = off[r - 1] + (up + 1) * (up + 2) / 2;
    const double* prev = pyr + off[r - 1];
    double* cur = pyr + off[r];
    for (int k = 0; k <= d - r; ++k)
      for (int j = 0; j <= d - r - k; ++j) {
        // α + e0, α + e1, α + e2 in degree up.
        const double e[3] = {prev[position(up, j, k)], prev[position(up, j + 1, k)],
                             prev[position(up, j, k + 1)]};
        cur[position(d - r, j, k)] = 0.5 * (e[a] + e[b]);
      }
  }
  const Eigen::Vector2d mid = 0.5 * (P.v[a] + P.v[b]);
  Piece* halves[2] = {h0, h1};
  const int replaced[2] = {a, b};
  for (int h = 0; h < 2; ++h) {
    Piece& H = *halves[h];
    const int q = replaced[h];
    for (int k = 0; k < 3; ++k) H.v[k] = P.v[k];
    H.v[q] = mid;
    H.level = P.level + 1;
    for (int k = 0; k <= d; ++k)
      for (int j = 0; j <= d - k; ++j) {
        int alpha[3] = {d - j - k, j, k};
        const int r = alpha[q];
        alpha[q] = 0;
        H.c[position(d, j, k)] = pyr[off[r] + position(d - r, alpha[1], alpha[2])];
      }
  }
}

/// The certificate proper on D's coefficients c (degree d) on the reference triangle, margin
/// τ = tol; `direct(ξ)` is D at any reference point, evaluated from the nodes. Sets r's sign,
/// point, value, depth, pieces, lowerBound, minCoefficient and tolerance.
template <class Direct>
void search(int d, const double* c, double tol, const Direct& direct, int maxDepth,
            JacobianCertificate* r) {
  const int m = (d + 1) * (d + 2) / 2;
  r->tolerance = tol;
  r->minCoefficient = *std::min_element(c, c + m);
  r->depth = 0;
  r->pieces = 1;
  if (r->minCoefficient > tol) {  // the first expansion proves it
    r->sign = JacobianSign::Positive;
    r->lowerBound = r->minCoefficient;
    return;
  }
  auto nonPositive = [&](const Eigen::Vector2d& p, double value, int level) {
    r->sign = JacobianSign::NonPositive;
    r->point = p;
    r->value = value;
    r->depth = (level + 1) / 2;
  };
  if (d == 0) {  // D constant (a linear triangle): its value decides, not a rounded coefficient
    const Eigen::Vector2d p(1.0 / 3.0, 1.0 / 3.0);
    const double v = direct(p);
    if (v <= tol) return nonPositive(p, v, 0);
    r->sign = JacobianSign::Positive;
    r->lowerBound = v;
    return;
  }
  // Two bisections per level of the split in four (maxDepth counts those).
  const int maxLevel = 2 * std::max(maxDepth, 0);
  std::vector<Piece>& stack = pieceStack(static_cast<std::size_t>(maxLevel) + 2);
  const int corner[3] = {0, d, m - 1};  // c_{d00}, c_{0d0}, c_{00d}
  std::size_t top = 0;
  {
    Piece& R = stack[top++];
    R.v[0] = Eigen::Vector2d(0, 0);
    R.v[1] = Eigen::Vector2d(1, 0);
    R.v[2] = Eigen::Vector2d(0, 1);
    std::copy(c, c + m, R.c);
    R.level = 0;
  }
  r->pieces = 0;
  double lowerBound = std::numeric_limits<double>::infinity();
  bool undecided = false;
  int deepest = 0;
  while (top > 0) {
    const Piece& P = stack[--top];
    ++r->pieces;
    deepest = std::max(deepest, P.level);
    const int lo = static_cast<int>(std::min_element(P.c, P.c + m) - P.c);
    if (P.c[lo] > tol) {
      lowerBound = std::min(lowerBound, P.c[lo]);
      continue;
    }
    // A point of the piece where D ≤ τ, evaluated from the nodes (the coefficients only point
    // to it: a corner coefficient equals D there up to rounding).
    for (int k = 0; k < 3; ++k)
      if (P.c[corner[k]] <= tol) {
        const double v = direct(P.v[k]);
        if (v <= tol) return nonPositive(P.v[k], v, P.level);
      }
    int j = lo, k = 0;
    while (j > d - k) j -= d - k++ + 1;
    const Eigen::Vector2d p = ((d - j - k) * P.v[0] + j * P.v[1] + k * P.v[2]) / d;
    const double v = direct(p);
    if (v <= tol) return nonPositive(p, v, P.level);
    if (P.level >= maxLevel || r->pieces + static_cast<int>(top) >= kCertificateMaxPieces) {
      undecided = true;
      continue;
    }
    // P's slot is reused: the halves go to top and top + 1 (P copied first).
    const Piece parent = P;
    Piece& h0 = stack[top];
    Piece& h1 = stack[top + 1];
    bisect(parent, d, &h0, &h1);
    // The half with the smaller coefficient on top (examined first).
    if (*std::min_element(h0.c, h0.c + m) < *std::min_element(h1.c, h1.c + m)) std::swap(h0, h1);
    top += 2;
  }
  r->depth = (deepest + 1) / 2;
  if (undecided) return;
  r->sign = JacobianSign::Positive;
  r->lowerBound = lowerBound;
}

/// Whether every value is finite.
bool allFinite(const double* v, int n) {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(v[i])) return false;
  return true;
}

/// The verdict on D's coefficients c (degree d) with their τ (no diagnostics from samples);
/// `zero`: D ≡ 0 (no direction to judge against), NonPositive at the centroid.
template <class Direct>
JacobianCertificate decide(int d, const double* c, const CoefficientBound& b, bool zero,
                           const Direct& direct, int maxDepth) {
  JacobianCertificate r;
  if (!std::isfinite(b.tolerance) || !allFinite(c, (d + 1) * (d + 2) / 2)) return r;  // Undecided
  if (zero) {
    r.tolerance = b.tolerance;
    r.minCoefficient = b.minCoefficient;
    r.sign = JacobianSign::NonPositive;
    r.point = Eigen::Vector2d(1.0 / 3.0, 1.0 / 3.0);
    r.value = 0.0;
    r.pieces = 1;
    return r;
  }
  search(d, c, b.tolerance, direct, maxDepth, &r);
  return r;
}

/// The verdict against the direction n.
JacobianCertificate decideReference(int order, const Vec3* x, const Vec3& n, int maxDepth) {
  if (!n.allFinite()) return JacobianCertificate{};  // Undecided
  double c[kMaxCoefficients];
  const CoefficientBound b = referenceCoefficients(order, x, n, c);
  auto direct = [&](const Eigen::Vector2d& p) {
    return triangleJacobianDeterminant(order, x, n, p);
  };
  return decide(2 * (order - 1), c, b, n.norm() == 0.0, direct, maxDepth);
}

/// The verdict against the nodes' normals; `filled`: the normals with the poles' replaced,
/// `normals` the length of their sum (fillPoleNormals).
JacobianCertificate decideAgainstNodeNormals(int order, const Vec3* x, const Vec3* filled,
                                             double normals, int maxDepth) {
  double c[kMaxCoefficients];
  const CoefficientBound b = fieldCoefficients(order, x, filled, c);
  auto direct = [&](const Eigen::Vector2d& p) {
    return triangleJacobianAgainstNodeNormals(order, x, filled, p);
  };
  return decide(3 * order - 2, c, b, normals == 0.0, direct, maxDepth);
}

}  // namespace

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

JacobianCertificate certifyTriangleJacobian(int order, const Vec3* x, const Vec3& n, int maxDepth) {
  const CertificateBasis& B = basis(order);
  JacobianCertificate r = decideReference(order, x, n, maxDepth);
  if (!n.allFinite()) return r;
  // Diagnostics: D at the equispaced points of order d, against the first expansion.
  double lowest = std::numeric_limits<double>::infinity();
  for (int a = 0; a < B.count; ++a) {
    Vec3 xa, xb;
    tangents(x, B.grad.data() + static_cast<std::size_t>(a) * static_cast<std::size_t>(B.nodes),
             B.nodes, &xa, &xb);
    lowest = std::min(lowest, xa.cross(xb).dot(n));
  }
  r.minSampled = lowest;
  r.ratio = r.minCoefficient / r.minSampled;
  return r;
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
  const int nn = B.nodes;
  Vec3 nodeNormals[kMaxElementNodes];
  double normals = 0.0;
  if (!fillPoleNormals(nodeNormalsIn, nn, nodeNormals, &normals))
    return JacobianCertificate{};  // Undecided
  JacobianCertificate r = decideAgainstNodeNormals(order, x, nodeNormals, normals, maxDepth);
  // Diagnostics: D_h at the equispaced points of order d, against the first expansion.
  double lowest = std::numeric_limits<double>::infinity();
  for (int a = 0; a < B.count; ++a) {
    const std::size_t o = static_cast<std::size_t>(a) * static_cast<std::size_t>(nn);
    Vec3 xa, xb;
    tangents(x, B.grad.data() + o, nn, &xa, &xb);
    lowest = std::min(lowest, xa.cross(xb).dot(interpolate(nodeNormals, B.shape.data() + o, nn)));
  }
  r.minSampled = lowest;
  r.ratio = r.minCoefficient / r.minSampled;
  return r;
}

JacobianCertificate certifyElementJacobian(ElementType type, const Vec3* x, const Vec3& n) {
  if (isQuad(type))
    throw std::invalid_argument(std::string("certifyElementJacobian: ") + elementTypeName(type) +
                                " is not a triangle (see elementCertifiedValid)");
  return certifyTriangleJacobian(elementOrder(type), x, n);
}

bool markUncertifiedFold(ElementType type, const Vec3* x, const Vec3& n, double delta,
                         ElementEval* r, Vec3* grad, Mat3* hess, double* eta0,
                         const PlanarMeasure* m, int freeLocal, const Mat2* target) {
  if (r->tangled || !isHighOrderTriangle(type)) return false;
  const int p = elementOrder(type);
  const JacobianCertificate c = decideReference(p, x, n, kCertificateMaxDepth);
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
  const SizedMeasure sized(*m);  // against the straight-sided triangle: its size too
  const ElementEval e = jacobianDistortion(target ? static_cast<const PlanarMeasure&>(sized) : *m,
                                           J, target ? *target : equilateralWinv(), n, delta,
                                           derivs ? &g[freeLocal] : nullptr, derivs ? &gs : nullptr,
                                           derivs && hess ? &Hs : nullptr);
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
  double c[kMaxCoefficients];
  return referenceCoefficients(order, x, n, c);
}

CoefficientBound bezierCoefficientBoundAgainstNodeNormals(int order, const Vec3* x,
                                                          const Vec3* nodeNormals) {
  const CertificateBasis& B = fieldBasis(order);  // (the order's check)
  Vec3 filled[kMaxElementNodes];
  double normals = 0.0;
  if (!fillPoleNormals(nodeNormals, B.nodes, filled, &normals)) return CoefficientBound{};
  double c[kMaxCoefficients];
  return fieldCoefficients(order, x, filled, c);
}

bool triangleJacobianPositive(int order, const Vec3* x, const Vec3& n) {
  basis(order);  // (the order's check)
  return decideReference(order, x, n, kCertificateMaxDepth).sign == JacobianSign::Positive;
}

bool triangleJacobianPositiveAgainstNodeNormals(int order, const Vec3* x, const Vec3* nodeNormals) {
  const CertificateBasis& B = fieldBasis(order);  // (the order's check)
  Vec3 filled[kMaxElementNodes];
  double normals = 0.0;
  if (!fillPoleNormals(nodeNormals, B.nodes, filled, &normals)) return false;
  return decideAgainstNodeNormals(order, x, filled, normals, kCertificateMaxDepth).sign ==
         JacobianSign::Positive;
}

namespace {

/// The verdict against node normals on the piece of the element (nodes x) with reference
/// corners a, b, c (counter-clockwise, as the element's): true when proven positive. With
/// `pieceNormals`, the piece is the whole element and those are its node normals; without,
/// the piece's nodes and normals are taken from x and `normalAt`. When
/// the search finds a point where D_h ≤ τ, D there against the face's own normal decides at
/// once: not positive, a fold against the face (false, and no other piece is examined);
/// positive, the interpolation was at fault, and the piece is split (up to `depth`).
bool piecePositive(const LagrangeTriangle& L, const Vec3* x, const Vec3* pieceNormals,
                   const FaceNormalAt& normalAt, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                   const Eigen::Vector2d& c, int depth) {
  const int nn = L.nodeCount();
  Vec3 xs[kMaxElementNodes], ns[kMaxElementNodes];
  const Vec3 *px = x, *pn = pieceNormals;  // the element itself, with its node normals
  if (!pieceNormals) {
    px = xs;
    pn = ns;
    double N[kMaxElementNodes];
    for (int k = 0; k < nn; ++k) {
      const Eigen::Vector2d& r = L.nodes()[static_cast<std::size_t>(k)];
      const Eigen::Vector2d xi = a + r.x() * (b - a) + r.y() * (c - a);
      L.shape(xi, N);
      Vec3 p = Vec3::Zero();
      for (int i = 0; i < nn; ++i) p += N[i] * x[i];
      xs[k] = p;
      ns[k] = normalAt(xi);
    }
  }
  Vec3 filled[kMaxElementNodes];
  double normals = 0.0;
  if (!fillPoleNormals(pn, nn, filled, &normals)) return false;
  const JacobianCertificate v =
      decideAgainstNodeNormals(L.order(), px, filled, normals, kCertificateMaxDepth);
  if (v.sign == JacobianSign::Positive) return true;
  if (v.sign == JacobianSign::NonPositive && v.point.allFinite()) {
    const Eigen::Vector2d xi = a + v.point.x() * (b - a) + v.point.y() * (c - a);
    Eigen::Vector2d g[kMaxElementNodes];
    L.gradients(xi, g);
    Vec3 xa, xb;
    tangents(x, g, nn, &xa, &xb);
    if (!(xa.cross(xb).dot(normalAt(xi)) > 0.0)) return false;
  }
  if (depth <= 0) return false;
  const Eigen::Vector2d ab = 0.5 * (a + b), bc = 0.5 * (b + c), ca = 0.5 * (c + a);
  const Eigen::Vector2d pieces[4][3] = {{a, ab, ca}, {ab, b, bc}, {ca, bc, c}, {ab, bc, ca}};
  for (const auto& q : pieces)
    if (!piecePositive(L, x, nullptr, normalAt, q[0], q[1], q[2], depth - 1)) return false;
  return true;
}

}  // namespace

bool triangleJacobianPositiveOnPieces(int order, const Vec3* x, const Vec3* nodeNormals,
                                      const FaceNormalAt& normalAt, int depth) {
  basis(order);  // (the order's check)
  return piecePositive(lagrangeTriangle(order), x, nodeNormals, normalAt, Eigen::Vector2d(0.0, 0.0),
                       Eigen::Vector2d(1.0, 0.0), Eigen::Vector2d(0.0, 1.0), depth);
}

bool elementCertifiedValid(ElementType type, const Vec3* x, const Vec3& n) {
  if (!isQuad(type)) return triangleJacobianPositive(elementOrder(type), x, n);
  // Quad4 and quad8: their own proofs, inside their distortion (any measure: validity only).
  return !elementDistortion(measureByName("shape"), type, x, n, 0.0).tangled;
}

}  // namespace surfmesh
