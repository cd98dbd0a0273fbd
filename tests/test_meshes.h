#pragma once
// Nominal meshes several tests share.

#include "fitting/triangle_mesh.h"

namespace s2m::test {

// The box [-a, a] x [-b, b] x [0, c], two triangles per face, counter-clockwise seen from outside, one group
// per face in the order +x, -x, +y, -y, top, bottom (named so; no units set).
inline TriangleMesh BoxMesh(double a, double b, double c) {
  TriangleMesh m;
  m.vertices.resize(3, 8);
  for (int i = 0; i < 8; ++i)
    m.vertices.col(i) << ((i & 1) ? a : -a), ((i & 2) ? b : -b), ((i & 4) ? c : 0.0);
  // Faces as quads (v0, v1, v2, v3) counter-clockwise from outside.
  const int quads[6][4] = {{1, 3, 7, 5}, {0, 4, 6, 2}, {2, 6, 7, 3},
                           {0, 1, 5, 4}, {4, 5, 7, 6}, {0, 2, 3, 1}};
  m.triangles.resize(3, 12);
  for (int f = 0; f < 6; ++f) {
    m.triangles.col(2 * f) << quads[f][0], quads[f][1], quads[f][2];
    m.triangles.col(2 * f + 1) << quads[f][0], quads[f][2], quads[f][3];
    m.groups.push_back(f);
    m.groups.push_back(f);
  }
  m.group_names = {"+x", "-x", "+y", "-y", "top", "bottom"};
  return m;
}

}  // namespace s2m::test
