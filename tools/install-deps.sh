#!/usr/bin/env bash
# Installs the Debian packages magvine needs to build, test and plot — and nothing else.
# Idempotent: when every package is already installed it changes nothing and does not touch apt.
# Runs as root, or through sudo otherwise. `apt-get update` runs only when a package has no install candidate.
#
# Usage: tools/install-deps.sh [--check]
#   --check   only report missing packages (exit 1 if any), install nothing.
set -euo pipefail

# Why each package is here (README "Dependencies" repeats this):
packages=(
  build-essential cmake pkg-config     # compiler, build system, .pc lookups (Bullet's float64 libraries)
  libeigen3-dev                        # linear algebra everywhere (MPL-2.0)
  liblbfgspp-dev                       # design: bounded L-BFGS-B, header-only (MIT)
  libbullet-dev                        # reference for the edge bends in tests; *-float64 libraries (zlib licence)
  libassimp-dev                        # mesh import: STL/OBJ/PLY/glTF/OFF (BSD-3)
  libyaml-cpp-dev                      # scene and magnet files (MIT)
  nlohmann-json3-dev                   # JSON reports (MIT)
  libcli11-dev                         # command line (BSD-3)
  libopencv-dev                        # optional render module: images and video (Apache-2.0)
  libgomp1                             # OpenMP runtime of GCC for the MPM solver (GCC runtime library exception)
  libembree-dev                        # BVH builder of the collision world; render: CPU ray casting (Apache-2.0)
  libnifti2-dev                        # optional ct module: NIfTI-1/2 label maps, gzip (public domain)
  libopenvdb-dev libboost-iostreams-dev  # optional ct module: level sets and surfaces from label maps (MPL-2.0;
                                       # Boost's iostreams only because OpenVDB's CMake module asks for it, BSL-1.0)
  libgtest-dev libgmock-dev            # tests (BSD-3)
  libbenchmark-dev                     # benchmarks (Apache-2.0)
  python3 python3-numpy python3-matplotlib  # plots written by tools/*.py (PSF/BSD)
  pybind11-dev python3-dev python3-pytest python3-yaml  # optional python module: import magvine, its tests (BSD-3, PSF, MIT, MIT)
  slurm-wlm munge                      # the one-node cluster test only: programs it starts, never linked (GPL-2.0+)
)

check_only=0
[[ "${1:-}" == "--check" ]] && check_only=1

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "install-deps: missing: ${missing[*]}"
[[ $check_only -eq 1 ]] && exit 1

if [[ $EUID -eq 0 ]]; then
  sudo=()
elif command -v sudo >/dev/null 2>&1; then
  sudo=(sudo)
else
  echo "install-deps: not root and sudo is not available; install as root: apt-get install ${missing[*]}" >&2
  exit 1
fi

export DEBIAN_FRONTEND=noninteractive
# Refresh the package lists only when one of the missing packages has no candidate (fresh image, stale lists).
needs_update=0
for p in "${missing[@]}"; do
  cand=$(apt-cache policy "$p" 2>/dev/null | awk '/Candidate:/ {print $2}')
  if [[ -z "$cand" || "$cand" == "(none)" ]]; then needs_update=1; break; fi
done
if [[ $needs_update -eq 1 ]]; then
  "${sudo[@]}" apt-get update -q
fi
if ! "${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"; then
  # Stale package lists (files moved on the mirror): refresh once and retry.
  [[ $needs_update -eq 1 ]] && exit 1
  "${sudo[@]}" apt-get update -q
  "${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
echo "install-deps: installed ${#missing[@]} packages"
