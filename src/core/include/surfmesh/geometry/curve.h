// SurfMesh — parameterized curves C : [tmin, tmax] → R³ (CAD edges), used to let boundary
// nodes slide along their edge.
#pragma once

#include "surfmesh/geometry/surface.h"

#include <memory>
#include <string>

namespace surfmesh {

/// Point and derivatives of a curve at t.
struct CurveD2 {
  Vec3 p;    ///< C(t)
  Vec3 dt;   ///< C'(t)
  Vec3 dtt;  ///< C''(t)
};

/// Abstract parameterized curve (a CAD edge). Not thread-safe: clone() one per thread.
class Curve {
 public:
  virtual ~Curve() = default;
  virtual Vec3 value(double t) const = 0;
  virtual CurveD2 d2(double t) const = 0;
  virtual double tmin() const = 0;
  virtual double tmax() const = 0;
  virtual bool isPeriodic() const { return false; }
  virtual double period() const { return 0.0; }

  /// Number of faces this edge bounds, and their ids (face ids of the SurfaceMesh).
  virtual int faceCount() const = 0;
  virtual int faceId(int k) const = 0;
  /// (u,v) of C(t) on face `faceId` (through the edge's pcurve on that face). For a seam edge
  /// the face sees the edge twice; `near` selects the pcurve whose image is closest to it.
  virtual Vec2 uvOnFace(int faceId, double t, const Vec2& near) const = 0;

  virtual std::unique_ptr<Curve> clone() const = 0;
  virtual std::string describe() const = 0;
};

}  // namespace surfmesh
