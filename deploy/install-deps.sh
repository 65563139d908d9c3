#!/usr/bin/env bash
# Installs what building, running and testing the project needs on Debian 12 (bookworm).
# Used by the README's commands, by .ci/run and by the container image.
#   deploy/install-deps.sh           build + runtime + test and CI dependencies
#   deploy/install-deps.sh --build   only what compiling the binaries needs (the image's build stage)
#   deploy/install-deps.sh --runtime only the shared libraries ism-server loads (the image's runtime stage)
set -euo pipefail

# ism-server's own libraries: no pcl_io, pcl_surface or pcl_features (they bring VTK, Qt and OpenNI,
# most of a 1 GB image; core/CMakeLists.txt keeps them out of the server's link).
runtime=(libpcl-common1.13 libpcl-search1.13 libpcl-kdtree1.13 libflann1.9 libgomp1
         libgrpc++1.51 libgrpc29 libprotobuf32 libssl3 libspdlog1.10 libpng16-16 zlib1g
         libprometheus-cpp-core1.0 libprometheus-cpp-pull1.0)
build=(build-essential cmake ninja-build pkg-config git
       libpcl-dev libeigen3-dev libflann-dev libpng-dev zlib1g-dev
       libgrpc++-dev libgrpc-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
       libspdlog-dev libcli11-dev nlohmann-json3-dev libopenni2-dev prometheus-cpp-dev libssl-dev)
test=(libgtest-dev libgmock-dev libbenchmark-dev openssl
      python3 python3-grpcio python3-protobuf python3-numpy python3-yaml
      sweethome3d-furniture
      podman buildah debootstrap runc
      clang libclang-rt-14-dev libomp-dev)  # .ci: libFuzzer and TSan runtimes, OpenMP for clang
# The Node client's tests need node >= 18 and npm; a node already installed (e.g. a newer one
# from NodeSource, which bundles npm) is kept.
if ! command -v node >/dev/null; then test+=(nodejs npm); fi

case "${1:-}" in
  --runtime) pkgs=("${runtime[@]}") ;;
  --build) pkgs=("${build[@]}") ;;
  "") pkgs=("${build[@]}" "${test[@]}") ;;
  *) echo "usage: $0 [--build|--runtime]" >&2; exit 2 ;;
esac

sudo=""
if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
# Skip apt entirely when everything is there already (CI runs on a machine that has them).
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if (( ${#missing[@]} )); then
  echo "installing: ${missing[*]}"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
