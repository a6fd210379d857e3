#!/usr/bin/env bash
# Runs a program that must fail on bad input: exit code non-zero (and not a crash signal), a
# message on stderr matching PATTERN, and no file left at WATCH (or "-" for none).
# Usage: expect_error.sh PATTERN WATCH program args...
set -u
pattern="$1"; watch="$2"; shift 2
[ "$watch" != "-" ] && rm -f "$watch"
err=$(mktemp)
"$@" >/dev/null 2>"$err"
rc=$?
msg=$(cat "$err"); rm -f "$err"
if [ "$rc" -eq 0 ]; then echo "FAIL: exit code 0 for: $*"; exit 1; fi
if [ "$rc" -ge 128 ]; then echo "FAIL: crashed (exit $rc) for: $*"; echo "$msg"; exit 1; fi
if ! grep -Eq -- "$pattern" <<<"$msg"; then
    echo "FAIL: message does not match /$pattern/:"; echo "$msg"; exit 1
fi
if [ "$watch" != "-" ] && [ -e "$watch" ]; then echo "FAIL: $watch was left behind"; exit 1; fi
echo "ok: exit $rc: $msg"
