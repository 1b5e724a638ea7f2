// Evaluates f at lattice vertices: each vertex u (integer coordinates, stored as reals) goes to
// R^d by the triangulation's affine map x = A u + b inside the shader, then through f.
// CPU twin: `isomesh::cpu::eval_vertices::eval_lattice` (the same operations in the same order).
// The host prepends: `alias real`, `const DIM: u32`, `const OUTS: u32`, `alias Point` (DIM reals)
// and the function `fn isomesh_f(x: Point) -> array<real, OUTS>`.
// input: A (DIM x DIM, row-major), then b (DIM), then count rows of DIM lattice coordinates.
// values: count rows of OUTS values.

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
    var x: Point;
    for (var r = 0u; r < DIM; r++) {
        var acc = input[r * DIM] * input[u];
        for (var c = 1u; c < DIM; c++) {
            acc = acc + input[r * DIM + c] * input[u + c];
        }
        x[r] = acc + input[DIM * DIM + r];
    }
    var y = isomesh_f(x);
    for (var o = 0u; o < OUTS; o++) {
        values[i * OUTS + o] = y[o];
    }
}
