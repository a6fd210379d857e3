#!/usr/bin/env bash
# scripts/device-tests.sh on a machine that cannot run the VM (here: VIG_DEVICE_QEMU names no
# program) must skip with exit 77 and say why, never pass.
# Usage: device_tests_skip.sh DEVICE_TESTS_SCRIPT BUILD_DIR
set -u
out=$(VIG_DEVICE_QEMU=/nonexistent/qemu "$1" "$2" 2>&1)
rc=$?
echo "$out"
[ "$rc" -eq 77 ] || { echo "FAIL: exit $rc, expected 77 (skipped)"; exit 1; }
grep -q 'SKIP: VIG_DEVICE_QEMU=/nonexistent/qemu: no such program' <<<"$out" ||
    { echo "FAIL: no SKIP message naming the missing program"; exit 1; }
echo "ok: skipped with exit 77"
