#!/usr/bin/env bash
# Mutation testing of one module with cargo-mutants (`cargo install --locked cargo-mutants`).
#
#   scripts/mutants.sh FILE [SHARD] [extra cargo-mutants options]
#   scripts/mutants.sh src/triangulation/key.rs          # every mutant of key.rs
#   scripts/mutants.sh src/triangulation/simplex.rs 0/4  # every fourth one
#
# Each mutant of FILE is built and checked against FILE's own unit tests (those under its
# module path, small cases written to be fast), with the crate built without the gpu and
# cli features, at opt-level 0 and without debug information: on 2 cores a mutant rebuilds
# in a few seconds. The score is then a lower bound for the whole suite (a mutant these
# tests miss may still be caught elsewhere). MUTANTS_TESTS=NAME runs the unit tests whose
# names hold NAME instead (e.g. cpu::solve::tests, without the slower adversarial batches
# of cpu::solve_adversarial); MUTANTS_TARGET=NAME[,NAME...] runs the integration tests
# tests/NAME.rs instead (e.g. expressions, for src/expr/parser.rs). MUTANTS_FULL=1 runs every unit test
# and the module's integration test, at opt-level 1 (about 20 s a rebuild and 1-2 minutes
# a mutant).
# A shard `k/n` takes every n-th mutant (round robin), a fixed sample spread over the file.
# It runs in place, in this tree and its target/: do not edit the tree while it runs; an
# interrupt (Ctrl-C) puts the file back. Results go to mutants.out/. Exclusions, with their
# reasons: .cargo/mutants.toml.
set -euo pipefail
cd "$(dirname "$0")/.."
# Mutants make property tests fail on purpose: their cases are not saved into tests/.
export PROPTEST_DISABLE_FAILURE_PERSISTENCE=1
file=${1:?usage: scripts/mutants.sh src/PATH.rs [k/n] [cargo-mutants options]}
shift
shard=()
if [[ ${1:-} =~ ^[0-9]+/[0-9]+$ ]]; then
    shard=(--shard "$1" --sharding round-robin)
    shift
fi
module=${file#src/}
module=${module%.rs}
module=${module%/mod}
module=${module//\//::}
# Targets to build and test (cargo args) and arguments for the test binaries.
targets=(--cargo-arg=--lib)
if [[ ${MUTANTS_FULL:-0} == 1 ]]; then
    opt=1
    timeout=300
    filter=()
    case "$file" in
        src/cpu/*) targets+=(--cargo-arg=--test=tracing) ;;
        src/triangulation/*) targets+=(--cargo-arg=--test=triangulation) ;;
        src/complex/*) targets+=(--cargo-arg=--test=complex) ;;
        src/expr/*) targets+=(--cargo-arg=--test=expressions) ;;
    esac
elif [[ -n ${MUTANTS_TARGET:-} ]]; then
    opt=0
    timeout=20
    targets=()
    for t in ${MUTANTS_TARGET//,/ }; do
        targets+=(--cargo-arg=--test="$t")
    done
    filter=()
else
    opt=0
    timeout=20
    filter=(-- "${MUTANTS_TESTS:-$module}")
fi
exec cargo mutants --file "$file" "${shard[@]}" \
    --in-place --baseline=skip --timeout $timeout --build-timeout 1200 \
    --cargo-arg=--no-default-features \
    --cargo-arg=--config=profile.test.package.isomesh.opt-level=$opt \
    --cargo-arg=--config=profile.test.package.isomesh.debug=0 "${targets[@]}" "$@" \
    -- "${filter[@]}"
