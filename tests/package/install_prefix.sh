# Sourced by the package tests (check_package.sh, check_engine_client.sh): terravt installed
# from a build tree into a fresh temporary prefix, and clients built against it.
#   tvt_install_prefix BUILD_DIR   sets $work (a temporary folder, removed at exit) and
#                                  $prefix ($work/prefix, the installed package)
#   tvt_build_client SOURCE_DIR BINARY_DIR [cmake args...]   configures and builds a client
#                                  project with CMAKE_PREFIX_PATH=$prefix (output only on failure)
tvt_install_prefix() {
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
  prefix=$work/prefix
  cmake --install "$1" --prefix "$prefix" >/dev/null
}

tvt_build_client() {
  local source=$1 binary=$2
  shift 2
  local log=$work/$(basename "$binary").log
  if ! { cmake -S "$source" -B "$binary" -DCMAKE_PREFIX_PATH="$prefix" "$@" && cmake --build "$binary"; } >"$log" 2>&1; then
    cat "$log"
    echo "FAIL: the client $source does not build against the installed package"
    return 1
  fi
}
