// MeshError: the one exception type of mesh input.
//
// Mesh loading is an edge of the engine (DESIGN "Errors"): a bad file must stop the run with one
// line that a user can act on. Every message therefore names the file (when there is one), the
// line, and the offending node or element tag, e.g.
//   "meshes/bar.msh: line 41: element 17 references unknown node tag 99".
#pragma once

#include <stdexcept>
#include <string>

namespace nexdyn {

class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace nexdyn
