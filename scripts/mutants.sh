#!/usr/bin/env bash
# Mutation testing of one module with cargo-mutants (`cargo install --locked cargo-mutants`).
#
#   scripts/mutants.sh FILE [SHARD] [extra cargo-mutants options]
#   scripts/mutants.sh src/cpu/solve.rs 0/20       # one twentieth of solve.rs's mutants
#
# Each mutant rebuilds the crate and runs the tests that guard FILE (the unit tests, plus
# the integration test named below when MUTANTS_FULL=1; only those targets are built). It
# runs in place, in this tree and its target/ (a copy would rebuild every dependency): do
# not edit the tree while it runs; an interrupt (Ctrl-C) puts the file back. The crate is
# built without the gpu and cli features, at opt-level 1 and without debug information: on
# 2 cores a mutant then rebuilds in about 20 s (about 36 s with line tables; opt-level 0
# rebuilds in 2 s but makes the unit tests up to 14x slower), and the unit tests run in
# about 35 s, so a whole module takes hours: use a shard (every n-th mutant) for a sample.
# Results go to mutants.out/. Exclusions, with their reasons: .cargo/mutants.toml.
set -euo pipefail
cd "$(dirname "$0")/.."
file=${1:?usage: scripts/mutants.sh src/PATH.rs [k/n] [cargo-mutants options]}
shift
shard=()
if [[ ${1:-} =~ ^[0-9]+/[0-9]+$ ]]; then
    shard=(--shard "$1")
    shift
fi
targets=(--cargo-arg=--lib)
if [[ ${MUTANTS_FULL:-0} == 1 ]]; then
    case "$file" in
        src/cpu/*) targets+=(--cargo-arg=--test=tracing) ;;
        src/triangulation/*) targets+=(--cargo-arg=--test=triangulation) ;;
        src/complex/*) targets+=(--cargo-arg=--test=complex) ;;
        src/expr/*) targets+=(--cargo-arg=--test=expressions) ;;
    esac
fi
exec cargo mutants --file "$file" "${shard[@]}" \
    --in-place --baseline=skip --timeout 300 --build-timeout 1200 \
    --sharding round-robin --cargo-arg=--no-default-features \
    --cargo-arg=--config=profile.test.package.isomesh.opt-level=1 \
    --cargo-arg=--config=profile.test.package.isomesh.debug=0 "${targets[@]}" "$@"
