// SceneError: the one exception type of scene loading.
//
// Loading a scene is an edge of the engine (DESIGN "Errors"): a bad file stops the run with one
// line a user can act on, naming the file, the key path (e.g. "bodies[2].material") and the
// offending value. Code that only needs to throw or catch it includes this header, not scene.hpp.
#pragma once

#include <stdexcept>

namespace nexdyn {

class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace nexdyn
