#pragma once
// Nominal meshes (a part's CAD model exported as triangles): STL (binary and ASCII), Wavefront OBJ and PLY
// meshes, read into an indexed TriangleMesh (fitting/triangle_mesh.h) with face groups. Our own readers, like
// the point-cloud readers: every problem is a FormatError naming the file, the line or byte and what is wrong
// (truncated files, counts that disagree with the size, indices out of range, non-finite coordinates, faces
// with fewer than 3 vertices, no triangles at all). docs/metrology.md section 5 says why not a library's.
//
// Groups: an ASCII STL file's solids (by name), an OBJ file's `g` (or, without any, `o`) statements, a PLY
// face element's integer "label" (or "group", "region") property ("label N"). A binary STL file has one
// group. Vertices of STL files (which repeat them per facet) are merged when bit-identical, so the facets
// share edges (the signed distance's pseudo-normals need them). Polygons of OBJ and PLY are split into
// triangles as fans from their first vertex.

#include <filesystem>
#include <string>

#include "fitting/triangle_mesh.h"

namespace s2m {

enum class MeshFormat { kStlBinary, kStlAscii, kObj, kPly };
const char* ToString(MeshFormat format);

// `units`: the vertices' units (STL and OBJ carry none; a PLY file's "comment units" wins when present).
// `format`: set to the format found when not null. Throws FormatError.
TriangleMesh ReadMesh(const std::filesystem::path& path, const std::string& units = "unknown",
                      MeshFormat* format = nullptr);
// The same from bytes already in memory (`file` names them in errors); the format from the name, and for
// .stl from the bytes (binary when the size is 84 + 50 n for the n its header declares, else ASCII when it
// starts with "solid").
TriangleMesh ParseMesh(const std::string& bytes, const std::string& file,
                       const std::string& units = "unknown", MeshFormat* format = nullptr);

// Writes a binary STL (one group) or an ASCII STL with one solid per group; OBJ with one `g` per group.
// Atomically (written beside, then renamed). Throws std::runtime_error naming the file on failure.
void WriteStl(const std::filesystem::path& path, const TriangleMesh& mesh, bool ascii = false);
void WriteObj(const std::filesystem::path& path, const TriangleMesh& mesh);

}  // namespace s2m
