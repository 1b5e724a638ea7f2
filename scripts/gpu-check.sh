#!/usr/bin/env bash
# The hardware check, for a machine with a GPU (a few minutes): the adapter, the GPU test
# suites with ISOMESH_REQUIRE_GPU=1, the reference traces and scans of `isomesh bench` on both
# backends, and S identity between `--backend cpu` and `--backend gpu` (f64 and f32, scans
# with and without --device-values) on every preset and on hard cases: boxes 1e-13 inside
# and outside M, a manifold through lattice vertices. One summary at the end.
#
# Usage: scripts/gpu-check.sh [OUT_DIR]   (default gpu-check-out)
#   ISOMESH_BIN    the isomesh binary (default target/release/isomesh, built if missing)
#   ISOMESH_TESTS  a folder of prebuilt test binaries named gpu and certified (default: built
#                  here with cargo in release mode)
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-gpu-check-out}
mkdir -p "$OUT"
S="$OUT/summary.txt"
: >"$S"
log() { echo "$*" | tee -a "$S"; }
fails=0
fail() {
    fails=$((fails + 1))
    log "FAIL $*"
}

B=${ISOMESH_BIN:-target/release/isomesh}
if [ ! -x "$B" ]; then
    cargo build --release --locked -q || exit 1
fi
export ISOMESH_REQUIRE_GPU=1
log "== isomesh gpu-check $(date -u +%FT%TZ), $(nproc) CPU cores"
"$B" info >"$OUT/info.txt" 2>&1
head -3 "$OUT/info.txt" | tee -a "$S"

# The GPU test suites, run to their end with several threads.
T=${ISOMESH_TESTS:-}
if [ -z "$T" ]; then
    T="$OUT/tests"
    mkdir -p "$T"
    for t in gpu certified; do
        exe=$(cargo test --release --locked --test "$t" --no-run --message-format=json 2>/dev/null |
            sed -n 's/.*"executable":"\([^"]*\)".*/\1/p' | tail -1)
        [ -n "$exe" ] && cp "$exe" "$T/$t"
    done
fi
for t in "$T"/*; do
    [ -x "$t" ] || continue
    name=$(basename "$t")
    timeout 150 "$t" --test-threads 4 >"$OUT/test-$name.txt" 2>&1
    rc=$?
    result=$(grep -E '^test result' "$OUT/test-$name.txt" | tail -1)
    log "tests $name: rc $rc: $result"
    [ "$rc" = 0 ] || fail "tests $name (see test-$name.txt)"
    grep -E -A3 '^---- |panicked' "$OUT/test-$name.txt" | grep -v backtrace | head -20 >>"$S"
done

# S identity: the sample file (keys and points) of the GPU backend is the CPU backend's.
same() {
    local what=$1
    shift
    local a="$OUT/cpu.csv" b="$OUT/gpu.csv" cpu_args=()
    rm -f "$a" "$b"
    # The CPU reference takes no GPU flag.
    for arg in "$@"; do
        [ "$arg" = --device-values ] || cpu_args+=("$arg")
    done
    if ! timeout 60 "$B" trace "${cpu_args[@]}" --backend cpu --no-complex --out "$a" >/dev/null \
        2>"$OUT/err.txt"; then
        fail "$what: the CPU run failed: $(tail -1 "$OUT/err.txt")"
        return
    fi
    for mode in "--precision f64" "--precision f32"; do
        # shellcheck disable=SC2086
        if ! timeout 60 "$B" trace "$@" --backend gpu $mode --no-complex --out "$b" \
            >/dev/null 2>"$OUT/err.txt"; then
            fail "$what $mode: the GPU run failed: $(tail -1 "$OUT/err.txt")"
        elif ! cmp -s "$a" "$b"; then
            fail "$what $mode: S or its points differ"
        else
            checked=$((checked + 1))
        fi
    done
}
checked=0
for p in circle sphere torus chair flat-torus 3-torus complex-cosine bagel-klein cut-flat-torus; do
    same "trace $p" --preset "$p"
done
same "trace sphere in R^8" --preset sphere --param d=8 --param m=2 --param edge=0.3
same "scan torus" --preset torus --param edge=0.02 --exhaustive --box -1.5,1.5,-1.5,1.5,-0.5,0.5
same "scan torus, device values" --preset torus --param edge=0.02 --exhaustive \
    --box -1.5,1.5,-1.5,1.5,-0.5,0.5 --device-values
same "scan flat torus" --preset flat-torus --param edge=0.08 --exhaustive --box -1.1,1.1
same "scan flat torus, device values" --preset flat-torus --param edge=0.08 --exhaustive \
    --box -1.1,1.1 --device-values
for side in 0.9999999999999 1.0000000000001; do
    same "scan sphere, box $side" --preset sphere --param edge=0.05 --exhaustive --box "-$side,$side"
    same "scan sphere, box $side, device values" --preset sphere --param edge=0.05 --exhaustive \
        --box "-$side,$side" --device-values
done
same "scan circle through lattice vertices" --preset circle --param edge=0.05 --no-rotation \
    --exhaustive --box -1.2,1.2 --device-values
log "S identity: $checked GPU runs equal to the CPU's"

# The benchmarks: the oracle alone, then the reference traces and scans on both backends.
timeout 60 "$B" bench --backend gpu --k 1-8 --count 1000000 --repeats 3 --traces none \
    >"$OUT/oracle.txt" 2>&1 || fail "oracle bench"
grep -E '^\|' "$OUT/oracle.txt" >>"$S"
timeout 120 "$B" bench --backend gpu --k 0 --traces all,scans >"$OUT/traces.txt" 2>&1 ||
    fail "trace bench"
grep -E '^\|' "$OUT/traces.txt" >>"$S"

log "== $(date -u +%T): $fails failed"
[ "$fails" = 0 ]
