// The third stage of the device-resident scan: one thread per candidate that
// `shaders/tile_scan.wgsl` appended, the certified solve (`shaders/gauss_jordan.wgsl`,
// `shaders/certify.wgsl`) on the values `shaders/tile_values.wgsl` left on the device; the
// candidates it cannot prove outside are appended, compacted, to `out`.
// CPU twin: `isomesh::trace::scan::tiles::twin_tile`.
// The host prepends the solve prelude (`alias real`, N = K + 1, NN and the margins),
// gauss_jordan.wgsl, certify.wgsl, then `const D: u32`, `const K: u32` and
// `const UNKNOWN: u32` (as in tile_values.wgsl).
//
// tile and cands: as in tile_scan.wgsl. The thread count is the capacity of `cands`.
// counters[0]: records (may exceed the capacity: the host then runs the tile again).
// out: per record, the candidate's K + 1 words, then the verdict (CROSSED or UNCERTAIN).

@group(0) @binding(0) var<storage, read> tile: array<u32>;
@group(0) @binding(1) var<storage, read> values: array<real>;
@group(0) @binding(2) var<storage, read> codes: array<u32>;
@group(0) @binding(3) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read> cands: array<u32>;
@group(0) @binding(5) var<storage, read_write> out: array<u32>;
@group(0) @binding(6) var<uniform> params: Params;

const RECORD: u32 = K + 2u;

// The certified verdict on candidate i.
fn verdict(i: u32) -> u32 {
    var l: array<real, NN>;
    var e: array<real, NN>;
    var a: array<real, NN>;
    var inv: array<real, NN>;
    let base = cands[i * N];
    for (var j = 0u; j < N; j++) {
        // Vertex j: the base plus e_{S_j}.
        var v = base;
        if (j > 0u) {
            let s = cands[i * N + j];
            var stride = 1u;
            for (var t = 0u; t < D; t++) {
                v += select(0u, stride, ((s >> t) & 1u) == 1u);
                stride *= tile[D + t];
            }
        }
        if ((codes[v] & UNKNOWN) != 0u) {
            return UNCERTAIN;
        }
        l[j] = real(1);
        e[j] = real(0);
        for (var c = 0u; c < K; c++) {
            l[(c + 1u) * N + j] = values[(v * K + c) * 2u];
            e[(c + 1u) * N + j] = values[(v * K + c) * 2u + 1u];
        }
    }
    a = l;
    if (!gauss_jordan(&a, &inv)) {
        return UNCERTAIN;
    }
    return certify(&l, &e, &inv);
}

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row_stride;
    if (i >= params.count || i >= atomicLoad(&counters[1])) {
        return;
    }
    let v = verdict(i);
    if (v == OUTSIDE) {
        return;
    }
    let slot = atomicAdd(&counters[0], 1u);
    if (slot < tile[2u * D]) {
        let at = slot * RECORD;
        for (var c = 0u; c < N; c++) {
            out[at + c] = cands[i * N + c];
        }
        out[at + N] = v;
    }
}
