// Evaluates f (or any emitted function) at a batch of points.
// The host prepends: `alias real`, `const DIM: u32`, `const OUTS: u32`, `alias Point` (DIM reals) and the
// function `fn isomesh_f(x: array<real, DIM>) -> array<real, OUTS>`.
// points: count rows of DIM values; values: count rows of OUTS values.

struct Params {
    count: u32,
    row_stride: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<storage, read> points: array<real>;
@group(0) @binding(1) var<storage, read_write> values: array<real>;
@group(0) @binding(2) var<uniform> params: Params;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row_stride;
    if (i >= params.count) {
        return;
    }
    var x: Point;
    for (var c = 0u; c < DIM; c++) {
        x[c] = points[i * DIM + c];
    }
    var y = isomesh_f(x);
    for (var o = 0u; o < OUTS; o++) {
        values[i * OUTS + o] = y[o];
    }
}
