// The intersection test's fast path, the twin of `Decider::fast_path` in src/cpu/solve.rs:
// Gauss-Jordan inversion of the labelling matrix L = [1 .. 1; F_0 .. F_k] with partial
// pivoting (shaders/gauss_jordan.wgsl), lambda = first column of L^-1, and a first-order
// error bound per lambda_i. The host prepends: `alias real`, `const N: u32` (k + 1),
// `const NN: u32` (N * N), `const EPS: real` (machine epsilon of real), `const BOUND: real`
// (safety factor), `const BIG: real` (largest finite real), `const MAX_RELATIVE_BOUND: real`
// and gauss_jordan.wgsl.
// rows: per simplex, rows 1..N-1 of L (N values each), already scaled by powers of two.
// lambda: N values per simplex. flags: 0 crossed, 1 outside, 2 uncertain (decide elsewhere).

struct Params {
    count: u32,
    row_stride: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<storage, read> rows: array<real>;
@group(0) @binding(1) var<storage, read_write> lambda: array<real>;
@group(0) @binding(2) var<storage, read_write> flags: array<u32>;
@group(0) @binding(3) var<uniform> params: Params;

const CROSSED: u32 = 0u;
const OUTSIDE: u32 = 1u;
const UNCERTAIN: u32 = 2u;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * params.row_stride;
    if (s >= params.count) {
        return;
    }
    var l0: array<real, NN>;
    var a: array<real, NN>;
    var inv: array<real, NN>;
    let base = s * (N - 1u) * N;
    for (var j = 0u; j < N; j++) {
        l0[j] = real(1);
    }
    for (var r = 1u; r < N; r++) {
        for (var j = 0u; j < N; j++) {
            let v = rows[base + (r - 1u) * N + j];
            l0[r * N + j] = v;
        }
    }
    a = l0;
    if (!gauss_jordan(&a, &inv)) {
        flags[s] = UNCERTAIN;
        return;
    }
    // Row sums of |L|, then Skeel's condition numbers c_i = (|L^-1| |L| 1)_i: the error of
    // lambda_i is bounded by unit * c_i * max|lambda|, while unit * c_i is small.
    var abs_l: array<real, N>;
    for (var r = 0u; r < N; r++) {
        var acc = real(0);
        for (var t = 0u; t < N; t++) {
            acc = acc + abs(l0[r * N + t]);
        }
        abs_l[r] = acc;
    }
    let unit = BOUND * real(N) * EPS;
    var lmax = real(0);
    for (var i = 0u; i < N; i++) {
        let li = inv[i * N];
        lambda[s * N + i] = li;
        if (!(abs(li) <= BIG)) {
            flags[s] = UNCERTAIN;
            return;
        }
        lmax = max(lmax, abs(li));
    }
    var verdict = CROSSED;
    for (var i = 0u; i < N; i++) {
        var c = real(0);
        for (var j = 0u; j < N; j++) {
            c = c + abs(inv[i * N + j]) * abs_l[j];
        }
        if (!(unit * c <= MAX_RELATIVE_BOUND)) {
            flags[s] = UNCERTAIN;
            return;
        }
        let li = inv[i * N];
        let err = unit * c * lmax;
        if (li < -err) {
            flags[s] = OUTSIDE;
            return;
        }
        if (!(li > err)) {
            verdict = UNCERTAIN;
        }
    }
    flags[s] = verdict;
}
