// SurfMesh — a B-rep shape with indexed faces, edges and vertices.
//
// Numbering: ids are 0-based indices into TopExp::MapShapes(shape, TopAbs_FACE / EDGE /
// VERTEX). FreeCAD's Part.Shape.Faces[i] is map index i + 1, so SurfMesh face id i is
// FreeCAD's Faces[i] ("Face{i+1}"); the same holds for Edges and Vertexes.
//
// A CadShape owns one OccFaceSurface per face and one OccEdgeCurve per edge. They are meant
// for single-threaded use (queries, tests); whoever needs its own copies (CadMesh, worker
// threads) clone()s them.
#pragma once

#include "surfmesh/cad/occ_surface.h"

#include <Bnd_Box.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS_Shape.hxx>
#include <TopoDS_Vertex.hxx>

#include <memory>
#include <string>
#include <vector>

namespace surfmesh {

class CadShape {
 public:
  /// Wraps `shape`. Throws std::invalid_argument if it is null or has no face.
  explicit CadShape(const TopoDS_Shape& shape);
  ~CadShape();
  CadShape(const CadShape&) = delete;
  CadShape& operator=(const CadShape&) = delete;

  /// Reads an OCC BREP text ("CASCADE Topology V1", what FreeCAD's Shape.exportBrepToString()
  /// writes). Throws std::invalid_argument for an unreadable/empty string or a shape without
  /// faces.
  static std::shared_ptr<CadShape> fromBrepString(const std::string& brep);
  /// Reads a file by extension (case-insensitive): .brep/.brp (also .rle), .step/.stp,
  /// .iges/.igs. Throws std::invalid_argument naming the path for a missing or unreadable
  /// file, an unknown extension, an empty shape or a shape without faces.
  static std::shared_ptr<CadShape> fromFile(const std::string& path);

  const TopoDS_Shape& shape() const { return shape_; }

  int faceCount() const { return faces_.Extent(); }
  int edgeCount() const { return edges_.Extent(); }
  int vertexCount() const { return vertices_.Extent(); }

  /// Topological entities by 0-based id (range-checked: std::out_of_range).
  const TopoDS_Face& face(int id) const;
  const TopoDS_Edge& edge(int id) const;
  const TopoDS_Vertex& vertex(int id) const;
  /// 0-based id of a sub-shape (orientation ignored), −1 when it is not part of the shape.
  int faceId(const TopoDS_Shape& f) const { return faces_.FindIndex(f) - 1; }
  int edgeId(const TopoDS_Shape& e) const { return edges_.FindIndex(e) - 1; }
  int vertexId(const TopoDS_Shape& v) const { return vertices_.FindIndex(v) - 1; }

  /// The Surface of face `id` / the Curve of edge `id` (owned by this CadShape).
  const OccFaceSurface& surface(int id) const;
  const OccEdgeCurve& curve(int id) const;
  /// Position of vertex `id` and its tolerance.
  Vec3 vertexPoint(int id) const;
  double vertexTolerance(int id) const;

  /// Adjacency (ids, ascending): faces bounded by an edge (a seam edge lists its face once),
  /// edges of a face, vertices of an edge (1 for a closed edge), edges and faces at a vertex.
  const std::vector<int>& edgeFaces(int edge) const { return edgeFaces_.at(edge); }
  const std::vector<int>& faceEdges(int face) const { return faceEdges_.at(face); }
  const std::vector<int>& edgeVertices(int edge) const { return edgeVertices_.at(edge); }
  const std::vector<int>& vertexEdges(int v) const { return vertexEdges_.at(v); }
  const std::vector<int>& vertexFaces(int v) const { return vertexFaces_.at(v); }
  bool isDegeneratedEdge(int edge) const { return curve(edge).isDegenerated(); }
  /// Whether `edge` is a seam of `face` (bounds it twice, two pcurves).
  bool isSeam(int edge, int face) const { return curve(edge).isSeamOf(face); }

  /// Axis-aligned bounding box of the shape (from its geometry, not a triangulation), and
  /// its diagonal length.
  const Bnd_Box& boundingBox() const { return bbox_; }
  double diagonal() const { return diagonal_; }
  /// Per-face bounding boxes (conservative).
  const Bnd_Box& faceBox(int face) const { return faceBoxes_.at(face); }
  /// Per-edge bounding boxes (conservative; void for degenerated edges).
  const Bnd_Box& edgeBox(int edge) const { return edgeBoxes_.at(edge); }

  /// Surface type of face `id`: "Plane", "Cylinder", "BSplineSurface", … (occSurfaceTypeName).
  std::string faceType(int id) const;
  /// One line per face: "face 3: Cylinder, Reversed, 2 wires".
  std::string describe() const;

 private:
  void checkId(int id, int n, const char* what) const;

  TopoDS_Shape shape_;
  TopTools_IndexedMapOfShape faces_, edges_, vertices_;
  std::vector<std::unique_ptr<OccFaceSurface>> surfaces_;
  std::vector<std::unique_ptr<OccEdgeCurve>> curves_;
  std::vector<std::vector<int>> edgeFaces_, faceEdges_, edgeVertices_, vertexEdges_, vertexFaces_;
  std::vector<Bnd_Box> faceBoxes_, edgeBoxes_;
  Bnd_Box bbox_;
  double diagonal_ = 0.0;
};

}  // namespace surfmesh
