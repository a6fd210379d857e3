#!/usr/bin/env bash
# Runs the output layer against real kernel drivers in a small virtual machine: Debian's own
# kernel (not the host's), booted by qemu with an initramfs holding busybox, the product's
# programs and tests, v4l-utils and the gpiod tools. Inside: vivid (a V4L2 output looped back
# to a capture node) and vig_gpio_sim (tests/io/device/vig_gpio_sim.c, a simulated GPIO chip
# with edge interrupts, built here for that kernel). See docs/design/io.md, "Device tests".
#
# usage: scripts/device-tests.sh [BUILD_DIR]     (default: build/release)
# Exit status: 0 every check passed, 1 a check failed or the VM gave no verdict, 77 skipped
# (no qemu, no packages, no Debian archive: never counted as a pass).
# VIG_DEVICE_CACHE: where packages and the built module are kept (default ~/.cache/vig-device).
# VIG_DEVICE_ACCEL: tcg (default) or kvm. VIG_DEVICE_TIMEOUT: seconds the VM may run (420).
# VIG_DEVICE_QEMU: the qemu program (default qemu-system-x86_64, installed when missing).
set -euo pipefail

skip() {
    echo "device-tests: SKIP: $*" >&2
    exit 77
}
fail() {
    echo "device-tests: FAIL: $*" >&2
    exit 1
}

root=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-$root/build/release}" 2>/dev/null && pwd) ||
    fail "build folder '${1:-$root/build/release}' does not exist (build io-check, flythrough, io_tests first)"
cache=${VIG_DEVICE_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/vig-device}
started=$(date +%s)

qemu=${VIG_DEVICE_QEMU:-qemu-system-x86_64}
if [ -n "${VIG_DEVICE_QEMU:-}" ] && ! command -v "$qemu" >/dev/null; then
    skip "VIG_DEVICE_QEMU=$qemu: no such program"
fi

programs=("$build/bin/io-check" "$build/tests/io_tests")
[ -x "$build/bin/flythrough" ] && programs+=("$build/bin/flythrough")
for p in "${programs[@]}"; do
    [ -x "$p" ] || fail "$p is missing: build the targets io-check, flythrough and io_tests"
done

# --- host tools: Debian packages, installed only when missing (needs root and the archive) ---
[ "$(uname -m)" = x86_64 ] || skip "needs an x86-64 host (qemu-system-x86_64 runs Debian's amd64 kernel)"
if ! command -v apt-cache >/dev/null || ! command -v dpkg-query >/dev/null; then
    skip "not a Debian system: no apt-cache to find the kernel package"
fi
kernel_pkg=$(apt-cache depends linux-image-amd64 2>/dev/null |
    awk '/Depends: linux-image-[0-9]/ {print $2; exit}') || true
[ -n "$kernel_pkg" ] || skip "apt-cache knows no linux-image-amd64 (run apt-get update)"
kver=${kernel_pkg#linux-image-}
tools=(qemu-system-x86 busybox-static v4l-utils gpiod cpio kmod "linux-headers-$kver")
missing=()
for p in "${tools[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    [ "$(id -u)" -eq 0 ] || skip "missing packages ${missing[*]} and not root to install them"
    echo "device-tests: installing ${missing[*]}"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" \
        >/dev/null 2>&1 || skip "cannot install ${missing[*]} (no Debian archive reachable?)"
fi
command -v "$qemu" >/dev/null || skip "no $qemu"

# --- the guest kernel: downloaded and unpacked in the cache, the host's packages untouched ---
kdir="$cache/$kver"
if [ ! -f "$kdir/ok" ]; then
    rm -rf "$kdir" && mkdir -p "$kdir"
    (cd "$kdir" && apt-get download "$kernel_pkg" >/dev/null 2>&1) ||
        skip "cannot download $kernel_pkg"
    dpkg -x "$kdir"/"$kernel_pkg"_*.deb "$kdir/root"
    rm -f "$kdir"/*.deb
    depmod -b "$kdir/root" "$kver"
    touch "$kdir/ok"
fi
vmlinuz="$kdir/root/boot/vmlinuz-$kver"
mods="$kdir/root/lib/modules/$kver"

# --- the simulated GPIO chip, built for that kernel ---
kbuild="/usr/src/linux-headers-$kver"
[ -d "$kbuild" ] || skip "no $kbuild"
modsrc="$root/tests/io/device"
modbuild="$cache/module-$kver"
if [ ! -f "$modbuild/vig_gpio_sim.ko" ] || [ "$modsrc/vig_gpio_sim.c" -nt "$modbuild/vig_gpio_sim.ko" ]; then
    rm -rf "$modbuild" && mkdir -p "$modbuild"
    cp "$modsrc/vig_gpio_sim.c" "$modsrc/Kbuild" "$modbuild/"
    make -s -C "$kbuild" M="$modbuild" modules >"$modbuild/build.log" 2>&1 ||
        { cat "$modbuild/build.log" >&2; fail "vig_gpio_sim did not build against $kbuild"; }
fi

# --- the initramfs ---
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
ir="$work/root"
mkdir -p "$ir"/{bin,sbin,dev,proc,sys,tmp,run,etc,vig,"lib/modules/$kver"}
cp /bin/busybox "$ir/bin/busybox"
ln -s busybox "$ir/bin/sh"  # /init installs the other applets
# Modules: vivid and what it needs, in load order, from the kernel package's own depmod.
: >"$ir/vig/modules"
while read -r _ ko _; do
    rel=${ko#"$mods/"}
    mkdir -p "$ir/lib/modules/$kver/$(dirname "$rel")"
    cp "$ko" "$ir/lib/modules/$kver/$rel"
    echo "/lib/modules/$kver/$rel" >>"$ir/vig/modules"
done < <(modprobe -S "$kver" -d "$kdir/root" --show-depends vivid | grep '^insmod')
cp "$modbuild/vig_gpio_sim.ko" "$ir/vig/"
# Programs and every shared library they load.
guest_programs=("${programs[@]}" "$(command -v v4l2-ctl)" "$(command -v v4l2-compliance)"
    "$(command -v gpioinfo)" "$(command -v gpiomon)" "$(command -v gpioget)")
for p in "${guest_programs[@]}"; do
    cp "$p" "$ir/vig/"
    ldd "$p" | awk '/=> \// {print $3} /^[ \t]*\// {print $1}' | while read -r lib; do
        [ -e "$ir$lib" ] && continue
        mkdir -p "$ir$(dirname "$lib")"
        cp -L "$lib" "$ir$lib"
    done
done
cp "$modsrc/guest-init.sh" "$ir/init"
chmod +x "$ir/init"
(cd "$ir" && find . | cpio -o -H newc --quiet | gzip -1 >"$work/initramfs.gz")

# --- boot ---
# TCG by default: a nested KVM guest under a Firecracker host hung at boot here, while TCG is
# the same everywhere. VIG_DEVICE_ACCEL=kvm asks for KVM.
accel=${VIG_DEVICE_ACCEL:-tcg}
if [ "$accel" = kvm ] && ! { [ -r /dev/kvm ] && [ -w /dev/kvm ]; }; then
    skip "VIG_DEVICE_ACCEL=kvm but /dev/kvm cannot be opened"
fi
limit=${VIG_DEVICE_TIMEOUT:-420}
cpu=max
# host, less the one MSR a nested hypervisor (Firecracker) refuses to set
[ "$accel" = kvm ] && cpu=host,-arch-capabilities
log="$work/console.log"
# no_timer_check: under an emulated CPU on a loaded host the kernel's IO-APIC timer check can
# time out and panic at boot ("IO-APIC + timer doesn't work!"); the timer works all the same.
# A guest that still dies before its /init started is booted once more, and says so.
for attempt in 1 2; do
    echo "device-tests: booting Debian $kver under qemu ($accel)"
    set +e
    timeout "$limit" "$qemu" -accel "$accel" -cpu "$cpu" -smp 2 -m 1024 -nographic -no-reboot \
        -kernel "$vmlinuz" -initrd "$work/initramfs.gz" \
        -append "console=ttyS0 panic=-1 loglevel=4 no_timer_check" </dev/null >"$log" 2>&1
    qemu_rc=$?
    set -e
    grep -q 'VIG-BEGIN' "$log" || [ $qemu_rc -eq 124 ] && break
    [ $attempt -eq 1 ] && { tr -d '\r' <"$log" | grep -m3 -i 'panic' || true; } &&
        echo "device-tests: the guest died before its checks started; booting it again"
done
cp "$log" "$cache/console.log"
tr -d '\r' <"$log" | sed -n '/VIG-BEGIN/,/^VIG-END/p' | grep -v 'VIG-\(BEGIN\|END\)' || true
verdict=$(tr -d '\r' <"$log" | grep '^VIG-RESULT' | tail -1) || true
elapsed=$(($(date +%s) - started))
if [ -z "$verdict" ]; then
    tail -40 "$log" >&2
    echo "device-tests: the whole console is in $cache/console.log" >&2
    [ "$qemu_rc" -eq 124 ] && fail "the VM did not finish in $limit s"
    fail "the VM gave no verdict (qemu exit $qemu_rc)"
fi
echo "device-tests: ${verdict#VIG-RESULT: } ($elapsed s, $accel)"
case "$verdict" in
    *" 0 failed"*) exit 0 ;;
    *) exit 1 ;;
esac
