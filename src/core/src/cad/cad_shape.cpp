// SurfMesh — a B-rep shape with indexed faces, edges and vertices (see cad_shape.h).
#include "surfmesh/cad/cad_shape.h"

#include <BRepAdaptor_Surface.hxx>
#include <BRepBndLib.hxx>
#include <BRepTools.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Reader.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_Failure.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopTools_ListOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Face.hxx>
#include <gp_Torus.hxx>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace surfmesh {

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// The bounding box of a face, and (`points`) a box of points of the face's surface. OCC's box
/// (BRepBndLib::Add) can miss most of a torus face whose parameter range does not start where
/// OCC's bounding of the torus expects it: the face of Part.makeTorus(R, r, p, d, -180, 180)
/// (v in [-π, π]) gets a box flat in z (OCCT 7.6). For tori and surfaces of revolution a grid
/// of the face's points over its (u,v) box is checked against OCC's box; where one falls out,
/// the box also takes in, for a torus, the grid's box enlarged by the largest gap between the
/// torus's circles and their chords over a grid cell (any point of the face is that near a
/// chord, and the chords lie in the box of the grid points), for a surface of revolution the
/// box of BRepBndLib::AddOptimal. Elsewhere OCC's box stays as it is (spheres, cylinders and
/// cones over shifted ranges are bounded right: tests/cpp/cad_periodic_test).
Bnd_Box faceBoundingBox(const TopoDS_Face& face, Bnd_Box* points) {
  Bnd_Box box;
  BRepBndLib::Add(face, box, Standard_False);
  try {
    BRepAdaptor_Surface ad(face, Standard_True);
    const GeomAbs_SurfaceType type = ad.GetType();
    if (type != GeomAbs_Torus && type != GeomAbs_SurfaceOfRevolution) return box;
    double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
    BRepTools::UVBounds(face, u0, u1, v0, v1);
    constexpr int n = 32;
    const double du = (u1 - u0) / n, dv = (v1 - v0) / n;
    Bnd_Box grid;
    bool out = false;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        const gp_Pnt p = ad.Value(u0 + i * du, v0 + j * dv);
        grid.Add(p);
        out = out || box.IsOut(p);
      }
    points->Add(grid);
    if (!out) return box;
    const double tol = BRep_Tool::Tolerance(face);
    if (type == GeomAbs_Torus) {
      const gp_Torus t = ad.Torus();
      const double R = t.MajorRadius(), r = t.MinorRadius();
      grid.Enlarge((R + r) * (1.0 - std::cos(0.5 * du)) + r * (1.0 - std::cos(0.5 * dv)) + tol);
      box.Add(grid);
    } else {
      Bnd_Box exact;
      BRepBndLib::AddOptimal(face, exact, Standard_False, Standard_False);
      if (!exact.IsVoid()) {
        exact.Enlarge(tol);
        box.Add(exact);
      }
    }
  } catch (const Standard_Failure&) {
  }
  return box;
}

void sortUnique(std::vector<int>& v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
}

}  // namespace

CadShape::CadShape(const TopoDS_Shape& shape) : shape_(shape) {
  if (shape_.IsNull()) throw std::invalid_argument("the shape is null (empty)");
  TopExp::MapShapes(shape_, TopAbs_FACE, faces_);
  TopExp::MapShapes(shape_, TopAbs_EDGE, edges_);
  TopExp::MapShapes(shape_, TopAbs_VERTEX, vertices_);
  if (faces_.Extent() == 0)
    throw std::invalid_argument("the shape has no faces (a mesh needs surfaces)");

  const int nf = faces_.Extent(), ne = edges_.Extent(), nv = vertices_.Extent();
  surfaces_.reserve(static_cast<std::size_t>(nf));
  faceBoxes_.resize(static_cast<std::size_t>(nf));
  Bnd_Box surfacePoints;
  for (int f = 0; f < nf; ++f) {
    const TopoDS_Face& face = TopoDS::Face(faces_(f + 1));
    surfaces_.push_back(std::make_unique<OccFaceSurface>(face, f));
    faceBoxes_[static_cast<std::size_t>(f)] = faceBoundingBox(face, &surfacePoints);
  }
  BRepBndLib::Add(shape_, bbox_, Standard_False);
  // Points of the faces that OCC's box may have missed (see faceBoundingBox): the diagonal,
  // the scale of every tolerance, is the shape's (unchanged where OCC's box holds them).
  if (!surfacePoints.IsVoid()) bbox_.Add(surfacePoints);
  if (!bbox_.IsVoid()) diagonal_ = std::sqrt(bbox_.SquareExtent());
  for (auto& s : surfaces_) s->setShapeDiagonal(diagonal_);

  // Adjacency.
  edgeFaces_.assign(static_cast<std::size_t>(ne), {});
  faceEdges_.assign(static_cast<std::size_t>(nf), {});
  edgeVertices_.assign(static_cast<std::size_t>(ne), {});
  vertexEdges_.assign(static_cast<std::size_t>(nv), {});
  vertexFaces_.assign(static_cast<std::size_t>(nv), {});
  for (int f = 0; f < nf; ++f) {
    for (TopExp_Explorer ex(faces_(f + 1), TopAbs_EDGE); ex.More(); ex.Next()) {
      const int e = edges_.FindIndex(ex.Current()) - 1;
      if (e < 0) continue;
      edgeFaces_[static_cast<std::size_t>(e)].push_back(f);
      faceEdges_[static_cast<std::size_t>(f)].push_back(e);
    }
  }
  for (int e = 0; e < ne; ++e) {
    auto& ev = edgeVertices_[static_cast<std::size_t>(e)];
    for (TopExp_Explorer ex(edges_(e + 1), TopAbs_VERTEX); ex.More(); ex.Next()) {
      const int v = vertices_.FindIndex(ex.Current()) - 1;
      if (v >= 0) ev.push_back(v);
    }
    sortUnique(ev);
    sortUnique(edgeFaces_[static_cast<std::size_t>(e)]);
    for (int v : ev) {
      vertexEdges_[static_cast<std::size_t>(v)].push_back(e);
      for (int f : edgeFaces_[static_cast<std::size_t>(e)])
        vertexFaces_[static_cast<std::size_t>(v)].push_back(f);
    }
  }
  for (auto& l : faceEdges_) sortUnique(l);
  for (auto& l : vertexEdges_) sortUnique(l);
  for (auto& l : vertexFaces_) sortUnique(l);

  // Curves with their pcurves on the adjacent faces.
  curves_.reserve(static_cast<std::size_t>(ne));
  edgeBoxes_.resize(static_cast<std::size_t>(ne));
  for (int e = 0; e < ne; ++e) {
    const TopoDS_Edge& edge = TopoDS::Edge(edges_(e + 1));
    std::vector<EdgeFaceUse> uses;
    for (int f : edgeFaces_[static_cast<std::size_t>(e)]) {
      EdgeFaceUse u;
      u.faceId = f;
      u.face = TopoDS::Face(faces_(f + 1));
      const OccFaceSurface& s = *surfaces_[static_cast<std::size_t>(f)];
      u.uPeriod = s.isUPeriodic() ? s.uPeriod() : 0.0;
      u.vPeriod = s.isVPeriodic() ? s.vPeriod() : 0.0;
      double a = 0, b = 0;
      try {
        const TopoDS_Edge fwd = TopoDS::Edge(edge.Oriented(TopAbs_FORWARD));
        u.pcurve = BRep_Tool::CurveOnSurface(fwd, u.face, a, b);
        if (BRep_Tool::IsClosed(edge, u.face)) {
          const TopoDS_Edge rev = TopoDS::Edge(edge.Oriented(TopAbs_REVERSED));
          u.pcurve2 = BRep_Tool::CurveOnSurface(rev, u.face, a, b);
        }
      } catch (const Standard_Failure&) {
      }
      uses.push_back(u);
    }
    curves_.push_back(std::make_unique<OccEdgeCurve>(edge, e, std::move(uses)));
    if (!BRep_Tool::Degenerated(edge))
      BRepBndLib::Add(edge, edgeBoxes_[static_cast<std::size_t>(e)], Standard_False);
  }
}

CadShape::~CadShape() = default;

std::shared_ptr<CadShape> CadShape::fromBrepString(const std::string& brep) {
  if (brep.empty()) throw std::invalid_argument("CadShape::fromBrepString: empty BREP string");
  TopoDS_Shape s;
  BRep_Builder builder;
  try {
    std::istringstream in(brep);
    BRepTools::Read(s, in, builder);
  } catch (const Standard_Failure& e) {
    throw std::invalid_argument(std::string("CadShape::fromBrepString: not a readable BREP (") +
                                e.GetMessageString() + ")");
  }
  if (s.IsNull())
    throw std::invalid_argument(
        "CadShape::fromBrepString: not a readable BREP string (expected \"CASCADE Topology "
        "V1\" text as written by Shape.exportBrepToString())");
  return std::make_shared<CadShape>(s);
}

std::shared_ptr<CadShape> CadShape::fromFile(const std::string& path) {
  {
    std::ifstream probe(path);
    if (!probe.good())
      throw std::invalid_argument("CadShape::fromFile: cannot open '" + path +
                                  "' (missing or unreadable)");
  }
  const std::size_t dot = path.find_last_of('.');
  const std::string ext = dot == std::string::npos ? "" : lower(path.substr(dot + 1));
  TopoDS_Shape s;
  try {
    if (ext == "brep" || ext == "brp" || ext == "rle") {
      BRep_Builder builder;
      if (!BRepTools::Read(s, path.c_str(), builder)) s.Nullify();
    } else if (ext == "step" || ext == "stp") {
      STEPControl_Reader reader;
      if (reader.ReadFile(path.c_str()) != IFSelect_RetDone)
        throw std::invalid_argument("CadShape::fromFile: '" + path +
                                    "' is not a readable STEP file");
      reader.TransferRoots();
      s = reader.OneShape();
    } else if (ext == "iges" || ext == "igs") {
      IGESControl_Reader reader;
      if (reader.ReadFile(path.c_str()) != IFSelect_RetDone)
        throw std::invalid_argument("CadShape::fromFile: '" + path +
                                    "' is not a readable IGES file");
      reader.TransferRoots();
      s = reader.OneShape();
    } else {
      throw std::invalid_argument("CadShape::fromFile: unknown extension of '" + path +
                                  "' (expected .brep, .brp, .step, .stp, .iges or .igs)");
    }
  } catch (const Standard_Failure& e) {
    throw std::invalid_argument("CadShape::fromFile: cannot read '" + path + "' (" +
                                e.GetMessageString() + ")");
  }
  if (s.IsNull()) throw std::invalid_argument("CadShape::fromFile: '" + path + "' holds no shape");
  TopExp_Explorer ex(s, TopAbs_FACE);
  if (!ex.More())
    throw std::invalid_argument("CadShape::fromFile: the shape in '" + path + "' has no faces");
  return std::make_shared<CadShape>(s);
}

void CadShape::checkId(int id, int n, const char* what) const {
  if (id < 0 || id >= n) {
    std::ostringstream os;
    os << "CadShape: " << what << " id " << id << " out of range [0, " << n << ")";
    throw std::out_of_range(os.str());
  }
}

const TopoDS_Face& CadShape::face(int id) const {
  checkId(id, faceCount(), "face");
  return TopoDS::Face(faces_(id + 1));
}

const TopoDS_Edge& CadShape::edge(int id) const {
  checkId(id, edgeCount(), "edge");
  return TopoDS::Edge(edges_(id + 1));
}

const TopoDS_Vertex& CadShape::vertex(int id) const {
  checkId(id, vertexCount(), "vertex");
  return TopoDS::Vertex(vertices_(id + 1));
}

const OccFaceSurface& CadShape::surface(int id) const {
  checkId(id, faceCount(), "face");
  return *surfaces_[static_cast<std::size_t>(id)];
}

const OccEdgeCurve& CadShape::curve(int id) const {
  checkId(id, edgeCount(), "edge");
  return *curves_[static_cast<std::size_t>(id)];
}

Vec3 CadShape::vertexPoint(int id) const {
  const gp_Pnt p = BRep_Tool::Pnt(vertex(id));
  return Vec3(p.X(), p.Y(), p.Z());
}

double CadShape::vertexTolerance(int id) const { return BRep_Tool::Tolerance(vertex(id)); }

std::string CadShape::faceType(int id) const { return occSurfaceTypeName(face(id)); }

std::string CadShape::describe() const {
  std::ostringstream os;
  os << faceCount() << " faces, " << edgeCount() << " edges, " << vertexCount()
     << " vertices, bounding box diagonal " << diagonal_ << "\n";
  for (int f = 0; f < faceCount(); ++f) {
    TopTools_IndexedMapOfShape wires;
    TopExp::MapShapes(face(f), TopAbs_WIRE, wires);
    os << "face " << f << ": " << faceType(f)
       << (face(f).Orientation() == TopAbs_REVERSED ? ", Reversed" : "") << ", " << wires.Extent()
       << (wires.Extent() == 1 ? " wire" : " wires") << "\n";
  }
  return os.str();
}

}  // namespace surfmesh
