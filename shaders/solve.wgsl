// The intersection test's fast path, the twin of `Decider::fast_path` in src/cpu/solve.rs:
// Gauss-Jordan inversion of the labelling matrix L = [1 .. 1; F_0 .. F_k] with partial
// pivoting (shaders/gauss_jordan.wgsl), lambda = first column of L^-1, and the a-posteriori
// certificate (shaders/certify.wgsl) for every matrix within the rounding of the host's
// values to `real`: |l - l_host| <= ROUND_UNIT |l| + ROUND_TINY per entry (both 0 in f64,
// where the values arrive exact). The host prepends the prelude of `solve_prelude`
// (src/gpu/oracle/solve.rs) with ROUND_UNIT and ROUND_TINY, gauss_jordan.wgsl and
// certify.wgsl.
// rows: per simplex, rows 1..N-1 of L (N values each), already scaled by powers of two.
// lambda: N values per simplex. flags: 0 crossed, 1 outside, 2 uncertain (decide elsewhere).

@group(0) @binding(0) var<storage, read> rows: array<real>;
@group(0) @binding(1) var<storage, read_write> lambda: array<real>;
@group(0) @binding(2) var<storage, read_write> flags: array<u32>;
@group(0) @binding(3) var<uniform> params: Params;

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * params.row_stride;
    if (s >= params.count) {
        return;
    }
    var l: array<real, NN>;
    var e: array<real, NN>;
    var a: array<real, NN>;
    var inv: array<real, NN>;
    let base = s * (N - 1u) * N;
    for (var j = 0u; j < N; j++) {
        l[j] = real(1);
        e[j] = real(0);
    }
    for (var t = N; t < NN; t++) {
        let v = rows[base + t - N];
        l[t] = v;
        e[t] = ROUND_UNIT * abs(v) + ROUND_TINY;
    }
    a = l;
    if (!gauss_jordan(&a, &inv)) {
        for (var i = 0u; i < N; i++) {
            lambda[s * N + i] = real(0);
        }
        flags[s] = UNCERTAIN;
        return;
    }
    for (var i = 0u; i < N; i++) {
        lambda[s * N + i] = inv[i * N];
    }
    flags[s] = certify(&l, &e, &inv);
}
