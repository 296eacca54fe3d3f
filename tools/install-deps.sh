#!/usr/bin/env bash
# Installs what lumesh needs to build and test, from Debian 12's own packages.
# Runs apt-get directly as root, through sudo otherwise.
set -euo pipefail
packages=(
  build-essential cmake pkg-config   # toolchain
  libassimp-dev                      # mesh files: OBJ+MTL, PLY, OFF, STL, glTF
  libopenmesh-dev                    # geometric mesh topology
  libopenimageio-dev                 # EXR and PNG images
  libcjson-dev                       # JSON scene descriptions and statistics
  libexpat1-dev                      # Mitsuba XML scenes
  libstb-dev                         # stb_easy_font: text in plots and the viewer's HUD (header only)
  libembree-dev                      # CPU ray tracing: reference renderer, Embree sampler
  python3-glad                       # generates the OpenGL 4.5 loader at build time (glad 2, MX)
  python3                            # the layers test (tests/layers.py)
  libegl-dev libosmesa6-dev          # headless GL for the GL sampler: EGL, OSMesa
  libegl-mesa0 libgl1-mesa-dri       # Mesa's EGL vendor and llvmpipe (run time; no GPU needed)
  libgl-dev                          # GL headers (osmesa.h includes GL/gl.h); libGL is not linked
  libglfw3-dev                       # lumesh view: the window and its OpenGL 4.5 context
  xvfb xauth                         # tests of lumesh view without a display (xvfb-run)
)
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${packages[@]}"
