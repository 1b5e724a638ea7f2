// The a-posteriori certificate of a verdict: with R = `inv` an approximate inverse of the
// labelling matrix `l` and `e` bounds on the distance of l's entries to those of the matrix
// it stands for, CROSSED or OUTSIDE when that holds for every matrix within the bounds, else
// UNCERTAIN. Shared by both solve shaders; CPU twin: `isomesh::cpu::certificate::certify`
// (the proof and its constants are documented there). The host prepends `alias real`,
// `const N: u32`, `const NN: u32` and the margins `GAMMA`, `GROW`, `TINY`,
// `MAX_CONTRACTION`, `BIG`.

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
    // kappa_i >= row sums of |I - R L*|: of |fl(I - R L)| entry by entry, and of the other
    // two terms through the row sums s = |L| 1 and se = E 1 (the row sum of |R| |L| is
    // |R| s), both rounded up. z >= |R| rho.
    var s: array<real, N>;
    var se: array<real, N>;
    for (var t = 0u; t < N; t++) {
        var st = real(0);
        var sum_e = real(0);
        for (var j = 0u; j < N; j++) {
            st = st + abs((*l)[t * N + j]);
            sum_e = sum_e + (*e)[t * N + j];
        }
        s[t] = up(st);
        se[t] = up(sum_e);
    }
    var kappa: array<real, N>;
    var z: array<real, N>;
    var zmax = real(0);
    for (var i = 0u; i < N; i++) {
        var computed = real(0);
        for (var j = 0u; j < N; j++) {
            var acc = kron(i, j);
            for (var t = 0u; t < N; t++) {
                acc = acc - (*inv)[i * N + t] * (*l)[t * N + j];
            }
            computed = computed + abs(acc);
        }
        var mag = real(1);
        var eb = real(0);
        for (var t = 0u; t < N; t++) {
            let rit = abs((*inv)[i * N + t]);
            mag = mag + rit * s[t];
            eb = eb + rit * se[t];
        }
        let row = up(computed) + GAMMA * up(mag) + up(eb);
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
