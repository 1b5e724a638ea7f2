// The first stage of the device-resident scan (`shaders/tile_scan.wgsl` is the second): per
// lattice vertex of a tile, its position in R^d with a bound per coordinate (as
// `shaders/eval_certified.wgsl` computes it), whether the cube based at it is scanned, and
// certified values of f, which stay on the device with a sign code per vertex.
// CPU twin: `isomesh::trace::scan::tiles::twin_tile`.
// The host prepends what `shaders/eval_certified.wgsl` gets (`alias real`, `const DIM: u32`,
// `const OUTS: u32`, the CB_* constants, `LATTICE_FACTOR`, the device primitives,
// `shaders/certified.wgsl`, `fn isomesh_fc`), then `const BASE: u32` (the bit of scanned
// cubes) and `const UNKNOWN: u32` (the bit of vertices whose value is unknown).
//
// map: A (DIM x DIM, row-major), b (DIM), then the low and high ends of the box the bases of
// scanned cubes lie in (DIM each, rounded outward), then those of the box their corners lie in. tile: the lattice origin (DIM, i32 bits),
// then the vertex counts per axis (DIM); vertex i has digits in that mixed radix, axis 0 first.
// values: per vertex OUTS pairs (value, bound). codes: 0 outside the corners' box, else bit 2c unless component c
// is certainly > 0, bit 2c + 1 unless it is certainly < 0, UNKNOWN (and both bits) where a
// value is not known, BASE where the cube based there is scanned.
// counters[2]: vertices with an unknown value; counters[3]: vertices where f was evaluated.

@group(0) @binding(0) var<storage, read> map: array<real>;
@group(0) @binding(1) var<storage, read> tile: array<u32>;
@group(0) @binding(2) var<storage, read_write> values: array<real>;
@group(0) @binding(3) var<storage, read_write> codes: array<u32>;
@group(0) @binding(4) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(5) var<uniform> params: Params;

// Vertices of this workgroup where f was evaluated.
var<workgroup> evaluated: atomic<u32>;

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>,
        @builtin(local_invocation_index) lid: u32) {
    let i = gid.x + gid.y * params.row_stride;
    if (i < params.count && vertex(i)) {
        atomicAdd(&evaluated, 1u);
    }
    workgroupBarrier();
    if (lid == 0u) {
        let n = atomicLoad(&evaluated);
        if (n > 0u) {
            atomicAdd(&counters[3], n);
        }
    }
}

// Vertex i: its code, and its values unless it lies outside the far box; whether f was
// evaluated there.
fn vertex(i: u32) -> bool {
    // The lattice vertex; a vertex on the top layer of an axis only closes cubes.
    var u: array<real, DIM>;
    var rest = i;
    var top = false;
    for (var j = 0u; j < DIM; j++) {
        let n = tile[DIM + j];
        let digit = rest % n;
        rest = rest / n;
        u[j] = real(bitcast<i32>(tile[j]) + i32(digit));
        top = top || digit + 1u == n;
    }
    var x: array<Cv, DIM>;
    var base = !top;
    var far = false;
    for (var r = 0u; r < DIM; r++) {
        var acc = map[r * DIM] * u[0];
        var size = abs(acc);
        for (var c = 1u; c < DIM; c++) {
            let t = map[r * DIM + c] * u[c];
            acc = acc + t;
            size = size + abs(t);
        }
        let br = map[DIM * DIM + r];
        size = size + abs(br);
        x[r] = Cv(acc + br, size * LATTICE_FACTOR + CB_TINY);
        let lo = map[DIM * DIM + DIM + r];
        let hi = map[DIM * DIM + 2u * DIM + r];
        base = base && x[r].x + x[r].y >= lo && x[r].x - x[r].y <= hi;
        let flo = map[DIM * DIM + 3u * DIM + r];
        let fhi = map[DIM * DIM + 4u * DIM + r];
        far = far || !(x[r].x + x[r].y >= flo && x[r].x - x[r].y <= fhi);
    }
    // No scanned cube has a corner outside the far box: f is not needed there.
    if (far) {
        codes[i] = 0u;
        return false;
    }
    var y = isomesh_fc(x);
    var code = select(0u, BASE, base);
    for (var o = 0u; o < OUTS; o++) {
        let v = y[o].x;
        let e = y[o].y;
        values[(i * OUTS + o) * 2u] = v;
        values[(i * OUTS + o) * 2u + 1u] = e;
        if (e < CB_BIG && abs(v) < CB_BIG) {
            code |= select(0u, 1u, !(v > e)) << (2u * o);
            code |= select(0u, 1u, !(v < -e)) << (2u * o + 1u);
        } else {
            code |= (3u << (2u * o)) | UNKNOWN;
        }
    }
    if ((code & UNKNOWN) != 0u) {
        atomicAdd(&counters[2], 1u);
    }
    codes[i] = code;
    return true;
}
