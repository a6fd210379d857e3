#!/usr/bin/env bash
# Installs the Debian 12 packages the build and the tests need (python3 checks the results page,
# gnuplot-nox draws the plots), when any is missing (needs root or sudo).
set -euo pipefail
packages=(build-essential cmake ninja-build pkg-config libeigen3-dev libglm-dev libgpiod-dev
          libtbb-dev libgtest-dev libgmock-dev libbenchmark-dev libpng-dev libjpeg-dev libgdal-dev
          nlohmann-json3-dev libcli11-dev
          zlib1g-dev liblz4-dev libzstd-dev  # terrain database: CRC-32, tile codecs
          python3 gnuplot-nox
          tshark  # tshark: tests/cli/cigi_tshark.sh reads our CIGI packets independently
          ffmpeg  # ffprobe: tests/cli/hostile.sh reads the Y4M written through renderer faults
          # scripts/device-tests.sh (ctest device.vm): the VM, its shell and the tools run in it;
          # it adds the kernel headers for the guest kernel it downloads
          qemu-system-x86 busybox-static v4l-utils gpiod cpio kmod)
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
    exit 0
fi
echo "setup: installing ${missing[*]}"
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "setup: need root or sudo to install packages" >&2; exit 1; }
    sudo_cmd=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
