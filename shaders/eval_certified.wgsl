// Certified values of f at lattice vertices: each vertex u goes to R^d by x = A u + b, with a
// bound per coordinate against the CPU's coordinates (LATTICE_FACTOR times the sum of the
// terms' magnitudes), then through the certified f (`shaders/certified.wgsl`).
// CPU twin: `isomesh::cpu::eval_certified::eval_lattice_certified`.
// The host prepends: `alias real`, `const DIM: u32`, `const OUTS: u32`, the CB_* constants,
// `const LATTICE_FACTOR: real`, the device primitives, `shaders/certified.wgsl` and
// `fn isomesh_fc(x: array<Cv, DIM>) -> array<Cv, OUTS>`.
// input: A (DIM x DIM, row-major), then b (DIM), then count rows of DIM lattice coordinates.
// values: count rows of OUTS pairs (value, bound).

@group(0) @binding(0) var<storage, read> input: array<real>;
@group(0) @binding(1) var<storage, read_write> values: array<real>;
@group(0) @binding(2) var<uniform> params: Params;

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row_stride;
    if (i >= params.count) {
        return;
    }
    let head = DIM * DIM + DIM;
    let u = head + i * DIM;
    var x: array<Cv, DIM>;
    for (var r = 0u; r < DIM; r++) {
        var acc = input[r * DIM] * input[u];
        var size = abs(acc);
        for (var c = 1u; c < DIM; c++) {
            let t = input[r * DIM + c] * input[u + c];
            acc = acc + t;
            size = size + abs(t);
        }
        let br = input[DIM * DIM + r];
        size = size + abs(br);
        x[r] = Cv(acc + br, size * LATTICE_FACTOR + CB_TINY);
    }
    var y = isomesh_fc(x);
    for (var o = 0u; o < OUTS; o++) {
        values[(i * OUTS + o) * 2u] = y[o].x;
        values[(i * OUTS + o) * 2u + 1u] = y[o].y;
    }
}
