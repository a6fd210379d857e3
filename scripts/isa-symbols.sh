#!/usr/bin/env bash
# Checks that the objects compiled for one instruction set (the sources named *_avx2.cpp and
# *_avx512.cpp, compiled with -mavx2 / -mavx512*) can share no code with any other object.
#
# An inline function or template instance that such an object emits out of line is a weak
# (COMDAT) symbol; when another object emits the same symbol, the linker keeps one copy for
# both, possibly the AVX-512 one, which then runs in the baseline code too and crashes on a
# processor without AVX-512. So an ISA object must define no weak symbol: what it instantiates
# has internal linkage (an anonymous namespace) or is a strong symbol of its own (its entry
# points). See docs/design/multires.md, "One object per instruction set".
#
#   scripts/isa-symbols.sh [DIR]         checks the objects under DIR (default build/release;
#                                        the test ig.isa_objects_share_no_code: build/*/ig)
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

check() {
    local dir="$1"
    local isa=() other=()
    while IFS= read -r -d '' f; do
        case "$(basename "$f")" in
            *_avx2.cpp.o | *_avx512.cpp.o | *_avx2.o | *_avx512.o) isa+=("$f") ;;
            *) other+=("$f") ;;
        esac
    done < <(find "$dir" -name '*.o' -type f -print0 | sort -z)
    if [ "${#isa[@]}" -eq 0 ]; then
        echo "isa-symbols: no *_avx2 / *_avx512 objects under $dir (build first)" >&2
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
    echo "isa-symbols self-test: shared weak symbol reported, internal linkage passed"
}

if [ "${1:-}" = "--self-test" ]; then
    selfTest
else
    check "${1:-build/release}"
fi
