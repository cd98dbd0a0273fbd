#pragma once
// A nominal triangle mesh (a part's CAD model as STL, OBJ or PLY) as a fixed model of the fitting engine,
// with exact point-to-triangle feet found through a bounding-volume hierarchy, and signed distances by the
// angle- weighted pseudo-normals (docs/metrology.md section 5).
//
// Closest point on a triangle: Ericson, "Real-Time Collision Detection", 2005, section 5.1.5 (Voronoi regions
// of the vertices, edges and face). Sign: Baerentzen and Aanaes, "Signed distance computation using the angle
// weighted pseudonormal", IEEE TVCG 11(3), 2005: the sign of (x - foot) . N, where N is the face normal when
// the foot is inside a face, the sum of the two face normals when it is on an edge, and the angle-weighted
// sum of the incident face normals when it is at a vertex; exact for a closed, consistently oriented
// (counter-clockwise seen from outside) 2-manifold, positive outside.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "fitting/parametric_model.h"

namespace s2m {

// A triangle mesh with named face groups (an STL file's solids, an OBJ file's groups, a PLY file's face
// labels).
struct TriangleMesh {
  Eigen::Matrix3Xd vertices;                        // one vertex per column
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles;  // vertex indices, counter-clockwise seen from outside
  // One group index per triangle (into group_names); empty: every triangle in group 0.
  std::vector<int> groups;
  std::vector<std::string> group_names;  // empty: one unnamed group ("all")
  std::string units = "unknown";

  Eigen::Index triangle_count() const { return triangles.cols(); }
  int GroupOf(Eigen::Index triangle) const {
    return groups.empty() ? 0 : groups[static_cast<std::size_t>(triangle)];
  }
  int group_count() const { return group_names.empty() ? 1 : static_cast<int>(group_names.size()); }
  std::string GroupName(int group) const;
  // Group index by name; -1 when absent.
  int FindGroup(const std::string& name) const;
  // Indices in range, finite vertices, at least one triangle of positive area, groups consistent. `why`
  // names the first problem.
  bool IsValid(std::string* why = nullptr) const;
  // Total area, and the area of each group.
  std::vector<double> GroupAreas() const;
};

// Where a foot lies on its triangle: inside, on an edge (AB, BC, CA) or at a vertex (A, B, C).
enum class TriangleRegion { kFace, kEdgeAB, kEdgeBC, kEdgeCA, kVertexA, kVertexB, kVertexC };

struct MeshFoot {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Index triangle = 0;
  double u = 0.0, v = 0.0;  // point = A + u (B - A) + v (C - A)
  TriangleRegion region = TriangleRegion::kFace;
  double distance = 0.0;         // |x - point|
  double signed_distance = 0.0;  // +distance outside (along the pseudo-normal), -distance inside
};

// The closest point of triangle (a, b, c) to x (Ericson 2005, section 5.1.5), with its barycentric (u, v) and
// region.
Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& x, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& u,
                                       double& v, TriangleRegion& region);

// The mesh as a fixed model: no shape parameters; t = (u, v, triangle) with C(t) = A + u (B - A) + v (C - A)
// on triangle t[2] (first derivatives the two edge vectors, second derivatives zero: the facets are flat, so
// SDM's curvature terms vanish and SDM is TDM on the facet's plane). Feet are closed form through the BVH.
class TriangleMeshModel : public ParametricModel {
 public:
  // Throws std::invalid_argument when the mesh is not valid (TriangleMesh::IsValid).
  explicit TriangleMeshModel(TriangleMesh mesh);
  TriangleMeshModel(const TriangleMeshModel& other);
  TriangleMeshModel& operator=(const TriangleMeshModel& other);
  ~TriangleMeshModel() override;

  std::unique_ptr<ParametricModel> Clone() const override;
  void CopyFrom(const ParametricModel& other) override;
  std::string name() const override { return "mesh"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return 0; }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override { return {}; }
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;

  // The closest point of the mesh to x and its signed distance (Baerentzen and Aanaes 2005).
  MeshFoot Foot(const Eigen::Vector3d& x) const;
  const TriangleMesh& mesh() const { return mesh_; }
  // Unit outward normal of a triangle.
  Eigen::Vector3d FaceNormal(Eigen::Index triangle) const { return face_normals_.col(triangle); }

 private:
  struct Node {
    Eigen::Vector3d lo, hi;
    int left = -1, right = -1;  // children; -1 for a leaf
    int begin = 0, end = 0;     // leaf: range in order_
  };
  void Build();
  int BuildNode(int begin, int end);
  Eigen::Vector3d PseudoNormal(Eigen::Index triangle, TriangleRegion region) const;

  TriangleMesh mesh_;
  Eigen::Matrix3Xd face_normals_;
  Eigen::Matrix3Xd edge_normals_;    // 3 per triangle: AB, BC, CA (sums of the adjacent faces' normals)
  Eigen::Matrix3Xd vertex_normals_;  // angle-weighted
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

}  // namespace s2m
