// The certified intersection test: Gauss-Jordan (shaders/gauss_jordan.wgsl), then the
// a-posteriori certificate that the verdict holds for every labelling matrix within the
// given entry bounds of L. The twin of `isomesh::cpu::certificate::CertifiedSolver::solve`
// (same steps; the proof and its constants are documented there). The host prepends
// `alias real`, `const N: u32` (k + 1), `const NN: u32`, `const EPS: real`, the margins
// `GAMMA`, `GROW`, `TINY`, `MAX_CONTRACTION`, `BIG` and gauss_jordan.wgsl.
// input: per simplex, rows 1..N-1 of L (N values each, scaled by powers of two), then the
// bounds of the same entries. lambda: N values per simplex (x = R e_1). flags: 0 crossed,
// 1 outside, 2 uncertain.

struct Params {
    count: u32,
    row_stride: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<storage, read> input: array<real>;
@group(0) @binding(1) var<storage, read_write> lambda: array<real>;
@group(0) @binding(2) var<storage, read_write> flags: array<u32>;
@group(0) @binding(3) var<uniform> params: Params;

const CROSSED: u32 = 0u;
const OUTSIDE: u32 = 1u;
const UNCERTAIN: u32 = 2u;

// An upper bound of the exact value of a non-negative sum computed as x.
fn up(x: real) -> real {
    return x * GROW + TINY;
}

fn kron(i: u32, j: u32) -> real {
    return select(real(0), real(1), i == j);
}

fn certify(l: ptr<function, array<real, NN>>, e: ptr<function, array<real, NN>>,
           inv: ptr<function, array<real, NN>>) -> u32 {
    var rho: array<real, N>;
    for (var i = 0u; i < N; i++) {
        var acc = kron(i, 0u);
        var mag = kron(i, 0u);
        var eb = real(0);
        for (var j = 0u; j < N; j++) {
            let lij = (*l)[i * N + j];
            let xj = (*inv)[j * N];
            acc = acc - lij * xj;
            mag = mag + abs(lij) * abs(xj);
            eb = eb + (*e)[i * N + j] * abs(xj);
        }
        rho[i] = up(abs(acc) + GAMMA * mag + eb);
    }
    var kappa: array<real, N>;
    var z: array<real, N>;
    var zmax = real(0);
    for (var i = 0u; i < N; i++) {
        var row = real(0);
        for (var j = 0u; j < N; j++) {
            var acc = kron(i, j);
            var mag = kron(i, j);
            var eb = real(0);
            for (var t = 0u; t < N; t++) {
                let rit = (*inv)[i * N + t];
                let ltj = (*l)[t * N + j];
                acc = acc - rit * ltj;
                mag = mag + abs(rit) * abs(ltj);
                eb = eb + abs(rit) * (*e)[t * N + j];
            }
            row = row + up(abs(acc) + GAMMA * mag + eb);
        }
        kappa[i] = up(row);
        if (!(kappa[i] <= MAX_CONTRACTION)) {
            return UNCERTAIN;
        }
        var zi = real(0);
        for (var j = 0u; j < N; j++) {
            zi = zi + abs((*inv)[i * N + j]) * rho[j];
        }
        z[i] = up(zi);
        if (!(z[i] <= BIG)) {
            return UNCERTAIN;
        }
        if (z[i] > zmax) {
            zmax = z[i];
        }
    }
    let norm = up(zmax * real(2));
    var verdict = CROSSED;
    for (var i = 0u; i < N; i++) {
        let rad = up(z[i] + kappa[i] * norm);
        let xi = (*inv)[i * N];
        if (xi < real(0) - rad) {
            return OUTSIDE;
        }
        if (!(xi > rad)) {
            verdict = UNCERTAIN;
        }
    }
    return verdict;
}

@compute @workgroup_size(64)
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
