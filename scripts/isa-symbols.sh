#!/usr/bin/env bash
# Checks that the objects compiled for one instruction set can share no code with any other
# object: the sources named *_avx2.cpp and *_avx512.cpp (compiled with -mavx2 / -mavx512*, or
# with those targets as function attributes), and every object whose compile command (the
# build's compile_commands.json, in DIR or a folder above it) carries an instruction-set flag
# (-mavx*, -msse3 and later, -mfma, -mbmi*, -mf16c, -march=, -mtune= aside).
#
# An inline function or template instance that such an object emits out of line is a weak
# (COMDAT) symbol; when another object emits the same symbol, the linker keeps one copy for
# both, possibly the AVX-512 one, which then runs in the baseline code too and crashes on a
# processor without AVX-512. So an ISA object must define no weak symbol: what it instantiates
# has internal linkage (an anonymous namespace) or is a strong symbol of its own (its entry
# points). See docs/design/multires.md, "One object per instruction set".
#
#   scripts/isa-symbols.sh [DIR]         checks the objects under DIR (default build/release;
#                                        the tests ig.isa_objects_share_no_code and
#                                        prp.isa_objects_share_no_code: build/*/ig, build/*/prp)
#   scripts/isa-symbols.sh --self-test   compiles a shared inline function into a baseline and
#                                        an AVX-512 object and checks that the check fails
# Prints what it found; exits 1 when an ISA object breaks the rule, 2 when it finds none.
set -euo pipefail

# Global symbols each object defines, one "object<TAB>type<TAB>mangled name" a line.
defined() {
    local obj
    for obj in "$@"; do
        nm --defined-only -P "$obj" 2>/dev/null |
            awk -v o="$obj" '$2 ~ /^[A-Zuvw]$/ { print o "\t" $2 "\t" $1 }'
    done
}

# The objects (absolute paths, one a line) that the compile_commands.json nearest above DIR
# compiles with an instruction-set flag; nothing when there is none.
flaggedObjects() {
    local dir db=""
    dir="$(cd "$1" && pwd)"
    while [ -n "$dir" ]; do
        if [ -f "$dir/compile_commands.json" ]; then
            db="$dir/compile_commands.json"
            break
        fi
        [ "$dir" = / ] && break
        dir="$(dirname "$dir")"
    done
    [ -n "$db" ] || return 0
    python3 - "$db" <<'PY'
import json, os, re, shlex, sys
isa = re.compile(r"^-m(avx|sse3|ssse3|sse4|fma|bmi|f16c|lzcnt|popcnt|arch=)")
for entry in json.load(open(sys.argv[1])):
    args = entry.get("arguments") or shlex.split(entry["command"])
    if not any(isa.match(a) for a in args) or "-o" not in args:
        continue
    obj = args[args.index("-o") + 1]
    print(os.path.realpath(os.path.join(entry["directory"], obj)))
PY
}

check() {
    local dir="$1"
    local isa=() other=() flagged
    flagged="$(flaggedObjects "$dir")"
    while IFS= read -r -d '' f; do
        case "$(basename "$f")" in
            *_avx2.cpp.o | *_avx512.cpp.o | *_avx2.o | *_avx512.o) isa+=("$f") ;;
            *)
                if [ -n "$flagged" ] && grep -qxF "$(realpath "$f")" <<<"$flagged"; then
                    isa+=("$f")
                else
                    other+=("$f")
                fi
                ;;
        esac
    done < <(find "$dir" -name '*.o' -type f -print0 | sort -z)
    if [ "${#isa[@]}" -eq 0 ]; then
        echo "isa-symbols: no *_avx2 / *_avx512 or instruction-set-flagged objects under $dir" \
            "(build first)" >&2
        return 2
    fi
    local work
    work="$(mktemp -d)"
    defined "${isa[@]}" >"$work/isa"
    defined "${other[@]+"${other[@]}"}" >"$work/other"
    local bad=0 obj type sym where
    while IFS=$'\t' read -r obj type sym; do
        case "$type" in
            W | V | w | v | u)
                # The personality routine's reference is data, the same in every object.
                [ "$sym" = "DW.ref.__gxx_personality_v0" ] && continue
                where="$(awk -F'\t' -v s="$sym" -v o="$obj" '$3 == s && $1 != o { print $1 }' \
                    "$work/isa" "$work/other" | sort -u | tr '\n' ' ')"
                echo "isa-symbols: $(basename "$obj") defines the weak symbol" \
                    "$(echo "$sym" | c++filt)${where:+, also defined in $where}"
                bad=1
                ;;
        esac
    done <"$work/isa"
    rm -rf "$work"
    echo "isa-symbols: ${#isa[@]} ISA objects checked against ${#other[@]} others:" \
        "$([ "$bad" -eq 0 ] && echo "no weak symbol" || echo "WEAK SYMBOLS, the linker may share them")"
    return "$bad"
}

selfTest() {
    local work cxx="${CXX:-c++}"
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' RETURN
    # The same inline function in a baseline object and an AVX-512 one, not inlined (-O0):
    # both emit it as a weak symbol, which the check must report.
    cat >"$work/shared.hpp" <<'EOF'
inline double twice(double x) { return 2.0 * x; }
EOF
    printf '#include "shared.hpp"\ndouble base(double x) { return twice(x); }\n' >"$work/base.cpp"
    printf '#include "shared.hpp"\nnamespace ig::rows_avx512 { double wide(double x) { return twice(x); } }\n' \
        >"$work/rows_avx512.cpp"
    "$cxx" -O0 -c "$work/base.cpp" -o "$work/base.o"
    "$cxx" -O0 -mavx512f -c "$work/rows_avx512.cpp" -o "$work/rows_avx512.o"
    local out
    if out="$(check "$work")"; then
        echo "isa-symbols self-test: a shared inline function was not reported:"
        echo "$out"
        return 1
    fi
    if ! echo "$out" | grep -q "weak symbol twice(double), also defined in .*base.o"; then
        echo "isa-symbols self-test: the report does not name the shared function:"
        echo "$out"
        return 1
    fi
    # The same with the ISA object's copy given internal linkage: clean.
    printf 'namespace {\n#include "shared.hpp"\n}\nnamespace ig::rows_avx512 { double wide(double x) { return twice(x); } }\n' \
        >"$work/rows_avx512.cpp"
    "$cxx" -O0 -mavx512f -c "$work/rows_avx512.cpp" -o "$work/rows_avx512.o"
    if ! out="$(check "$work")"; then
        echo "isa-symbols self-test: internal linkage was reported:"
        echo "$out"
        return 1
    fi
    # An object of any name compiled with an instruction-set flag (compile_commands.json): its
    # shared inline function is reported too.
    rm -f "$work/rows_avx512.o"
    printf '#include "shared.hpp"\ndouble wide(double x) { return twice(x); }\n' >"$work/wide.cpp"
    "$cxx" -O0 -mavx2 -c "$work/wide.cpp" -o "$work/wide.o"
    printf '[{"directory": "%s", "command": "c++ -O0 -mavx2 -c wide.cpp -o wide.o", "file": "wide.cpp"}]\n' \
        "$work" >"$work/compile_commands.json"
    if out="$(check "$work")" || ! echo "$out" | grep -q "wide.o defines the weak symbol twice(double)"; then
        echo "isa-symbols self-test: an object compiled with -mavx2 was not checked:"
        echo "$out"
        return 1
    fi
    echo "isa-symbols self-test: shared weak symbol reported (by name and by flag)," \
        "internal linkage passed"
}

if [ "${1:-}" = "--self-test" ]; then
    selfTest
else
    check "${1:-build/release}"
fi
