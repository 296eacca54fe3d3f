#!/usr/bin/env bash
# Installs what lumesh needs to build and test, from Debian 12's own packages.
# Runs apt-get directly as root, through sudo otherwise.
set -euo pipefail
packages=(
  build-essential cmake pkg-config   # toolchain
  libassimp-dev                      # mesh files: OBJ+MTL, PLY, OFF, STL, glTF
  libopenmesh-dev                    # geometric mesh topology
  libopenimageio-dev                 # EXR and PNG images
  libcjson-dev                       # JSON scene descriptions
  libembree-dev                      # CPU ray tracing: reference renderer, Embree sampler
)
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${packages[@]}"
