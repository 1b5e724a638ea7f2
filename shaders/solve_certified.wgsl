// The certified intersection test: Gauss-Jordan (shaders/gauss_jordan.wgsl), then the
// a-posteriori certificate (shaders/certify.wgsl) that the verdict holds for every labelling
// matrix within the given entry bounds of L. The twin of
// `isomesh::cpu::certificate::CertifiedSolver::solve`. The host prepends the prelude of
// `solve_prelude` (src/gpu/oracle/solve.rs), gauss_jordan.wgsl and certify.wgsl.
// input: per simplex, rows 1..N-1 of L (N values each, scaled by powers of two), then the
// bounds of the same entries. lambda: N values per simplex (x = R e_1). flags: 0 crossed,
// 1 outside, 2 uncertain.

@group(0) @binding(0) var<storage, read> input: array<real>;
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
    let base = s * 2u * (N - 1u) * N;
    let bounds = base + (N - 1u) * N;
    for (var j = 0u; j < N; j++) {
        l[j] = real(1);
        e[j] = real(0);
    }
    for (var t = N; t < NN; t++) {
        l[t] = input[base + t - N];
        e[t] = input[bounds + t - N];
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
