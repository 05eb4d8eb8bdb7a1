#!/usr/bin/env bash
# Installs what umbra needs beyond Rust on a Debian/Ubuntu machine: a Vulkan driver.
# Machines without a GPU get Mesa's software Vulkan device (lavapipe). Idempotent.
set -euo pipefail

have_vulkan_icd() {
  local f
  for f in /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json /usr/local/share/vulkan/icd.d/*.json; do
    [ -e "$f" ] && return 0
  done
  return 1
}

if have_vulkan_icd; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "setup: no Vulkan driver found and not root: install mesa-vulkan-drivers (Debian) yourself" >&2
    exit 1
  fi
fi
echo "setup: installing Mesa's Vulkan drivers (lavapipe) ..." >&2
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
have_vulkan_icd || { echo "setup: mesa-vulkan-drivers installed but no Vulkan ICD file appeared" >&2; exit 1; }
