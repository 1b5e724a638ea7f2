// The second stage of the device-resident scan: per scanned cube of a tile, the candidate
// k-simplices whose vertices' sign codes admit a zero (the chains of corner sets, walked as
// in `shaders/scan.wgsl`), appended to `cands` for the third stage
// (`shaders/tile_certify.wgsl`), which decides them one per thread.
// CPU twin: `isomesh::trace::scan::tiles::twin_tile`.
// The host prepends `const D: u32`, `const K: u32`, `const KP1: u32` (K + 1),
// `const CORNERS: u32` (2^D), `const MASK: u32` (the bits a passing code holds) and
// `const BASE: u32` (as in tile_values.wgsl).
//
// tile: as in tile_values.wgsl, then the capacities of the records (`tile_certify.wgsl`) and
// of `cands`. The thread count is the number of cubes, whose digits run over the vertex
// counts less one. counters[1]: candidates (may exceed the capacity: the host then runs the
// tile again). cands: per candidate, the vertex index of its cube's base and its corner
// sets S_1 < .. < S_K (bit j: axis j; vertex c of the simplex is the base plus e_{S_c}).

@group(0) @binding(0) var<storage, read> tile: array<u32>;
@group(0) @binding(1) var<storage, read> codes: array<u32>;
@group(0) @binding(2) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read_write> cands: array<u32>;
@group(0) @binding(4) var<uniform> params: Params;

const FULL: u32 = CORNERS - 1u;

var<private> corner: array<u32, CORNERS>;
var<private> sup: array<u32, CORNERS>;

// Appends a passing chain.
fn emit(base: u32, sets: ptr<function, array<u32, KP1>>) {
    let slot = atomicAdd(&counters[1], 1u);
    if (slot < tile[2u * D + 1u]) {
        let at = slot * KP1;
        cands[at] = base;
        for (var c = 1u; c <= K; c++) {
            cands[at + c] = (*sets)[c];
        }
    }
}

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row_stride;
    if (i >= params.count) {
        return;
    }
    // The base vertex, and the vertex index step of each axis.
    var rest = i;
    var base = 0u;
    var stride = 1u;
    var step: array<u32, D>;
    for (var j = 0u; j < D; j++) {
        let n = tile[D + j];
        base += (rest % (n - 1u)) * stride;
        rest = rest / (n - 1u);
        step[j] = stride;
        stride *= n;
    }
    if ((codes[base] & BASE) == 0u) {
        return;
    }
    // The whole cube first, in registers: most cubes fail, and private arrays are slow on
    // some devices.
    var any = 0u;
    for (var s = 0u; s < CORNERS; s++) {
        var v = base;
        for (var j = 0u; j < D; j++) {
            v += select(0u, step[j], ((s >> j) & 1u) == 1u);
        }
        any |= codes[v];
    }
    if ((any & MASK) != MASK) {
        return;
    }
    for (var s = 0u; s < CORNERS; s++) {
        var v = base;
        for (var j = 0u; j < D; j++) {
            v += select(0u, step[j], ((s >> j) & 1u) == 1u);
        }
        corner[s] = v;
        sup[s] = codes[v];
    }
    for (var j = 0u; j < D; j++) {
        for (var s = 0u; s < CORNERS; s++) {
            if ((s & (1u << j)) == 0u) {
                sup[s] |= sup[s | (1u << j)];
            }
        }
    }
    // Depth first over chains; at depth i the chain holds sets[0..=i] and their codes' OR.
    var sets: array<u32, KP1>;
    var run: array<u32, KP1>;
    var add: array<u32, KP1>;
    sets[0] = 0u;
    run[0] = codes[corner[0]];
    var depth = 0u;
    var descend = true;
    loop {
        if (descend) {
            let s = sets[depth];
            let free = FULL & ~s;
            if (depth == K) {
                if ((run[K] & MASK) == MASK) {
                    emit(base, &sets);
                }
            } else if (((run[depth] | sup[s]) & MASK) == MASK
                && countOneBits(free) >= K - depth) {
                add[depth] = free & (~free + 1u);
                sets[depth + 1u] = s | add[depth];
                run[depth + 1u] = run[depth] | codes[corner[sets[depth + 1u]]];
                depth += 1u;
                continue;
            }
            descend = false;
        }
        // Back up to the deepest set that has a next superset, in increasing order.
        if (depth == 0u) {
            break;
        }
        depth -= 1u;
        let s = sets[depth];
        let free = FULL & ~s;
        if (add[depth] == free) {
            continue;
        }
        add[depth] = (add[depth] - free) & free;
        sets[depth + 1u] = s | add[depth];
        run[depth + 1u] = run[depth] | codes[corner[sets[depth + 1u]]];
        depth += 1u;
        descend = true;
    }
}
