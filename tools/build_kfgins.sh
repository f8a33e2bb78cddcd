#!/bin/sh
# Build KF-GINS (i2Nav-WHU/KF-GINS, GPL-3.0, the peer of bench/bench_process.py) from a
# checkout against Debian's libraries instead of its bundled ThirdParty folder.
#
# Usage: tools/build_kfgins.sh SRC_DIR BUILD_DIR
#   SRC_DIR    a KF-GINS clone (git clone https://github.com/i2Nav-WHU/KF-GINS); only its
#              CMakeLists.txt and src/ are used, ThirdParty/ may be absent
#   BUILD_DIR  where the patched tree is configured and built; the executable is
#              BUILD_DIR/bin/KF-GINS (run: KF-GINS config.yaml)
#   KFGINS_OPT optimisation flags (environment), default "-O2 -DNDEBUG" (a Release build)
#
# Needs (Debian 12, as root):
#   apt-get install -y g++ make cmake libeigen3-dev libyaml-cpp-dev libabsl-dev
# (Eigen 3.4.0, yaml-cpp 0.7.0, abseil 20220623.1: the same yaml-cpp and abseil releases
# as KF-GINS's ThirdParty folder, Eigen 3.4.0 instead of 3.3.9.)
#
# The source tree is not modified: CMakeLists.txt and src/ are copied into
# BUILD_DIR/src-patched and CMakeLists.txt is patched there (sed below):
#   - EXECUTABLE_OUTPUT_PATH / LIBRARY_OUTPUT_PATH: the build tree, not the source tree;
#   - include_directories(ThirdParty/eigen-3.3.9)      -> find_package(Eigen3) + Eigen3::Eigen;
#   - add_subdirectory(ThirdParty/yaml-cpp-0.7.0)      -> find_package(yaml-cpp) (target yaml-cpp);
#   - add_subdirectory(ThirdParty/abseil-cpp-20220623.1) -> find_package(absl) (absl::strings,
#     absl::str_format, absl::time as before).
# Debian's abseil is built with ABSL_OPTION_USE_STD_STRING_VIEW 0, so KF-GINS's C++14
# standard links against it unchanged. No source file is changed.
set -eu
if [ $# -ne 2 ]; then
    echo "usage: $0 SRC_DIR BUILD_DIR" >&2
    exit 2
fi
SRC=$(cd "$1" && pwd)
mkdir -p "$2"
BUILD=$(cd "$2" && pwd)
OPT=${KFGINS_OPT:-"-O2 -DNDEBUG"}
for f in CMakeLists.txt src/kf_gins.cpp src/kf-gins/gi_engine.cpp src/kf-gins/insmech.cpp; do
    [ -f "$SRC/$f" ] || { echo "$SRC/$f: missing (not a KF-GINS checkout?)" >&2; exit 2; }
done

PATCHED="$BUILD/src-patched"
rm -rf "$PATCHED"
mkdir -p "$PATCHED"
cp -r "$SRC/src" "$PATCHED/src"
sed -e 's|^set(EXECUTABLE_OUTPUT_PATH .*|set(EXECUTABLE_OUTPUT_PATH ${PROJECT_BINARY_DIR}/bin)|' \
    -e 's|^set(LIBRARY_OUTPUT_PATH .*|set(LIBRARY_OUTPUT_PATH ${PROJECT_BINARY_DIR}/lib)|' \
    -e 's|^include_directories(ThirdParty/eigen[^)]*)|find_package(Eigen3 3.3 REQUIRED NO_MODULE)\ntarget_link_libraries(${PROJECT_NAME} Eigen3::Eigen)|' \
    -e 's|^add_subdirectory(ThirdParty/yaml-cpp[^)]*)|find_package(yaml-cpp REQUIRED)|' \
    -e 's|^add_subdirectory(ThirdParty/abseil-cpp[^)]*)|find_package(absl REQUIRED)|' \
    "$SRC/CMakeLists.txt" > "$PATCHED/CMakeLists.txt"
if grep -n ThirdParty "$PATCHED/CMakeLists.txt"; then
    echo "$SRC/CMakeLists.txt: a ThirdParty line the patch does not know (above)" >&2
    exit 2
fi

cmake -S "$PATCHED" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_CXX_FLAGS_RELEASE="$OPT" >"$BUILD/cmake.log"
make -C "$BUILD" -j"$(nproc)" >"$BUILD/make.log"
echo "$BUILD/bin/KF-GINS"
