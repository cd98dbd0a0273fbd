// Fuzz target: the nominal-mesh readers (acquisition/mesh_io.h). The first byte picks the file name's suffix
// (the reader chooses by it; for .stl the bytes decide between binary and ASCII), the rest is the file: STL
// (binary, ASCII), Wavefront OBJ and PLY meshes (ascii, binary, gzipped). A mesh the reader accepts must be
// usable by the inspection: it becomes a TriangleMeshModel (the BVH and the pseudo-normals,
// fitting/triangle_mesh.h) and answers signed distances, so a file that passes the reader but breaks the
// model is a finding too.

#include <Eigen/Core>

#include "acquisition/mesh_io.h"
#include "fitting/triangle_mesh.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* const kSuffixes[] = {".stl", ".obj", ".ply", ".ply.gz"};
  const std::string suffix = kSuffixes[data[0] % (sizeof(kSuffixes) / sizeof(kSuffixes[0]))];
  const s2m::fuzz::ScratchFile file(data + 1, size - 1, suffix);
  s2m::fuzz::ExpectOnlyFormatErrors([&] {
    s2m::TriangleMesh mesh = s2m::ReadMesh(file.path());
    const Eigen::Vector3d lo = mesh.vertices.rowwise().minCoeff(), hi = mesh.vertices.rowwise().maxCoeff();
    const s2m::TriangleMeshModel model(std::move(mesh));  // std::invalid_argument here is a finding
    // Feet from the bounding box's centre and corners (finite for any finite mesh, unlike points beyond it):
    // over the corpus they visit every region of a triangle and every branch of the BVH's descent.
    (void)model.Foot(0.5 * lo + 0.5 * hi);
    for (int corner = 0; corner < 8; ++corner) {
      Eigen::Vector3d x;
      for (int c = 0; c < 3; ++c) x[c] = (corner >> c & 1) ? hi[c] : lo[c];
      (void)model.Foot(x);
    }
  });
  return 0;
}
