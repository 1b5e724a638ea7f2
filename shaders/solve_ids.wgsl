// The intersection test on simplices given as vertex ids: solve.wgsl's test, with the rows
// of L gathered on the device from per-vertex values the host uploads once per vertex (K =
// N - 1 values a vertex, in `real`) and a bit per vertex that says the device holds its
// values within the bounds below (0 for a value that is not finite, or that `real` would
// hold only as a subnormal or not at all: those simplices are UNCERTAIN and decided on the
// CPU). Per simplex: the cheap filter (some component of one strict sign at every vertex:
// OUTSIDE, as `filter_verdict` in src/cpu/solve.rs), then each row scaled by a power of two
// near 1 / max |row| (`scaled_rows`), Gauss-Jordan and the certificate. Entry bounds:
// ROUND_UNIT |l| + ROUND_TINY covers the host's rounding to `real` and the device's product
// with the power of two (exact in f32 unless it underflows; a conforming device keeps only
// f32's precision in f64). CPU twin: `solve_ids_one` in src/gpu/oracle/emulated.rs.
// ids: N vertex ids per simplex. flags: 0 crossed, 1 outside, 2 uncertain.

@group(0) @binding(0) var<storage, read> ids: array<u32>;
@group(0) @binding(1) var<storage, read_write> flags: array<u32>;
@group(0) @binding(2) var<uniform> params: Params;
@group(0) @binding(3) var<storage, read> values: array<real>;
@group(0) @binding(4) var<storage, read> held: array<u32>;

// A power of two near 1 / v for v = 0 or |v| in [2^-126, 2^126] (the host holds back other
// values), 1 for 0: the exponent of f32(v), as `pow2_inverse` in src/linalg.rs takes f64's.
fn pow2_inverse(v: real) -> real {
    let e = i32((bitcast<u32>(f32(v)) >> 23u) & 0xffu);
    if (e == 0) {
        return real(1);
    }
    return real(bitcast<f32>(u32(max(254 - e, 1)) << 23u));
}

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * params.row_stride;
    if (s >= params.count) {
        return;
    }
    var at: array<u32, N>;
    for (var j = 0u; j < N; j++) {
        let id = ids[s * N + j];
        if (((held[id >> 5u] >> (id & 31u)) & 1u) == 0u) {
            flags[s] = UNCERTAIN;
            return;
        }
        at[j] = id * (N - 1u);
    }
    var l: array<real, NN>;
    var e: array<real, NN>;
    var a: array<real, NN>;
    var inv: array<real, NN>;
    for (var j = 0u; j < N; j++) {
        l[j] = real(1);
        e[j] = real(0);
    }
    for (var c = 0u; c + 1u < N; c++) {
        var big = real(0);
        var pos = 0u;
        var neg = 0u;
        for (var j = 0u; j < N; j++) {
            let x = values[at[j] + c];
            big = max(big, abs(x));
            pos += select(0u, 1u, x > real(0));
            neg += select(0u, 1u, x < real(0));
        }
        if (pos == N || neg == N) {
            flags[s] = OUTSIDE;
            return;
        }
        let scale = pow2_inverse(big);
        for (var j = 0u; j < N; j++) {
            let x = values[at[j] + c] * scale;
            let t = (c + 1u) * N + j;
            l[t] = x;
            e[t] = ROUND_UNIT * abs(x) + ROUND_TINY;
        }
    }
    a = l;
    if (!gauss_jordan(&a, &inv)) {
        flags[s] = UNCERTAIN;
        return;
    }
    flags[s] = certify(&l, &e, &inv);
}
