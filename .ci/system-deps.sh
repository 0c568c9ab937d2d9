#!/usr/bin/env bash
# Debian packages for rendering without a screen:
# - off-screen rendering: EGL with Mesa's software rasteriser (llvmpipe);
# - the interactive viewer (`cyber-rodent view`, MuJoCo's GLFW window) and its test: the Xvfb
#   virtual X server, GLX through Mesa (llvmpipe under Xvfb), and the X11 libraries GLFW loads.
# Idempotent: installs only what is missing. Needs root (or sudo) on a fresh machine.
set -euo pipefail
pkgs=(
  libegl1 libegl-mesa0 libgl1-mesa-dri libgles2
  xvfb libgl1 libglx-mesa0 libx11-6 libxrandr2 libxinerama1 libxcursor1 libxi6
)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "installing Debian packages for headless rendering and the viewer: ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
