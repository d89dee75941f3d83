# Sourced by build.sh and scripts/fuzz.sh: the Debian packages the build needs (TetGen for surface
# meshes, libpng for `nexdyn render`, gnuplot for `nexdyn plot`, Debian's Python 3 for the scripts
# the README shows and the Python module with NumPy, Dask and pytest), and a function
# that installs those of a list that are missing (apt-get update first: a fresh machine's
# package lists can be empty; sudo only when not root).
nexdyn_packages=(build-essential cmake ninja-build libeigen3-dev libtbb-dev libembree-dev
                 libsuitesparse-dev libopenblas0-pthread doctest-dev libbenchmark-dev
                 nlohmann-json3-dev libcli11-dev libtet1.5-dev libpng-dev gnuplot-nox python3
                 python3-dev pybind11-dev python3-numpy python3-dask python3-distributed python3-pytest)

install_missing() {
  local missing=() p sudo=""
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "$(basename "$0"): installing ${missing[*]}"
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y --no-install-recommends "${missing[@]}"
}
