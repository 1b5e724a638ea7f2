// Candidate generation of the exhaustive scan: one invocation per run of RUN consecutive
// lattice cubes (which mostly share their corner rows). Per cube, it finds the 2^D corners
// in the grid's rows, ORs the corners' sign codes over the supersets of every
// corner set, and walks the chains of corner sets depth first, appending those whose codes
// pass. CPU twin: `isomesh::trace::scan::candidates::cube_candidates` (the same steps, integers only).
// The host prepends: `const D: u32` (dimension), `const K: u32` (codimension),
// `const CORNERS: u32` (2^D), `const HALF: u32` (2^(D-1)), `const MASK: u32` (the bits a
// passing code holds), `const BASE: u32` (the bit of scanned cubes), `const KP1: u32` (K + 1),
// `const RUN: u32` (cubes per invocation).
//
// input, u32: first cube, row count, capacity (candidates), index of the first code, cube
// count, then the row-id strides of axes 1..D-1, then the rows (id, start as i32 bits, len,
// offset, top axes), then one code per vertex. Rows and offsets are relative to the window the host sent.
// found: the number of candidates (may exceed the capacity: the host then runs again).
// out: per candidate, K + 1 vertex indices, then the K corner sets S_1 < .. < S_K.

@group(0) @binding(0) var<storage, read> input: array<u32>;
@group(0) @binding(1) var<storage, read_write> found: array<atomic<u32>>;
@group(0) @binding(2) var<storage, read_write> out: array<u32>;
@group(0) @binding(3) var<uniform> params: Params;

const STRIDES_AT: u32 = 5u;
const ROWS_AT: u32 = STRIDES_AT + D - 1u;
const ROW: u32 = 5u;
const FULL: u32 = CORNERS - 1u;
const RECORD: u32 = 2u * K + 1u;

fn code_of(v: u32) -> u32 {
    return input[input[3] + v];
}

fn row_field(r: u32, f: u32) -> u32 {
    return input[ROWS_AT + r * ROW + f];
}

// The last row whose offset is <= v.
fn row_of(v: u32) -> u32 {
    var lo = 0u;
    var hi = input[1];
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (row_field(mid, 3u) <= v) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// The row with this id, or the row count when there is none.
fn find_row(id: u32) -> u32 {
    var lo = 0u;
    var hi = input[1];
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        let m = row_field(mid, 0u);
        if (m == id) {
            return mid;
        }
        if (m < id) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return input[1];
}

const NONE: u32 = 0xffffffffu;

// Per invocation: the cube's corners (storage indices) and the codes' OR over supersets,
var<private> corner: array<u32, CORNERS>;
var<private> sup: array<u32, CORNERS>;
// and, for the grid row `own` (NONE: none yet), the row of each subset of axes 1..D-1,
// valid when `whole` (every corner row exists). The cubes of a run share them mostly.
var<private> corner_rows: array<u32, HALF>;
var<private> own: u32 = NONE;
var<private> whole: bool = false;

// Finds the corner rows of the grid row of `cube`, unless they are the ones held.
fn locate(cube: u32) {
    if (own != NONE) {
        let at = row_field(own, 3u);
        if (cube >= at && cube - at < row_field(own, 2u)) {
            return;
        }
    }
    own = row_of(cube);
    whole = false;
    let own_id = row_field(own, 0u);
    let top = row_field(own, 4u);
    for (var t = 0u; t < HALF; t++) {
        if ((t & top) != 0u) {
            return;
        }
        var id = own_id;
        for (var j = 1u; j < D; j++) {
            if (((t >> (j - 1u)) & 1u) == 1u) {
                id += input[STRIDES_AT + j - 1u];
            }
        }
        let r = find_row(id);
        if (r == input[1]) {
            return;
        }
        corner_rows[t] = r;
    }
    whole = true;
}

// Appends the passing chains of the cube based at vertex `cube`.
fn scan_cube(cube: u32) {
    if ((code_of(cube) & BASE) == 0u) {
        return;
    }
    locate(cube);
    if (!whole) {
        return;
    }
    // The corners: axis 0 steps along a row.
    let u0 = bitcast<i32>(row_field(own, 1u)) + i32(cube - row_field(own, 3u));
    for (var t = 0u; t < HALF; t++) {
        let r = corner_rows[t];
        let start = bitcast<i32>(row_field(r, 1u));
        let len = i32(row_field(r, 2u));
        for (var b = 0u; b < 2u; b++) {
            let u = u0 + i32(b);
            if (u < start || u >= start + len) {
                return;
            }
            corner[(t << 1u) | b] = row_field(r, 3u) + u32(u - start);
        }
    }
    // The whole cube first: most fail, and the OR over supersets is D times the work.
    var any = 0u;
    for (var s = 0u; s < CORNERS; s++) {
        sup[s] = code_of(corner[s]);
        any |= sup[s];
    }
    if ((any & MASK) != MASK) {
        return;
    }
    for (var j = 0u; j < D; j++) {
        for (var s = 0u; s < CORNERS; s++) {
            if ((s & (1u << j)) == 0u) {
                sup[s] |= sup[s | (1u << j)];
            }
        }
    }
    // Depth first over chains; at depth i the chain holds sets[0..=i] and their codes' OR.
    var sets: array<u32, KP1>;
    var run: array<u32, KP1>;
    var add: array<u32, KP1>;
    sets[0] = 0u;
    run[0] = code_of(corner[0]);
    var depth = 0u;
    var descend = true;
    loop {
        if (descend) {
            let s = sets[depth];
            let free = FULL & ~s;
            if (depth == K) {
                if ((run[K] & MASK) == MASK) {
                    let slot = atomicAdd(&found[0], 1u);
                    if (slot < input[2]) {
                        let at = slot * RECORD;
                        for (var c = 0u; c <= K; c++) {
                            out[at + c] = corner[sets[c]];
                        }
                        for (var c = 1u; c <= K; c++) {
                            out[at + K + c] = sets[c];
                        }
                    }
                }
            } else if (((run[depth] | sup[s]) & MASK) == MASK
                && countOneBits(free) >= K - depth) {
                add[depth] = free & (~free + 1u);
                sets[depth + 1u] = s | add[depth];
                run[depth + 1u] = run[depth] | code_of(corner[sets[depth + 1u]]);
                depth += 1u;
                continue;
            }
            descend = false;
        }
        // Back up to the deepest set that has a next superset, in increasing order.
        if (depth == 0u) {
            break;
        }
        depth -= 1u;
        let s = sets[depth];
        let free = FULL & ~s;
        if (add[depth] == free) {
            continue;
        }
        add[depth] = (add[depth] - free) & free;
        sets[depth + 1u] = s | add[depth];
        run[depth + 1u] = run[depth] | code_of(corner[sets[depth + 1u]]);
        depth += 1u;
        descend = true;
    }
}

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row_stride;
    if (i >= params.count) {
        return;
    }
    let first = input[0] + i * RUN;
    let end = min(first + RUN, input[0] + input[4]);
    for (var cube = first; cube < end; cube++) {
        scan_cube(cube);
    }
}
