// Gauss-Jordan inversion with partial pivoting of the N x N row-major matrix `a` (destroyed)
// into `inv`; false when a pivot is at most N ulps of the largest entry. Shared by both solve
// shaders; CPU twin: `isomesh::cpu::certificate::gauss_jordan` (and, in f64, the fast path's
// `invert`). The host prepends `alias real`, `const N: u32`, `const NN: u32` (N * N) and
// `const EPS: real` (the machine epsilon, 2 u).

fn gauss_jordan(a: ptr<function, array<real, NN>>, inv: ptr<function, array<real, NN>>) -> bool {
    var scale = real(0);
    for (var t = 0u; t < NN; t++) {
        scale = max(scale, abs((*a)[t]));
        (*inv)[t] = real(0);
    }
    for (var i = 0u; i < N; i++) {
        (*inv)[i * N + i] = real(1);
    }
    let tiny = scale * EPS * real(N);
    for (var c = 0u; c < N; c++) {
        var p = c;
        for (var r = c + 1u; r < N; r++) {
            if (abs((*a)[r * N + c]) > abs((*a)[p * N + c])) {
                p = r;
            }
        }
        if (!(abs((*a)[p * N + c]) > tiny)) {
            return false;
        }
        if (p != c) {
            for (var t = 0u; t < N; t++) {
                let x = (*a)[p * N + t];
                (*a)[p * N + t] = (*a)[c * N + t];
                (*a)[c * N + t] = x;
                let y = (*inv)[p * N + t];
                (*inv)[p * N + t] = (*inv)[c * N + t];
                (*inv)[c * N + t] = y;
            }
        }
        let r_piv = real(1) / (*a)[c * N + c];
        for (var t = c; t < N; t++) {
            (*a)[c * N + t] = (*a)[c * N + t] * r_piv;
        }
        for (var t = 0u; t < N; t++) {
            (*inv)[c * N + t] = (*inv)[c * N + t] * r_piv;
        }
        for (var r = 0u; r < N; r++) {
            if (r == c) {
                continue;
            }
            let f = (*a)[r * N + c];
            if (f == real(0)) {
                continue;
            }
            for (var t = c; t < N; t++) {
                (*a)[r * N + t] = (*a)[r * N + t] - f * (*a)[c * N + t];
            }
            for (var t = 0u; t < N; t++) {
                (*inv)[r * N + t] = (*inv)[r * N + t] - f * (*inv)[c * N + t];
            }
        }
    }
    return true;
}
