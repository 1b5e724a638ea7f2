// What every compute stage shares with the host's dispatch (`submit` in
// src/gpu/oracle/device.rs): the uniform `Params` (the thread count and the row stride of a
// two-dimensional dispatch, whose thread (x, y) is item x + y * row_stride), and WORKGROUP,
// the threads per workgroup, which the host prepends from its own constant.

struct Params {
    count: u32,
    row_stride: u32,
    _pad1: u32,
    _pad2: u32,
}
