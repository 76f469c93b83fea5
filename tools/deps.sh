#!/usr/bin/env bash
# Installs the Debian 12 packages broadphase needs to build, test, plot and
# compare against its peers. Uses sudo when not run as root.
set -euo pipefail
packages=(
  build-essential cmake ninja-build git python3
  libcli11-dev nlohmann-json3-dev libgtest-dev libgmock-dev libbenchmark-dev
  python3-matplotlib python3-numpy python3-pil
  libbullet-dev libfcl-dev libode-dev libcgal-dev libembree-dev
  pybind11-dev python3-dev python3-scipy python3-sklearn python3-ase python3-rtree
  python3-pytest python3-mdanalysis python3-pykdtree libnanoflann-dev
  libopenmpi-dev openmpi-bin
  clang libclang-rt-14-dev
)
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "tools/deps.sh: installing ${missing[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
