#!/usr/bin/env bash
# Thread scaling of the CPU trace and cell complex: medians of `elapsed_s` and `complex_s`
# over R runs per thread count, the thread counts taken in turn (1 2 1 2 ...), so that a
# drift of the machine's speed hits each alike.
#
#   scripts/scaling.sh [R] [THREADS...]      # defaults: 5 runs, threads 1 2
#   ISOMESH=target/release/isomesh CASES="sphere:0.01 3-torus:0.4" scripts/scaling.sh 5 1 2 8
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${ISOMESH:-target/release/isomesh}
runs=${1:-5}
shift || true
threads=("${@:-1 2}")
read -r -a threads <<<"${threads[*]}"
cases=${CASES:-"sphere:0.01 torus:0.02 3-torus:0.4"}
median() { sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }
field() { grep -o "\"$1\": [0-9.e+-]*" | head -1 | awk '{print $2}'; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for c in $cases; do
    preset=${c%%:*} edge=${c##*:}
    for _ in $(seq "$runs"); do
        for t in "${threads[@]}"; do
            "$bin" trace --preset "$preset" --edge "$edge" --backend cpu --threads "$t" \
                --report - 2>/dev/null >"$tmp/r.json"
            field elapsed_s <"$tmp/r.json" >>"$tmp/trace.$t"
            field complex_s <"$tmp/r.json" >>"$tmp/complex.$t"
        done
    done
    t1=$(median <"$tmp/trace.${threads[0]}") c1=$(median <"$tmp/complex.${threads[0]}")
    for t in "${threads[@]}"; do
        tt=$(median <"$tmp/trace.$t") ct=$(median <"$tmp/complex.$t")
        awk -v p="$preset" -v e="$edge" -v t="$t" -v tt="$tt" -v ct="$ct" -v t1="$t1" -v c1="$c1" \
            'BEGIN {printf "%-8s edge %-6s T=%-3s trace %.3f s (%.2fx)  complex %.3f s (%.2fx)\n", p, e, t, tt, t1/tt, ct, c1/ct}'
    done
    rm -f "$tmp"/trace.* "$tmp"/complex.*
done
