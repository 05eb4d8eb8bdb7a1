#!/usr/bin/env bash
# Installs what umbra needs beyond Rust on a Debian/Ubuntu machine: a Vulkan driver (machines
# without a GPU get Mesa's software Vulkan device, lavapipe) and, for the viewer's tests, an X
# server without a screen (Xvfb) with the X libraries winit loads at run time. Idempotent.
set -euo pipefail

have_vulkan_icd() {
  local f
  for f in /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json /usr/local/share/vulkan/icd.d/*.json; do
    [ -e "$f" ] && return 0
  done
  return 1
}

have_x_libs() {
  local l
  for l in libX11-xcb.so.1 libXcursor.so.1 libXrandr.so.2 libXi.so.6 libxkbcommon-x11.so.0; do
    ldconfig -p 2>/dev/null | grep -q "$l" || return 1
  done
  return 0
}

pkgs=()
have_vulkan_icd || pkgs+=(mesa-vulkan-drivers libvulkan1)
command -v Xvfb >/dev/null 2>&1 || pkgs+=(xvfb xauth)
# The viewer's end-to-end test drives the window (xdotool) and captures the screen (xwd, netpbm).
command -v xdotool >/dev/null 2>&1 || pkgs+=(xdotool)
command -v xwd >/dev/null 2>&1 || pkgs+=(x11-apps)
command -v xwdtopnm >/dev/null 2>&1 || pkgs+=(netpbm)
have_x_libs || pkgs+=(libx11-xcb1 libxcursor1 libxrandr2 libxi6 libxkbcommon-x11-0)
if [ ${#pkgs[@]} -eq 0 ]; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "setup: missing ${pkgs[*]} and not root: install them (Debian) yourself" >&2
    exit 1
  fi
fi
echo "setup: installing ${pkgs[*]} ..." >&2
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${pkgs[@]}" >/dev/null
have_vulkan_icd || { echo "setup: mesa-vulkan-drivers installed but no Vulkan ICD file appeared" >&2; exit 1; }
