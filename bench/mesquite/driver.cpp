// Mesquite peer of bench/peers.py (docs/performance.md, "Against every peer"): Mesquite's
// UntangleWrapper then ShapeImprover on a triangulated unit sphere, the nodes kept on the
// sphere by a SphericalDomain. Our code on Mesquite's public API; built by
// bench/mesquite/build.sh against $MESQUITE_DIR.
//
//   mesquite_driver IN.txt OUT.txt SECONDS
//
// IN.txt / OUT.txt: "N T", then N lines "x y z", then T lines "i j k" (0-based node indices).
// SECONDS caps both wrappers together (Mesquite's own CPU-time termination criteria: the
// untangler gets SECONDS, the shape improver what is left; they are checked between
// iterations, so a run may overshoot a little, and the shape improver may end earlier on its
// own movement criterion). Prints one JSON line on stdout
// (the last line): seconds (wall, both wrappers), inverted_before / inverted_after (Mesquite's
// QualityAssessor count of inverted elements), untangle_seconds, shape_seconds, flipped.
#include <Mesquite.hpp>
#include <Mesquite_ArrayMesh.hpp>
#include <Mesquite_InstructionQueue.hpp>
#include <Mesquite_MsqError.hpp>
#include <Mesquite_QualityAssessor.hpp>
#include <Mesquite_ShapeImprover.hpp>
#include <Mesquite_SphericalDomain.hpp>
#include <Mesquite_UntangleWrapper.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using namespace Mesquite;

static double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Mesquite's count of inverted elements (a QualityAssessor without a metric checks just that).
static int inverted(MeshDomainAssoc& md) {
  MsqError err;
  QualityAssessor qa(false, false);
  InstructionQueue q;
  q.add_quality_assessor(&qa, err);
  q.run_instructions(&md, err);
  int elems = -1, samples = 0;
  if (err || !qa.get_inverted_element_count(elems, samples, err)) return -1;
  return elems;
}

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: mesquite_driver IN.txt OUT.txt SECONDS\n";
    return 2;
  }
  const double cap = std::atof(argv[3]);
  std::ifstream in(argv[1]);
  unsigned long n = 0, t = 0;
  if (!(in >> n >> t) || n == 0 || t == 0) {
    std::cerr << "cannot read " << argv[1] << "\n";
    return 2;
  }
  std::vector<double> xyz(3 * n);
  std::vector<unsigned long> conn(3 * t);
  for (auto& v : xyz) in >> v;
  for (auto& v : conn) in >> v;
  if (!in) {
    std::cerr << "truncated " << argv[1] << "\n";
    return 2;
  }
  // Mesquite reads a surface element's orientation against the domain's normal (outward for
  // a SphericalDomain): a mesh oriented inward as a whole is turned over, and back on output.
  long inward = 0;
  for (unsigned long e = 0; e < t; ++e) {
    const double* a = &xyz[3 * conn[3 * e]];
    const double* b = &xyz[3 * conn[3 * e + 1]];
    const double* c = &xyz[3 * conn[3 * e + 2]];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double nx = u[1] * v[2] - u[2] * v[1], ny = u[2] * v[0] - u[0] * v[2],
           nz = u[0] * v[1] - u[1] * v[0];
    if (nx * (a[0] + b[0] + c[0]) + ny * (a[1] + b[1] + c[1]) + nz * (a[2] + b[2] + c[2]) < 0)
      ++inward;
  }
  const bool flipped = 2 * inward > (long)t;
  if (flipped)
    for (unsigned long e = 0; e < t; ++e) std::swap(conn[3 * e + 1], conn[3 * e + 2]);

  // The mesh wraps our arrays (no copy); no fixed node: the sphere is closed.
  std::vector<int> fixed(n, 0);
  ArrayMesh mesh(3, n, xyz.data(), fixed.data(), t, TRIANGLE, conn.data());
  SphericalDomain sphere(Vector3D(0, 0, 0), 1.0);
  MeshDomainAssoc md(&mesh, &sphere, false, true, true);

  const int before = inverted(md);
  MsqError err;
  const double t0 = now();
  UntangleWrapper untangle;
  untangle.set_cpu_time_limit(cap);
  untangle.quality_assessor().disable_printing_results();
  untangle.run_instructions(&md, err);
  std::string error;
  if (err) error = std::string("untangle: ") + err.error_message();
  const double t1 = now();
  double left = cap - (t1 - t0);
  if (error.empty() && left > 0) {
    ShapeImprover shape;
    shape.set_cpu_time_limit(left);
    shape.quality_assessor().disable_printing_results();
    shape.run_instructions(&md, err);
    if (err) error = std::string("shape: ") + err.error_message();
  }
  const double t2 = now();
  const int after = inverted(md);

  if (flipped)
    for (unsigned long e = 0; e < t; ++e) std::swap(conn[3 * e + 1], conn[3 * e + 2]);
  FILE* out = std::fopen(argv[2], "w");
  if (!out) {
    std::cerr << "cannot write " << argv[2] << "\n";
    return 2;
  }
  std::fprintf(out, "%lu %lu\n", n, t);
  for (unsigned long i = 0; i < n; ++i)
    std::fprintf(out, "%.17g %.17g %.17g\n", xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  for (unsigned long e = 0; e < t; ++e)
    std::fprintf(out, "%lu %lu %lu\n", conn[3 * e], conn[3 * e + 1], conn[3 * e + 2]);
  std::fclose(out);

  std::ostringstream js;
  js << "{\"seconds\": " << t2 - t0 << ", \"untangle_seconds\": " << t1 - t0
     << ", \"shape_seconds\": " << t2 - t1 << ", \"inverted_before\": " << before
     << ", \"inverted_after\": " << after << ", \"flipped\": " << (flipped ? "true" : "false");
  if (!error.empty()) {
    std::string e;
    for (char ch : error)
      if (ch != '"' && ch != '\\' && ch != '\n') e += ch;
    js << ", \"error\": \"" << e.substr(0, 200) << "\"";
  }
  js << "}";
  std::cout.flush();
  std::printf("\n%s\n", js.str().c_str());
  return error.empty() ? 0 : 1;
}
