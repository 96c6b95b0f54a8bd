#!/usr/bin/env bash
# Installs every Debian package bistable-sweep needs. Idempotent; run as root on a fresh Debian bookworm machine.
# Nothing is downloaded from anywhere but Debian's package registry.
#   scripts/setup.sh            what the build and the main job (bistable run) need
#   scripts/setup.sh --tests    also the tests, benchmarks, Python module and deployment tests (README's test
#                               command; .ci/run)
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build ccache pkg-config git
  # numerics and utilities (dynamics/, engine/, identify/)
  libeigen3-dev libnanoflann-dev libxxhash-dev nlohmann-json3-dev libcli11-dev libtomlplusplus-dev libspdlog-dev
  libceres-dev libnlopt-dev libnlopt-cxx-dev
  # service and storage (proto/, server/, worker/, storage/): the embedded run is the coordinator and its workers
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  libsqlite3-dev libhdf5-dev libboost-dev libssl-dev openssl prometheus-cpp-dev
  # plots
  gnuplot-nox
)

# The tests, the benchmarks, the Python module and the deployment tests (README's test command; .ci/run). CMake
# builds each part when its packages are here (CMakeLists.txt: BISTABLE_TESTS, BISTABLE_BENCH, BISTABLE_PYTHON).
TEST_PACKAGES=(
  clang-format  # Format: the layout of every source file
  libgtest-dev libgmock-dev libbenchmark-dev python3-h5py python3-pil python3-numpy python3-scipy python3-yaml iproute2
  time  # GNU time: peak memory in bench/cost_curve.sh
  # Python: the `bistable` module (pybind11), maps in xarray (CF-1.10), its tests and examples
  python3-dev pybind11-dev python3-xarray python3-h5netcdf python3-netcdf4 python3-matplotlib python3-pytest udunits-bin
  # the example notebooks run by nbclient in ipykernel (Python.ExampleNotebooks); `pip install .` into a venv with
  # Debian's pip, setuptools and wheel (Python.PipInstallIntoVenv; docs/python.md)
  python3-nbclient python3-nbformat python3-ipykernel python3-venv python3-pip python3-setuptools python3-wheel
  # universal-ctags measures functions for Hygiene.FunctionAndFileLengths (scripts/function_lengths.sh)
  universal-ctags
  # the dashboard's browser test (tests/dashboard_test.py: headless chromium over the DevTools protocol)
  chromium python3-websocket
  # deployment tests (deploy/container: base image, image build and run; runc where crun cannot run)
  podman debootstrap runc uidmap fuse-overlayfs slirp4netns
  # deployment tests (deploy/slurm/test-cluster.sh: a Slurm cluster in network namespaces)
  slurmctld slurmd slurm-client munge procps util-linux
)

case "${1:-}" in
  "") ;;
  --tests) PACKAGES+=("${TEST_PACKAGES[@]}") ;;
  *) echo "usage: scripts/setup.sh [--tests]" >&2; exit 2 ;;
esac

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "setup: done"
